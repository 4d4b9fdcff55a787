"""The bus scheduler's fault handling, end to end: fault plans on the emulator, events checked.

Each test runs the real :class:`~whexar.actors.bus.BusScheduler` on virtual time against
the in-process servo chain with a :class:`~whexar.bus.emulator.faults.FaultInjector` attached, and
checks what the runtime said (events, states, stats, exit code) and what the servos were
left with (the emulator's control tables).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from itertools import pairwise
from pathlib import Path
from typing import Any

import pytest

from whexar.actors.messages import (
    BusLost,
    BusStats,
    HardwareFault,
    HardwareWarning,
    JointGoal,
    JointGoals,
    ServoDegraded,
    ServoFault,
    ServoHealth,
    ServoRebooted,
    ServoRecovered,
    ServoRestored,
    ServoStates,
    SupplyLow,
    SupplyRestored,
)
from whexar.bus import control_table as ct
from whexar.bus.emulator.chain import SERVO_CHAIN, ServoChain
from whexar.bus.emulator.faults import Fault, FaultInjector, FaultPlan, load_fault_plan
from whexar.bus.protocol import Instruction, Packet
from whexar.config import RobotConfig
from whexar.robot import JOINT_NAMES, LEG_NAMES, servo_id
from whexar.runtime.devices import DEVICES
from whexar.runtime.messages import ActorFailed, ActorStopped, Event, SafeStop
from whexar.testing import Harness, RunResult
from whexar.testing.bus import bus_graph, servo_chain
from whexar.testing.bus import run_bus as run

CFG = RobotConfig()
FAULT_PLANS = Path(__file__).resolve().parents[3] / "config" / "faults"
TIBIA = JOINT_NAMES.index("tibia")
TARSUS = JOINT_NAMES.index("tarsus")
POSITIONING = frozenset(
    servo_id(leg, joint)
    for leg in range(len(LEG_NAMES))
    for joint in ("coxa", "femur", "tibia", "tarsus")
)
"""The servos whose positions the default plan reads every cycle."""
HEALTH_EVERY_CYCLE: dict[str, Any] = {
    "name": "health_every_cycle",
    "reads": [
        {"registers": ["present_current", "present_position"], "joints": ["tarsus", "tibia"]},
        {"registers": ["hardware_error_status", "present_input_voltage"], "joints": ["tarsus"]},
    ],
    "fast_sync_read": "off",
}
"""A plan that reads the tarsus servos' voltage and error bits in every cycle."""

RECOVERY_EVENTS = (
    ServoFault,
    ServoDegraded,
    ServoRecovered,
    HardwareFault,
    ServoRebooted,
    ServoRestored,
)


# --------------------------------------------------------------------------- helpers


def inject(chain: ServoChain, *faults: Fault, seed: int = 0) -> FaultInjector:
    return FaultInjector(FaultPlan(seed=seed, faults=list(faults))).attach(chain)


def graph(params: dict[str, Any] | None = None, *, wiggle: bool = False) -> dict[str, Any]:
    """Scheduler on ``emulator:test`` (stats 4× a second); goals from the harness or a wiggle."""
    return bus_graph(
        "emulator:test",
        {"stats_period_s": 0.25, **(params or {})},
        wiggle={} if wiggle else None,
        max_restarts=0,
    )


def table(chain: ServoChain, sid: int, name: str) -> int:
    return chain.servos[sid].register_value(name)


def goal(leg: int, joint: int, q: float) -> JointGoals:
    return JointGoals(
        t=0.0,
        source="harness",
        goals=(JointGoal(t=0.0, source="harness", leg=leg, joint=joint, position_rad=q),),
    )


def servo_events(result: RunResult, sid: int) -> list[Event]:
    """The recovery events about servo ``sid``, in order."""
    return [e for e in result.events() if isinstance(e, RECOVERY_EVENTS) and e.servo_id == sid]


def names(events: Sequence[Event]) -> list[str]:
    return [type(e).__name__ for e in events]


def true_positions(chain: ServoChain) -> list[tuple[float, dict[int, int]]]:
    """Record, at every Sync Read of Present Position, each listed servo's true position."""
    seen: list[tuple[float, dict[int, int]]] = []
    position = ct.MODELS["MX-64"].register("present_position").address

    def hook(chain: ServoChain, t: float, packets: Sequence[Packet]) -> None:
        for p in packets:
            if p.instruction not in (Instruction.SYNC_READ, Instruction.FAST_SYNC_READ):
                continue
            start = int.from_bytes(p.params[0:2], "little")
            length = int.from_bytes(p.params[2:4], "little")
            if start <= position < start + length:
                ids = [i for i in p.params[4:] if i in chain.servos]
                seen.append((t, {i: round(chain.servos[i].position) for i in ids}))

    chain.hooks.append(hook)
    return seen


def worst_position_error(result: RunResult, truth: list[tuple[float, dict[int, int]]]) -> int:
    """Largest gap (ticks) between a published position and the truth read in that cycle."""
    states = result.messages("state", of=ServoStates)
    worst = 0
    checked = 0
    for k, state in enumerate(states):
        end = states[k + 1].t if k + 1 < len(states) else float("inf")
        window = [d for t, d in truth if state.t <= t < end]
        for js in state.joints:
            if js.position_rad is None:
                continue
            ticks = ct.rad_to_ticks(js.position_rad)
            candidates = [d[js.servo_id] for d in window if js.servo_id in d]
            assert candidates, f"servo {js.servo_id} published without being read at {state.t}"
            worst = max(worst, min(abs(ticks - c) for c in candidates))
            checked += 1
    assert checked > 1000  # the comparison did look at the run
    return worst


def assert_clean_bus(result: RunResult) -> None:
    assert not result.events(ActorFailed)
    assert not result.events(BusLost)
    assert not result.events(SafeStop)


# --------------------------------------------------------------------------- silent


def test_silent_tarsus_is_degraded_others_read_then_it_recovers_restored(
    chain: ServoChain,
) -> None:
    sid = servo_id(1, "tarsus")  # 12: in the middle of the read, not critical
    inject(chain, Fault(kind="silent", ids=[sid], at_s=0.5, duration_s=1.0))
    target = ct.rad_to_ticks(0.25)

    async def scenario(h: Harness) -> None:
        await h.wait_for(ServoDegraded, lambda e: e.servo_id == sid, timeout=2.0)
        # Power-cycled while it was silent: it comes back limp, goal = where it stands.
        chain.servos[sid].reboot()
        await h.feed("goals", goal(1, TARSUS, 0.25))  # held while degraded
        await h.wait_for(ServoRecovered, lambda e: e.servo_id == sid, timeout=2.0)
        back = await h.wait_for(ServoStates)
        assert sid in {js.servo_id for js in back.joints}
        assert table(chain, sid, "torque_enable") == 1
        assert table(chain, sid, "goal_position") == target
        await h.sleep(0.5)
        assert abs(table(chain, sid, "present_position") - target) <= 1

    result = run(graph(), scenario)
    assert result.exit_code == 0
    assert_clean_bus(result)

    events = servo_events(result, sid)
    assert names(events) == ["ServoFault"] * 5 + ["ServoDegraded", "ServoRecovered"]
    faults = [e for e in events if isinstance(e, ServoFault)]
    assert [(f.kind, f.consecutive) for f in faults] == [("timeout", n) for n in range(1, 6)]
    assert faults[0].t >= 0.5
    degraded, recovered = events[5], events[6]
    assert isinstance(degraded, ServoDegraded)
    assert "5 failed cycles" in degraded.reason
    assert recovered.t >= 1.5  # not before the servo answers again
    # Every cycle kept reading the 23 others; the silent servo was left out while degraded.
    states = result.messages("state", of=ServoStates)
    during = [s for s in states if faults[0].t <= s.t < recovered.t]
    assert len(during) > 40
    for s in during:
        ids = {js.servo_id for js in s.joints}
        assert ids >= POSITIONING - {sid}
        if s.t > degraded.t:
            assert sid not in ids
    assert all(sid in {js.servo_id for js in s.joints} for s in states if s.t > recovered.t)
    # BusStats said so, then said it was over.
    stats = result.messages("stats", of=BusStats)
    assert any(st.degraded == (sid,) for st in stats if degraded.t < st.t < recovered.t)
    assert stats[-1].degraded == ()
    assert stats[-1].timeouts == 5


def test_a_servo_read_a_few_times_a_second_is_asked_every_cycle_once_it_fails(
    chain: ServoChain,
) -> None:
    """The default plan asks a wheel servo only in its health reads (every 0.6 s at most),
    but ``degrade_after`` counts cycles for it too: once a read of it fails it is asked in
    every cycle, and degraded 5 cycles later, not 5 health reads (2 s and more) later."""
    wheel = servo_id(2, "wheel")
    inject(chain, Fault(kind="silent", ids=[wheel], at_s=0.5))
    result = run(graph(), duration=2.5)
    assert result.exit_code == 0  # a wheel is not critical: the robot goes on
    events = servo_events(result, wheel)
    assert names(events) == ["ServoFault"] * 5 + ["ServoDegraded"]
    faults = [e for e in events if isinstance(e, ServoFault)]
    # The first failed read is a health read, at most 0.6 s after the fault …
    assert 0.5 <= faults[0].t <= 1.15
    # … then one a cycle: each such cycle waits out the SDK's packet timeout twice (34 ms
    # with its 16 ms latency timer, then the retry), where a health read comes every 0.6 s.
    gaps = [b.t - a.t for a, b in pairwise(faults)]
    assert max(gaps) < 0.1, gaps
    assert events[-1].t - faults[0].t < 0.4
    # The others of its health reads kept their turns: every servo was still read.
    health = [h for h in result.messages("health", of=ServoHealth) if h.t > events[-1].t]
    assert {h.servo_id for h in health} == set(chain.servos) - {wheel}


def test_femur_silent_for_good_is_bus_lost_and_safe_stop(chain: ServoChain) -> None:
    femur = servo_id(0, "femur")  # 3
    inject(chain, Fault(kind="silent", ids=[femur], at_s=0.5))
    result = run(graph(), duration=5.0)
    assert result.exit_code == 3
    assert not result.events(ActorFailed)
    lost = result.events(BusLost)
    assert len(lost) == 1
    assert "servo 3 (RF femur) lost" in lost[0].reason
    assert names(servo_events(result, femur))[-1] == "ServoDegraded"
    safe = result.events(SafeStop)
    assert len(safe) == 1
    assert safe[0].t >= lost[0].t
    assert result.stop_reason is not None
    assert "servo 3 (RF femur)" in result.stop_reason
    assert result.end_time < 2.0  # stopped at once, not at the end of the duration
    # Every servo that can still hear was left limp (bus.on_stop = torque_off).
    assert [sid for sid in chain.servos if table(chain, sid, "torque_enable")] == [femur]


# --------------------------------------------------------------------------- noise


def test_corrupt_status_bytes_are_retried_and_never_published(chain: ServoChain) -> None:
    truth = true_positions(chain)
    inject(chain, Fault(kind="corrupt", rate=1e-4, at_s=0.3, duration_s=2.5), seed=1)
    result = run(graph(wiggle=True), duration=3.0)
    assert result.exit_code == 0
    assert_clean_bus(result)
    assert chain.stats.corrupted > 0
    stats = result.messages("stats", of=BusStats)[-1]
    assert stats.retries > 0
    assert stats.corrupt > 0
    assert stats.degraded == ()
    kinds = {e.kind for e in result.events(ServoFault)}
    assert "corrupt" in kinds
    # The servos move (the wiggle): a corrupted value would stand out.
    assert worst_position_error(result, truth) <= 1


def test_dropped_status_packets_are_retried_and_never_published(chain: ServoChain) -> None:
    truth = true_positions(chain)
    inject(chain, Fault(kind="drop", rate=0.01, at_s=0.3, duration_s=2.5), seed=2)
    result = run(graph(wiggle=True), duration=3.0)
    assert result.exit_code == 0
    assert_clean_bus(result)
    assert chain.stats.dropped > 0
    stats = result.messages("stats", of=BusStats)[-1]
    assert stats.retries > 0
    assert stats.timeouts > 0
    assert stats.corrupt == 0
    assert stats.degraded == ()
    assert {e.kind for e in result.events(ServoFault)} == {"timeout"}
    assert worst_position_error(result, truth) <= 1


# --------------------------------------------------------------------------- hardware errors


def test_overload_is_rebooted_restored_and_its_goal_held(chain: ServoChain) -> None:
    tibia = servo_id(0, "tibia")  # 4, critical: a hardware error is rebooted, not lost
    # Start-up sends three Sync Writes including it (torque off, goals, torque on);
    # the goal below is the fourth, and the overload comes right after it.
    injector = inject(
        chain,
        Fault(kind="hardware_error", ids=[tibia], bits=["overload"], on="sync_write", count=4),
    )
    target = ct.rad_to_ticks(0.3)

    async def scenario(h: Harness) -> None:
        await h.wait_for(ServoStates)
        await h.feed("goals", goal(0, TIBIA, 0.3))
        await h.wait_for(ServoRestored, timeout=1.0)
        await h.wait_for(ServoStates)
        servo = chain.servos[tibia]
        assert table(chain, tibia, "torque_enable") == 1
        assert table(chain, tibia, "hardware_error_status") == 0
        assert servo.goal == target
        await h.sleep(0.5)
        assert abs(table(chain, tibia, "present_position") - target) <= 1

    result = run(graph(), scenario)
    assert result.exit_code == 0
    assert_clean_bus(result)
    assert any("overload" in text for _, text in injector.log)
    events = servo_events(result, tibia)
    assert names(events) == ["HardwareFault", "ServoRebooted", "ServoRestored"]
    fault, rebooted, _ = events
    assert isinstance(fault, HardwareFault)
    assert fault.bits == ct.HardwareError.OVERLOAD
    assert fault.description == "overload"
    assert isinstance(rebooted, ServoRebooted)
    assert rebooted.ok
    # The Alert bit reached the published state of the cycle that saw it.
    alerts = [
        js
        for s in result.messages("state", of=ServoStates)
        for js in s.joints
        if js.servo_id == tibia and js.alert
    ]
    assert alerts


def test_a_rebooted_servo_gets_its_configured_gains_again(
    chain: ServoChain, tmp_path: Path
) -> None:
    # A reboot sets RAM back to its initial values, the position gains with it.
    config = tmp_path / "gains.toml"
    config.write_text("[joints.tibia]\ngains = { p = 1700, d = 40 }\n")
    tibia = servo_id(0, "tibia")
    inject(
        chain,
        Fault(kind="hardware_error", ids=[tibia], bits=["overload"], on="sync_write", count=4),
    )
    p_gain = ct.MODELS["MX-64"].register("position_p_gain").address
    written: list[float] = []  # when the tibia's Position P Gain was written
    chain.hooks.append(
        lambda _c, t, packets: written.extend(
            t
            for p in packets
            if p.instruction == Instruction.WRITE and p.id == tibia and p.params[0] == p_gain
        )
    )

    async def scenario(h: Harness) -> None:
        await h.wait_for(ServoStates)
        await h.feed("goals", goal(0, TIBIA, 0.3))
        await h.wait_for(ServoRestored, timeout=1.0)
        assert table(chain, tibia, "position_p_gain") == 1700
        assert table(chain, tibia, "position_d_gain") == 40
        assert table(chain, tibia, "torque_enable") == 1

    result = run(graph({"config": str(config)}), scenario)
    assert result.exit_code == 0
    assert_clean_bus(result)
    events = servo_events(result, tibia)
    assert names(events) == ["HardwareFault", "ServoRebooted", "ServoRestored"]
    # Written at start-up, and again after the reboot had put 850 back.
    assert len(written) == 2
    assert written[0] < events[1].t <= written[1]


def test_voltage_sag_is_a_warning_the_servo_keeps_torque_and_it_clears(
    chain: ServoChain,
) -> None:
    tarsus = servo_id(0, "tarsus")  # 5
    inject(chain, Fault(kind="voltage_sag", ids=[tarsus], volts=9.0, at_s=0.5, duration_s=1.0))
    torque: list[int] = []

    async def scenario(h: Harness) -> None:
        await h.wait_for(SupplyLow, timeout=2.0)
        torque.append(table(chain, tarsus, "torque_enable"))
        await h.wait_for(SupplyRestored, timeout=2.0)
        await h.sleep(0.2)

    result = run(graph({"plan": HEALTH_EVERY_CYCLE}), scenario)
    assert result.exit_code == 0
    assert_clean_bus(result)
    # Input voltage is not in Shutdown (52): no reboot, torque stays on, the bit clears.
    assert not servo_events(result, tarsus)
    assert torque == [1]
    warnings = [w for w in result.events(HardwareWarning) if w.servo_id == tarsus]
    assert [(w.active, w.bits) for w in warnings] == [
        (True, ct.HardwareError.INPUT_VOLTAGE),
        (False, ct.HardwareError.INPUT_VOLTAGE),
    ]
    assert warnings[0].description == "input voltage"
    assert 0.5 <= warnings[0].t < 0.6
    assert 1.5 <= warnings[1].t < 1.6
    low = result.events(SupplyLow)
    assert [e.servo_ids for e in low] == [(tarsus,)]
    assert len(result.events(SupplyRestored)) == 1
    # The servo stayed in every cycle; ServoHealth showed the sag, then the normal supply.
    states = result.messages("state", of=ServoStates)
    assert all(tarsus in {js.servo_id for js in s.joints} for s in states)
    health = [h for h in result.messages("health", of=ServoHealth) if h.servo_id == tarsus]
    sag = [h for h in health if h.voltage_v is not None and h.voltage_v < 9.5]
    assert sag
    assert all(h.voltage_v == pytest.approx(9.0) for h in sag)
    assert sag[0].hardware_error == ct.HardwareError.INPUT_VOLTAGE
    after = [h for h in health if h.t > warnings[1].t]
    assert after
    assert all(h.voltage_v == pytest.approx(12.0) for h in after)
    assert all(h.hardware_error == 0 for h in after)


# --------------------------------------------------------------------------- the port


def test_unplugged_port_is_bus_lost_naming_the_port(chain: ServoChain) -> None:
    inject(chain, Fault(kind="unplug", at_s=0.5))
    result = run(graph(), duration=3.0)
    assert result.exit_code == 3
    assert not result.events(ActorFailed)
    lost = result.events(BusLost)
    assert len(lost) == 1
    assert lost[0].reason.startswith("servo port lost: servo port emulator:test: ")
    assert "device disconnected" in lost[0].reason
    assert 0.5 <= lost[0].t < 0.6
    assert len(result.events(SafeStop)) == 1
    stopped = [e for e in result.events(ActorStopped) if e.actor == "bus"]
    assert [(e.reason, e.timed_out) for e in stopped] == [("stop", False)]
    assert result.end_time < 1.0


# --------------------------------------------------------------------------- shipped plans


def _dead_femur(result: RunResult, chain: ServoChain) -> None:
    assert result.exit_code == 3
    lost = result.events(BusLost)
    assert len(lost) == 1
    assert "servo 3 (RF femur) lost" in lost[0].reason
    assert lost[0].t >= 2.0


def _overload(result: RunResult, chain: ServoChain) -> None:
    assert result.exit_code == 0
    assert_clean_bus(result)
    assert names(servo_events(result, 4)) == ["HardwareFault", "ServoRebooted", "ServoRestored"]
    assert table(chain, 4, "hardware_error_status") == 0


def _noisy_bus(result: RunResult, chain: ServoChain) -> None:
    assert result.exit_code == 0
    assert_clean_bus(result)
    assert result.messages("stats", of=BusStats)[-1].retries > 0


def _brownout(result: RunResult, chain: ServoChain) -> None:
    # Every servo sags to 9 V, below Min Voltage Limit, for 1 s: an Input Voltage Error
    # does not latch (Shutdown 52), so no servo is rebooted and the run goes on.
    assert result.exit_code == 0
    assert not result.events(ActorFailed)
    assert not result.events(BusLost)
    assert not result.events(ServoRebooted)
    low = result.events(SupplyLow)
    assert len(low) == 1
    assert 5.0 <= low[0].t < 5.2
    restored = result.events(SupplyRestored)
    assert len(restored) == 1
    assert 6.0 <= restored[0].t < 6.8  # the last servo is seen clean by its health read
    warned = {w.servo_id for w in result.events(HardwareWarning) if w.active}
    assert warned == set(chain.servos)
    assert all(chain.servos[sid].hardware_error == 0 for sid in chain.servos)


def _unplug(result: RunResult, chain: ServoChain) -> None:
    # Out at the first torque enable, i.e. during start-up: the actor fails to start
    # with the port error it expects (no BusLost: there is no running bus to lose).
    assert result.exit_code == 3
    failed = result.events(ActorFailed)
    assert len(failed) == 1
    assert failed[0].phase == "start"
    assert failed[0].error.startswith("DeviceGoneError: servo port emulator:test: ")


@pytest.mark.parametrize(
    ("plan", "duration", "check"),
    [
        ("dead-femur.toml", 4.0, _dead_femur),
        ("overload.toml", 1.0, _overload),
        ("noisy-bus.toml", 3.0, _noisy_bus),
        ("brownout.toml", 7.5, _brownout),
        ("unplug.toml", 1.0, _unplug),
    ],
)
def test_shipped_fault_plans(
    chain: ServoChain,
    plan: str,
    duration: float,
    check: Callable[[RunResult, ServoChain], None],
) -> None:
    FaultInjector(load_fault_plan(FAULT_PLANS / plan)).attach(chain)
    check(run(graph(wiggle=True), duration=duration), chain)


def test_scheduler_loads_a_fault_plan_for_its_own_emulator() -> None:
    params = {"port": "emulator", "faults": str(FAULT_PLANS / "overload.toml")}
    result = run(graph(params, wiggle=True), duration=1.0)
    assert result.exit_code == 0
    assert_clean_bus(result)
    assert names(servo_events(result, 4)) == ["HardwareFault", "ServoRebooted", "ServoRestored"]


# --------------------------------------------------------------------------- determinism


def test_same_fault_plan_gives_the_same_log() -> None:
    plan = FaultPlan(
        seed=7,
        faults=[
            Fault(kind="corrupt", rate=3e-4, at_s=0.3, duration_s=1.0),
            Fault(kind="drop", rate=0.01, at_s=0.5, duration_s=0.5),
            Fault(kind="silent", ids=[12], at_s=0.4, duration_s=0.6),
            Fault(kind="hardware_error", ids=[4], bits=["overload"], on="sync_write", count=20),
        ],
    )
    digests = []
    for _ in range(2):
        made = servo_chain(CFG)
        FaultInjector(plan).attach(made)
        DEVICES.register(SERVO_CHAIN, "test", made)
        try:
            result = run(graph(wiggle=True), duration=1.5)
        finally:
            DEVICES.unregister(SERVO_CHAIN, "test")
        assert result.events(ServoFault)
        assert result.events(ServoRecovered)
        assert result.events(HardwareFault)
        digests.append(result.log.digest())
    assert digests[0] == digests[1]
