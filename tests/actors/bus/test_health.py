"""The servo health machine, called directly: every transition of its table, and the
stories the bus tells with them (no runtime, no port, no clock)."""

from __future__ import annotations

from collections.abc import Callable

import pytest
from dynamixel_sdk import COMM_RX_TIMEOUT

from whexar.actors.bus.health import (
    BOOT_POLL_S,
    TRANSITIONS,
    WARNING_RECHECK_S,
    Action,
    Effect,
    HealthMachine,
    Job,
    SafeStopRequest,
    Seen,
    State,
    Step,
    TransitionError,
)
from whexar.actors.bus.servos import servo_table
from whexar.actors.messages import (
    BusLost,
    HardwareFault,
    HardwareWarning,
    ServoDegraded,
    ServoFault,
    ServoRebooted,
    ServoRecovered,
    ServoRestored,
    SupplyLow,
    SupplyRestored,
)
from whexar.bus.protocol import ALERT
from whexar.bus.sdk import COMM_SUCCESS, Reply
from whexar.config import RobotConfig
from whexar.robot import servo_id

CFG = RobotConfig()
COXA = servo_id(0, "coxa")  # not critical
FEMUR = servo_id(0, "femur")  # critical
DEGRADE_AFTER, PROBE_S, BOOT_S = 5, 1.0, 2.0
OVERLOAD, INPUT_VOLTAGE = 0x20, 0x01
NOW = 10.0

ANSWER = Reply(COMM_SUCCESS)
ALERTED = Reply(COMM_SUCCESS, error=ALERT)
NO_ANSWER = Reply(COMM_RX_TIMEOUT)


def machine() -> HealthMachine:
    return HealthMachine(
        servo_table(CFG),
        "bus",
        degrade_after=DEGRADE_AFTER,
        probe_period_s=PROBE_S,
        boot_timeout_s=BOOT_S,
    )


def kinds(effects: list[Effect]) -> list[type]:
    return [type(e) for e in effects]


def put(m: HealthMachine, sid: int, state: State) -> None:
    """Servo ``sid`` in ``state``, as the table would have left it."""
    m.records[sid].state = state
    if state is State.OK:
        m.out.discard(sid)
    else:
        m.out.add(sid)


# --------------------------------------------------------------------------- the table


def _observe(m: HealthMachine, sid: int, seen: Seen) -> Step:
    """Make the machine see ``seen`` of ``sid`` through its public methods."""
    h = m.records[sid]
    if seen is Seen.FAILING:
        h.failures = DEGRADE_AFTER - 1
        effects = m.account(NOW, [], {sid: "timeout"})
        assert isinstance(effects[0], ServoFault)
        return Step(effects[1:])
    if seen is Seen.LATCHED:
        return m.error_status(NOW, sid, OVERLOAD, alert=True, answered=True)
    if seen is Seen.REBOOTED:
        return m.rebooted(NOW, sid, ANSWER)
    if seen is Seen.ANSWERED:
        return m.pinged(NOW, sid, ANSWER)
    if seen is Seen.ALERT:
        return m.pinged(NOW, sid, ALERTED)
    if seen is Seen.SILENT:
        h.boot_deadline = NOW + 1.0
        return m.pinged(NOW, sid, NO_ANSWER)
    if seen is Seen.TIMED_OUT:
        h.boot_deadline = NOW
        return m.pinged(NOW, sid, NO_ANSWER)
    if seen is Seen.ERROR_READ:
        return m.error_read(NOW, sid, Reply(COMM_SUCCESS, value=OVERLOAD))
    if seen is Seen.RESTORED:
        return m.restored(NOW, sid, True)
    assert seen is Seen.NOT_RESTORED
    return m.restored(NOW, sid, False)


_EVENTS: dict[Action, list[type]] = {
    Action.REBOOT: [HardwareFault],
    Action.BOOT: [ServoRebooted],
    Action.DEGRADE: [ServoDegraded],
    Action.RESTORED: [ServoRestored],
    Action.RECOVERED: [ServoRecovered],
}
_JOB: dict[Action, Job] = {
    Action.REBOOT: Job.REBOOT,
    Action.READ_ERROR: Job.READ_ERROR,
    Action.RESTORE: Job.RESTORE,
    Action.RECOVERED: Job.DETECT_FAST,
}


@pytest.mark.parametrize(
    ("state", "seen"), list(TRANSITIONS), ids=[f"{a.name}-{b.name}" for a, b in TRANSITIONS]
)
def test_each_transition_goes_where_the_table_says_and_does_its_actions(
    state: State, seen: Seen
) -> None:
    m = machine()
    put(m, COXA, state)
    step = _observe(m, COXA, seen)
    after, actions = TRANSITIONS[state, seen]
    h = m.records[COXA]
    assert h.state is after
    assert (COXA in m.out) == (after is not State.OK)
    assert kinds(step.effects) == [k for a in actions for k in _EVENTS.get(a, [])]
    jobs = [_JOB[a] for a in actions if a in _JOB]
    assert step.job is (jobs[0] if jobs else None)
    if Action.PROBE in actions:
        assert h.next_probe == NOW + PROBE_S
    if Action.POLL in actions or Action.BOOT in actions:
        assert h.next_probe == NOW + BOOT_POLL_S
    if Action.BOOT in actions:
        assert h.boot_deadline == NOW + BOOT_S
    if after is State.OK:
        assert h.failures == 0
    assert not m.lost  # the coxa is not critical


def test_a_transition_does_at_most_one_port_job_and_does_it_last() -> None:
    for (state, seen), (_, actions) in TRANSITIONS.items():
        jobs = [k for k, a in enumerate(actions) if a in _JOB]
        assert len(jobs) <= 1, (state, seen)
        assert not jobs or jobs[0] == len(actions) - 1, (state, seen)


def test_every_state_is_left_and_every_observation_used() -> None:
    assert {s for s, _ in TRANSITIONS} == set(State)
    assert {seen for _, seen in TRANSITIONS} == set(Seen)
    assert {after for after, _ in TRANSITIONS.values()} == set(State)


@pytest.mark.parametrize(
    ("state", "observe"),
    [
        (State.OK, lambda m: m.pinged(NOW, COXA, ANSWER)),
        (State.OK, lambda m: m.restored(NOW, COXA, True)),
        (State.BOOTING, lambda m: m.rebooted(NOW, COXA, ANSWER)),
        (State.DEGRADED, lambda m: m.error_status(NOW, COXA, OVERLOAD, True, True)),
    ],
)
def test_an_observation_without_a_transition_is_a_bug_said_so(
    state: State, observe: Callable[[HealthMachine], Step]
) -> None:
    m = machine()
    put(m, COXA, state)
    with pytest.raises(TransitionError, match=r"servo 1 \(RF coxa\)"):
        observe(m)


# --------------------------------------------------------------------------- stories


def test_a_silent_servo_is_degraded_after_degrade_after_cycles_and_recovered_by_a_probe() -> None:
    m = machine()
    for _k in range(1, DEGRADE_AFTER):
        effects = m.account(NOW, [], {COXA: "timeout"})
        assert kinds(effects) == [ServoFault]
        assert m.to_ask() == [COXA]  # asked again every cycle
    effects = m.account(NOW, [], {COXA: "corrupt"})
    assert kinds(effects) == [ServoFault, ServoDegraded]
    assert isinstance(effects[1], ServoDegraded)
    assert effects[1].reason == f"{DEGRADE_AFTER} failed cycles in a row (corrupt)"
    assert (m.timeouts, m.corrupt) == (DEGRADE_AFTER - 1, 1)
    assert m.to_ask() == []
    assert m.out == {COXA}
    assert m.due(NOW + PROBE_S - 0.01) is None
    assert m.due(NOW + PROBE_S) == COXA
    step = m.pinged(NOW + PROBE_S, COXA, ANSWER)
    assert step.job is Job.RESTORE
    step = m.restored(NOW + PROBE_S, COXA, True)
    assert kinds(step.effects) == [ServoRecovered]
    assert step.job is Job.DETECT_FAST
    assert m.state(COXA) is State.OK
    assert m.out == set()


def test_an_answer_in_a_cycle_resets_the_count_of_failures() -> None:
    m = machine()
    for _ in range(DEGRADE_AFTER - 1):
        m.account(NOW, [], {COXA: "timeout"})
    m.account(NOW, [COXA], {})
    assert m.records[COXA].failures == 0
    assert m.to_ask() == []
    assert kinds(m.account(NOW, [], {COXA: "timeout"})) == [ServoFault]


def test_losing_a_critical_servo_loses_the_bus_once() -> None:
    m = machine()
    tibia = servo_id(1, "tibia")
    m.records[FEMUR].failures = m.records[tibia].failures = DEGRADE_AFTER - 1
    effects = m.account(NOW, [], {FEMUR: "timeout", tibia: "timeout"})
    assert kinds(effects) == [
        ServoFault,
        ServoDegraded,
        BusLost,
        SafeStopRequest,
        ServoFault,
        ServoDegraded,
        SafeStopRequest,  # BusLost said once
    ]
    assert isinstance(effects[2], BusLost)
    assert effects[2].reason.startswith("servo 3 (RF femur) lost: ")
    assert m.lost
    # The port, though, is said again.
    assert kinds(m.lose(NOW, "servo port lost: gone", port=True)) == [BusLost, SafeStopRequest]


def test_a_latched_error_reboots_then_restores_the_servo() -> None:
    m = machine()
    step = m.error_status(NOW, COXA, OVERLOAD, alert=True, answered=True)
    assert kinds(step.effects) == [HardwareFault]
    assert step.job is Job.REBOOT
    fault = step.effects[0]
    assert isinstance(fault, HardwareFault)
    assert (fault.bits, fault.description) == (OVERLOAD, "overload")
    assert m.state(COXA) is State.OK  # until the reboot went out
    step = m.rebooted(NOW + 0.001, COXA, ANSWER)
    assert kinds(step.effects) == [ServoRebooted]
    assert step.job is None
    assert m.state(COXA) is State.BOOTING
    assert COXA in m.out
    assert m.due(NOW + 0.001) is None
    t = NOW + 0.001 + BOOT_POLL_S
    assert m.due(t) == COXA
    assert m.pinged(t, COXA, NO_ANSWER).job is None  # still booting: polled again
    assert m.records[COXA].next_probe == t + BOOT_POLL_S
    assert m.pinged(t + 0.4, COXA, ANSWER).job is Job.RESTORE
    step = m.restored(t + 0.4, COXA, True)
    assert kinds(step.effects) == [ServoRestored]
    assert step.job is None
    assert m.state(COXA) is State.OK


def test_an_error_that_persists_after_the_reboot_degrades_the_servo() -> None:
    m = machine()
    m.error_status(NOW, COXA, OVERLOAD, alert=True, answered=True)
    m.rebooted(NOW, COXA, ANSWER)
    assert m.pinged(NOW + 0.5, COXA, ALERTED).job is Job.READ_ERROR
    step = m.error_read(NOW + 0.5, COXA, Reply(COMM_SUCCESS, value=OVERLOAD))
    assert kinds(step.effects) == [ServoDegraded]
    assert isinstance(step.effects[0], ServoDegraded)
    assert step.effects[0].reason == "hardware error persists after reboot (overload)"
    # The read itself failing says how.
    other = machine()
    put(other, COXA, State.BOOTING)
    step = other.error_read(NOW, COXA, NO_ANSWER)
    assert isinstance(step.effects[0], ServoDegraded)
    assert step.effects[0].reason == "hardware error persists after reboot (timeout)"


def test_a_booting_servo_that_never_answers_is_given_up_after_the_boot_timeout() -> None:
    m = machine()
    m.error_status(NOW, COXA, OVERLOAD, alert=True, answered=True)
    m.rebooted(NOW, COXA, Reply(COMM_RX_TIMEOUT))
    step = m.pinged(NOW + BOOT_S, COXA, NO_ANSWER)
    assert kinds(step.effects) == [ServoDegraded]
    assert isinstance(step.effects[0], ServoDegraded)
    assert step.effects[0].reason == f"no answer {BOOT_S:g} s after its reboot"
    assert m.state(COXA) is State.DEGRADED


def test_a_degraded_servo_with_a_latched_error_is_rebooted_and_only_then_recovered() -> None:
    m = machine()
    put(m, COXA, State.DEGRADED)
    assert m.pinged(NOW, COXA, ALERTED).job is Job.READ_ERROR
    step = m.error_read(NOW, COXA, Reply(COMM_SUCCESS, value=OVERLOAD))
    assert kinds(step.effects) == [HardwareFault]
    assert step.job is Job.REBOOT
    m.rebooted(NOW, COXA, ANSWER)
    assert m.state(COXA) is State.RECOVERING
    # A failed boot is said no more: it was degraded already.
    failed = machine()
    put(failed, COXA, State.RECOVERING)
    assert failed.pinged(NOW, COXA, ALERTED).job is Job.READ_ERROR
    assert failed.error_read(NOW, COXA, ANSWER).effects == []
    assert failed.state(COXA) is State.DEGRADED
    # Back, it is restored and recovered.
    assert m.pinged(NOW + 0.5, COXA, ANSWER).job is Job.RESTORE
    step = m.restored(NOW + 0.5, COXA, True)
    assert kinds(step.effects) == [ServoRestored, ServoRecovered]
    assert step.job is Job.DETECT_FAST


def test_a_failed_read_of_the_error_still_reboots_a_degraded_servo() -> None:
    m = machine()
    put(m, COXA, State.DEGRADED)
    step = m.error_read(NOW, COXA, NO_ANSWER)
    assert step.job is Job.REBOOT
    assert isinstance(step.effects[0], HardwareFault)
    assert step.effects[0].bits == 0


def test_a_degraded_servo_that_does_not_answer_is_probed_again_a_period_later() -> None:
    m = machine()
    put(m, COXA, State.DEGRADED)
    m.records[COXA].boot_deadline = 0.0  # long past: a degraded servo has no boot timeout
    step = m.pinged(NOW, COXA, NO_ANSWER)
    assert step.effects == []
    assert step.job is None
    assert m.records[COXA].next_probe == NOW + PROBE_S


def test_the_earliest_probe_goes_first_one_at_a_time() -> None:
    m = machine()
    for sid, at in ((7, 2.0), (3, 1.0), (5, 1.0)):
        put(m, sid, State.DEGRADED)
        m.records[sid].next_probe = at
    assert m.due(0.5) is None
    assert m.due(1.5) == 3  # the earliest, then the lowest ID
    assert [s.id for s in m.reachable()] == [s for s in range(1, 43) if s not in (3, 5, 7)]


# --------------------------------------------------------------------------- warnings


def test_an_input_voltage_error_warns_without_a_reboot_and_clears_by_itself() -> None:
    m = machine()
    step = m.error_status(NOW, COXA, INPUT_VOLTAGE, alert=True, answered=True)
    assert kinds(step.effects) == [HardwareWarning, SupplyLow]
    assert step.job is None
    warning = step.effects[0]
    assert isinstance(warning, HardwareWarning)
    assert (warning.bits, warning.active) == (INPUT_VOLTAGE, True)
    assert m.state(COXA) is State.OK
    # A second servo's sag says nothing more of the supply.
    assert kinds(m.error_status(NOW, 2, INPUT_VOLTAGE, True, True).effects) == [HardwareWarning]
    # The same bits again: nothing new.
    assert m.error_status(NOW, COXA, INPUT_VOLTAGE, True, True).effects == []
    assert m.to_check({COXA: {}}, {COXA: 0}) == [COXA]  # a standing warning is checked
    # A clean status ends the warning; the supply is back once no servo sags.
    assert kinds(m.error_status(NOW, COXA, None, alert=False, answered=True).effects) == [
        HardwareWarning
    ]
    assert kinds(m.error_status(NOW, 2, 0, alert=False, answered=True).effects) == [
        HardwareWarning,
        SupplyRestored,
    ]
    assert not m.supply_low


def test_a_standing_warning_is_read_again_only_every_recheck_period() -> None:
    m = machine()
    assert m.wants_error_read(NOW, COXA, alert=True, bits=None)
    assert not m.wants_error_read(NOW, COXA, alert=True, bits=0x01)  # read in the cycle
    assert not m.wants_error_read(NOW, COXA, alert=False, bits=None)
    m.error_status(NOW, COXA, INPUT_VOLTAGE, alert=True, answered=True)
    assert not m.wants_error_read(NOW + WARNING_RECHECK_S / 2, COXA, alert=True, bits=None)
    assert m.wants_error_read(NOW + WARNING_RECHECK_S, COXA, alert=True, bits=None)


def test_only_servos_in_the_cycle_with_something_to_say_are_checked() -> None:
    m = machine()
    put(m, 9, State.DEGRADED)
    values = {4: {"hardware_error_status": 0}, 6: {"hardware_error_status": OVERLOAD}}
    errors = {2: 0, 4: 0, 6: ALERT, 8: ALERT, 9: ALERT}
    assert m.to_check(values, errors) == [6, 8]


def test_a_latched_error_on_top_of_a_warning_reports_both() -> None:
    m = machine()
    step = m.error_status(NOW, COXA, INPUT_VOLTAGE | OVERLOAD, alert=True, answered=True)
    assert kinds(step.effects) == [HardwareWarning, SupplyLow, HardwareFault]
    assert step.job is Job.REBOOT
    m.rebooted(NOW, COXA, ANSWER)
    assert m.records[COXA].warning == 0  # a reboot clears what the servo had
