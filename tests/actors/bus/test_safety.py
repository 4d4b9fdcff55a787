"""The bus scheduler on the real robot's terms: boots, brownouts, wheels, the watchdog,
a gentle start-up, exact limits, one goal per joint, checked writes, no stalls.

Each test runs the real :class:`~whexar.actors.bus.BusScheduler` on virtual time against
the in-process servo chain and checks what it said and what the servos were left with.
"""

from __future__ import annotations

import itertools
import math
import statistics
from collections.abc import Sequence
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from whexar.actors.bus.servos import tick_limits
from whexar.actors.messages import (
    BusLost,
    BusStats,
    GoalClamped,
    GoalRefused,
    HardwareFault,
    JointGoal,
    JointGoals,
    ServoDegraded,
    ServoRebooted,
    ServoRestored,
    ServoStates,
    WatchdogStopped,
    WriteFailed,
)
from whexar.bus import control_table as ct
from whexar.bus.emulator.chain import ServoChain
from whexar.bus.emulator.faults import Fault, FaultInjector, FaultPlan
from whexar.bus.protocol import Instruction, Packet
from whexar.config import RobotConfig
from whexar.robot import JOINT_NAMES, POSITIONING_JOINTS, servo_id
from whexar.runtime.messages import ActorFailed
from whexar.testing import Harness
from whexar.testing.bus import bus_graph
from whexar.testing.bus import run_bus as run

CFG = RobotConfig()
WHEEL = JOINT_NAMES.index("wheel")
FEMUR = JOINT_NAMES.index("femur")
WHEELS = [servo_id(leg, "wheel") for leg in range(6)]


def graph(params: dict[str, Any] | None = None, **wiggle: Any) -> dict[str, Any]:
    return bus_graph("emulator:test", params, wiggle=wiggle if wiggle else None, max_restarts=0)


def table(chain: ServoChain, sid: int, name: str) -> int:
    return chain.servos[sid].register_value(name)


def goal(leg: int, joint: int, **values: float) -> JointGoal:
    return JointGoal(t=0.0, source="harness", leg=leg, joint=joint, **values)


def goals(*items: JointGoal, reflex: bool = False) -> JointGoals:
    return JointGoals(t=0.0, source="harness", goals=items, reflex=reflex)


def hold_config(tmp_path: Any) -> str:
    path = tmp_path / "hold.toml"
    path.write_text('[bus]\non_stop = "hold"\n')
    return str(path)


def packets_of(chain: ServoChain) -> list[tuple[float, Packet]]:
    seen: list[tuple[float, Packet]] = []
    chain.hooks.append(lambda _c, t, ps: seen.extend((t, p) for p in ps))
    return seen


def writes_below(seen: Sequence[tuple[float, Packet]], address: int) -> list[Packet]:
    """Write, Reg Write and Sync Write packets that start below ``address``."""
    writes = (Instruction.WRITE, Instruction.REG_WRITE, Instruction.SYNC_WRITE)
    return [
        p
        for _, p in seen
        if p.instruction in writes and int.from_bytes(p.params[0:2], "little") < address
    ]


def torque_off_writes(seen: Sequence[tuple[float, Packet]]) -> list[Packet]:
    out = []
    for _, p in seen:
        start = int.from_bytes(p.params[0:2], "little") if len(p.params) >= 2 else -1
        if p.instruction == Instruction.WRITE and start == 64 and p.params[2:] == b"\x00":
            out.append(p)
        if p.instruction == Instruction.SYNC_WRITE and start == 64 and p.params[4:][1::2].count(0):
            out.append(p)
    return out


# --------------------------------------------------------------------------- boot, brownout


def test_an_overloaded_femur_that_boots_in_0_4_s_is_restored_not_lost(chain: ServoChain) -> None:
    femur = servo_id(0, "femur")  # 3: critical
    FaultInjector(
        FaultPlan(faults=[Fault(kind="hardware_error", ids=[femur], bits=["overload"], at_s=1.0)])
    ).attach(chain)
    assert chain.servos[femur].boot_time_s == pytest.approx(0.4)
    result = run(graph({"plan": "full_feedback"}, wheel_rad_s=0.5), duration=3.0)
    assert result.exit_code == 0
    assert not result.events(BusLost)
    assert not result.events(ServoDegraded)
    fault, rebooted, restored = (
        result.events(HardwareFault),
        result.events(ServoRebooted),
        result.events(ServoRestored),
    )
    ids = [e.servo_id for e in fault] + [e.servo_id for e in rebooted]
    assert ids + [e.servo_id for e in restored] == [femur] * 3
    assert 1.0 <= fault[0].t < 1.1
    assert restored[0].t - rebooted[0].t >= 0.4  # it waited for the boot …
    assert restored[0].t - rebooted[0].t < 0.6  # … and not much longer
    # The other servos kept cycling while the femur booted.
    during = [
        s for s in result.messages("state", of=ServoStates) if rebooted[0].t < s.t < restored[0].t
    ]
    assert len(during) > 10
    assert all(femur not in {js.servo_id for js in s.joints} for s in during)
    assert table(chain, femur, "torque_enable") == 0  # on_stop = torque_off, after the run


def test_a_servo_that_never_comes_back_after_its_reboot_is_degraded(chain: ServoChain) -> None:
    coxa = servo_id(0, "coxa")
    chain.servos[coxa].boot_time_s = 10.0  # it will not answer within boot_timeout_s
    FaultInjector(
        FaultPlan(faults=[Fault(kind="hardware_error", ids=[coxa], bits=["overload"], at_s=0.5)])
    ).attach(chain)
    result = run(graph({"plan": "full_feedback"}), duration=3.0)
    degraded = result.events(ServoDegraded)
    assert [d.servo_id for d in degraded] == [coxa]
    assert "no answer 1.5 s after its reboot" in degraded[0].reason
    assert not result.events(BusLost)  # a coxa is not critical


# --------------------------------------------------------------------------- wheels


def test_wheel_speeds_are_clamped_to_the_velocity_limit(chain: ServoChain) -> None:
    limit_units = chain.servos[WHEELS[0]].register_value("velocity_limit")
    limit = ct.velocity_to_rad_s(limit_units)

    async def scenario(h: Harness) -> None:
        await h.wait_for(ServoStates)
        await h.feed("goals", goals(goal(0, WHEEL, velocity_rad_s=20.0)))
        await h.wait_for(GoalClamped)
        await h.wait_for(ServoStates)
        await h.wait_for(ServoStates)
        assert table(chain, WHEELS[0], "goal_velocity") == limit_units
        h.stop()

    result = run(graph(), scenario)
    clamped = result.events(GoalClamped)
    assert [(c.servo_id, c.requested_rad, c.unit) for c in clamped] == [(WHEELS[0], 20.0, "rad/s")]
    assert clamped[0].sent_rad == pytest.approx(limit)
    assert all(s.rejected_goals == 0 for s in chain.servos.values())


@pytest.mark.parametrize(
    ("bad", "says"),
    [
        (goal(0, WHEEL, velocity_rad_s=1e9), "not a speed"),
        (goal(0, WHEEL, velocity_rad_s=math.nan), "not a speed"),
        (goal(0, WHEEL, velocity_rad_s=-math.inf), "not a speed"),
        (goal(0, WHEEL, position_rad=0.3), "a position for servo 7 (RF wheel), a wheel"),
        (goal(0, FEMUR, velocity_rad_s=1.0), "a speed for servo 3 (RF femur)"),
        (goal(0, FEMUR, position_rad=math.nan), "not a finite number"),
        (goal(0, FEMUR, position_rad=40.0), "more than a turn beyond its limits"),
        (goal(0, FEMUR), "no goal"),
        (goal(6, FEMUR, position_rad=0.1), "no joint 2 on leg 6"),
    ],
)
def test_goals_that_are_no_command_are_refused_and_the_bus_goes_on(
    chain: ServoChain, bad: JointGoal, says: str
) -> None:
    wheels: list[int] = []

    async def scenario(h: Harness) -> None:
        await h.wait_for(ServoStates)
        await h.feed("goals", goals(bad, goal(1, WHEEL, velocity_rad_s=2.0)))
        await h.wait_for(GoalRefused)
        for _ in range(3):
            await h.wait_for(ServoStates)
        wheels.extend(table(chain, w, "goal_velocity") for w in WHEELS[:2])
        h.stop()

    result = run(graph(), scenario)
    assert result.exit_code == 0
    assert not result.events(ActorFailed)
    refused = result.events(GoalRefused)
    assert len(refused) == 1
    assert says in refused[0].reason
    assert (refused[0].leg, refused[0].joint) == (bad.leg, bad.joint)
    # The good goal in the same message went out; the wheel of leg 0 kept its old goal.
    assert wheels == [0, ct.rad_s_to_velocity(2.0)]


@pytest.mark.parametrize("on_stop", ["hold", "torque_off"])
def test_every_stop_brings_the_wheels_to_zero(
    chain: ServoChain, on_stop: str, tmp_path: Any
) -> None:
    path = tmp_path / "robot.toml"
    path.write_text(f'[bus]\non_stop = "{on_stop}"\n')

    async def scenario(h: Harness) -> None:
        await h.sleep(0.5)
        assert all(table(chain, w, "present_velocity") != 0 for w in WHEELS)
        h.stop()

    result = run(graph({"config": str(path)}, wheel_rad_s=1.5), scenario)
    assert result.exit_code == 0
    assert all(table(chain, w, "goal_velocity") == 0 for w in WHEELS)
    chain.advance(chain.servos[1].time + 0.1)
    assert all(table(chain, w, "present_velocity") == 0 for w in WHEELS)
    held = [table(chain, sid, "torque_enable") for sid in chain.servos]
    assert held == [1 if on_stop == "hold" else 0] * 42
    if on_stop == "hold":  # held, and the watchdog disarmed so that it stays held
        assert all(table(chain, sid, "bus_watchdog") == 0 for sid in chain.servos)


def test_a_safe_stop_also_stops_the_wheels(chain: ServoChain) -> None:
    femur = servo_id(1, "femur")
    FaultInjector(FaultPlan(faults=[Fault(kind="silent", ids=[femur], at_s=1.0)])).attach(chain)
    result = run(graph(wheel_rad_s=1.5), duration=3.0)
    assert result.exit_code == 3  # a femur lost
    assert result.events(BusLost)
    assert all(table(chain, w, "goal_velocity") == 0 for w in WHEELS)


# --------------------------------------------------------------------------- watchdog


def test_the_scheduler_arms_the_watchdog_and_keeps_every_servo_fed(chain: ServoChain) -> None:
    seen: list[int] = []

    async def scenario(h: Harness) -> None:
        await h.sleep(2.0)  # wheels and trochanters are never read by the default plan
        seen.extend(table(chain, sid, "bus_watchdog") for sid in chain.servos)
        assert all(table(chain, w, "present_velocity") != 0 for w in WHEELS)
        h.stop()

    result = run(graph({"plan": "default"}, wheel_rad_s=1.0, amplitude_rad=0.0), scenario)
    assert result.exit_code == 0
    assert seen == [5] * 42  # 100 ms in 20 ms units, and nobody tripped


def test_when_the_host_goes_silent_the_servos_stop_within_the_watchdog_time(
    chain: ServoChain,
) -> None:
    """A host that dies: here the servos stop hearing it (as after a crash or a kill)."""
    deaf_at: list[float] = []

    async def scenario(h: Harness) -> None:
        await h.sleep(1.0)
        deaf_at.append(h.clock.now())
        chain.faults.silent_until = dict.fromkeys(chain.servos, math.inf)
        await h.sleep(0.12)
        h.stop()

    run(graph(wheel_rad_s=2.0), scenario)
    t = deaf_at[0]
    chain.advance(t + 1.0)  # later: the wheels stood still from t + 0.1
    for w in WHEELS:
        servo = chain.servos[w]
        assert servo.register_value("bus_watchdog") == -1
        assert servo.register_value("present_velocity") == 0
        assert servo.torque_enabled  # stopped, holding
    moved = abs(chain.servos[WHEELS[0]].position - chain.servos[WHEELS[0]].position)
    assert moved == 0


def test_a_watchdog_error_left_by_a_dead_host_is_cleared_at_start(chain: ServoChain) -> None:
    for w in WHEELS:
        servo = chain.servos[w]
        servo.set_register("operating_mode", 1)
        servo.set_register("torque_enable", 1)
        servo.set_register("bus_watchdog", 5)
        servo.heard(-1.0)  # the last host went silent a second before this run's clock starts
    chain.advance(0.0)
    assert all(table(chain, w, "bus_watchdog") == -1 for w in WHEELS)

    async def scenario(h: Harness) -> None:
        await h.sleep(0.5)
        assert all(table(chain, w, "present_velocity") != 0 for w in WHEELS)
        h.stop()

    result = run(graph(wheel_rad_s=1.0), scenario)
    stopped = result.events(WatchdogStopped)
    assert [e.servo_ids for e in stopped] == [tuple(WHEELS)]
    assert result.exit_code == 0


# --------------------------------------------------------------------------- gentle start


def test_a_second_start_under_torque_turns_no_torque_off_and_writes_no_eeprom(
    chain: ServoChain, tmp_path: Any
) -> None:
    config = hold_config(tmp_path)
    first = run(graph({"config": config}), duration=0.5)
    assert first.exit_code == 0
    assert all(table(chain, sid, "torque_enable") == 1 for sid in chain.servos)
    standing = {sid: table(chain, sid, "goal_position") for sid in chain.servos}
    seen = packets_of(chain)
    second = run(graph({"config": config}), duration=0.5)
    assert second.exit_code == 0
    assert writes_below(seen, 64) == []  # no EEPROM write
    assert torque_off_writes(seen) == []
    assert all(table(chain, sid, "torque_enable") == 1 for sid in chain.servos)
    for sid, g in standing.items():  # every joint held where it stood
        if (sid - 1) % 7 != WHEEL:
            assert table(chain, sid, "goal_position") == g


def test_configured_gains_reach_the_servos_under_torque(chain: ServoChain, tmp_path: Any) -> None:
    path = tmp_path / "gains.toml"
    path.write_text('[bus]\non_stop = "hold"\n\n[joints.coxa]\ngains = { p = 3400, i = 8 }\n')
    config = str(path)
    coxas = [servo_id(leg, "coxa") for leg in range(6)]
    run(graph({"config": config}), duration=0.3)
    for sid in chain.servos:
        p, i = table(chain, sid, "position_p_gain"), table(chain, sid, "position_i_gain")
        assert (p, i) == ((3400, 8) if sid in coxas else (850, 0))
    # A second start finds them set and writes nothing; one servo reset (a power cycle
    # of its RAM) gets its gains again, and nobody's torque goes off.
    chain.servos[coxas[3]].set_register("position_p_gain", 850)
    seen = packets_of(chain)
    run(graph({"config": config}), duration=0.3)
    gains = [p for _, p in seen if p.instruction == Instruction.WRITE and p.params[0] == 84]
    assert [p.id for p in gains] == [coxas[3]]
    assert torque_off_writes(seen) == []
    assert table(chain, coxas[3], "position_p_gain") == 3400


def test_only_servos_whose_eeprom_differs_lose_torque_at_start(
    chain: ServoChain, tmp_path: Any
) -> None:
    config = hold_config(tmp_path)
    run(graph({"config": config}), duration=0.3)
    odd = servo_id(2, "tibia")
    chain.servos[odd].set_register("torque_enable", 0)
    chain.servos[odd].set_register("return_delay_time", 250)  # someone reset it
    seen = packets_of(chain)
    run(graph({"config": config}), duration=0.3)
    eeprom = writes_below(seen, 64)
    assert eeprom
    assert all(p.instruction == Instruction.WRITE and p.id == odd for p in eeprom)
    assert {p.params[0] for p in eeprom} == {9}  # only Return Delay Time differed
    assert table(chain, odd, "return_delay_time") == 10


def test_a_servo_starting_outside_its_limits_gets_a_goal_inside(chain: ServoChain) -> None:
    tibia = servo_id(0, "tibia")
    hi = (CFG.joints.tibia.limits_rad or (0.0, 0.0))[1]
    outside = ct.rad_to_ticks(hi) + 40
    chain.servos[tibia].set_state(outside)
    result = run(graph(), duration=0.3)
    clamped = [c for c in result.events(GoalClamped) if c.servo_id == tibia]
    assert len(clamped) == 1
    assert clamped[0].requested_rad == pytest.approx(ct.ticks_to_rad(outside))
    assert clamped[0].sent_rad <= hi
    assert ct.ticks_to_rad(table(chain, tibia, "goal_position")) <= hi


# --------------------------------------------------------------------------- exact limits


def test_tibia_150_degrees_goes_out_inside_the_limit() -> None:
    lo, hi = CFG.joints.tibia.limits_rad or (0.0, 0.0)
    first, last = tick_limits(lo, hi)
    assert ct.rad_to_ticks(hi) == 3755  # the nearest tick is 150.03°
    assert last == 3754
    assert ct.ticks_to_rad(last) <= hi < ct.ticks_to_rad(last + 1)
    assert ct.ticks_to_rad(first - 1) < lo <= ct.ticks_to_rad(first)


@settings(max_examples=300, derandomize=True, deadline=None)
@given(
    joint=st.sampled_from((*POSITIONING_JOINTS, "direction")),
    goal_rad=st.floats(-8.0, 8.0, allow_nan=False),
)
def test_no_tick_on_the_wire_is_beyond_a_limit(joint: str, goal_rad: float) -> None:
    lo, hi = CFG.joints.by_name(joint).limits_rad or (0.0, 0.0)
    lo, hi = max(lo, ct.ticks_to_rad(0)), min(hi, ct.ticks_to_rad(4095))
    first, last = tick_limits(lo, hi)
    sent = min(max(goal_rad, lo), hi)
    tick = min(max(ct.rad_to_ticks(sent), first), last)
    assert lo <= ct.ticks_to_rad(tick) <= hi  # zero tolerance
    assert abs(ct.ticks_to_rad(tick) - sent) <= ct.ticks_to_rad(2049) + 1e-12  # within a tick


def test_every_goal_the_scheduler_sends_is_inside_the_limits(chain: ServoChain) -> None:
    seen = packets_of(chain)
    edges = [
        goal(leg, j, position_rad=lim * 1.0001)
        for leg in range(6)
        for j, name in enumerate(POSITIONING_JOINTS)
        for lim in (CFG.joints.by_name(name).limits_rad or (0.0, 0.0))
    ]

    async def scenario(h: Harness) -> None:
        await h.wait_for(ServoStates)
        await h.feed("goals", goals(*edges))
        for _ in range(3):
            await h.wait_for(ServoStates)
        h.stop()

    run(graph(), scenario)
    checked = 0
    for _, p in seen:
        if p.instruction != Instruction.SYNC_WRITE or p.params[0:2] != (116).to_bytes(2, "little"):
            continue
        body = p.params[4:]
        for k in range(0, len(body), 5):
            sid = body[k]
            tick = int.from_bytes(body[k + 1 : k + 5], "little", signed=True)
            name = JOINT_NAMES[(sid - 1) % 7]
            lo, hi = CFG.joints.by_name(name).limits_rad or (0.0, 0.0)
            assert lo <= ct.ticks_to_rad(tick) <= hi, (sid, tick)
            checked += 1
    assert checked >= 30


# --------------------------------------------------------------------------- one goal per joint


@pytest.mark.parametrize("reflex_first", [True, False])
def test_the_latest_goal_per_joint_wins_and_goes_out_once_whatever_its_reflex_mark(
    chain: ServoChain, reflex_first: bool
) -> None:
    """Which goal source overrides which is the leg's decision, not the bus's: the bus
    takes the goals of a cycle in order, each joint's latest wins, ``reflex`` or not, and
    only that one is written."""
    femur = servo_id(2, "femur")
    reflex = goals(goal(2, FEMUR, position_rad=0.5), reflex=True)
    plain = goals(goal(2, FEMUR, position_rad=-0.2), goal(3, FEMUR, position_rad=0.1))
    latest = -0.2 if reflex_first else 0.5
    written: list[int] = []

    def femur_goals(_chain: ServoChain, _t: float, packets: Sequence[Packet]) -> None:
        for p in packets:
            if p.instruction != Instruction.SYNC_WRITE or p.params[0:2] != (116).to_bytes(
                2, "little"
            ):
                continue
            body = p.params[4:]
            written.extend(
                int.from_bytes(body[k + 1 : k + 5], "little", signed=True)
                for k in range(0, len(body), 5)
                if body[k] == femur
            )

    async def scenario(h: Harness) -> None:
        await h.wait_for(ServoStates)
        chain.hooks.append(femur_goals)
        for msg in (reflex, plain) if reflex_first else (plain, reflex):
            await h.feed("goals", msg)
        await h.wait_for(ServoStates)
        await h.wait_for(ServoStates)
        h.stop()

    run(graph(), scenario)
    assert written == [ct.rad_to_ticks(latest)]
    assert table(chain, femur, "goal_position") == ct.rad_to_ticks(latest)
    assert table(chain, servo_id(3, "femur"), "goal_position") == ct.rad_to_ticks(0.1)


# --------------------------------------------------------------------------- checked writes


def test_a_sync_write_that_did_not_go_out_is_counted_and_sent_again(chain: ServoChain) -> None:
    femur = servo_id(4, "femur")
    armed: list[bool] = []

    def fail_the_next_write(c: ServoChain, _t: float, _packets: Sequence[Packet]) -> None:
        if armed and armed[0]:
            c.faults.tx_fail = 1
            armed[0] = False

    chain.hooks.append(fail_the_next_write)

    async def scenario(h: Harness) -> None:
        await h.wait_for(ServoStates)
        armed.append(True)  # the next transaction after this: the goal's Sync Write
        await h.feed("goals", goals(goal(4, FEMUR, position_rad=0.4)))
        await h.wait_for(WriteFailed)
        await h.wait_for(ServoStates)
        await h.wait_for(ServoStates)
        h.stop()

    result = run(graph({"plan": "positioning", "stats_period_s": 0.01}), scenario)
    failed = result.events(WriteFailed)
    assert len(failed) == 1
    assert (failed[0].register, failed[0].result) == ("goal_position", "tx_fail")
    assert table(chain, femur, "goal_position") == ct.rad_to_ticks(0.4)
    stats = result.messages("stats", of=BusStats)
    assert stats[-1].write_failures == 1


# --------------------------------------------------------------------------- no stalls


def test_probing_a_dead_servo_never_doubles_a_cycle(chain: ServoChain) -> None:
    dead = servo_id(3, "coxa")  # not critical
    FaultInjector(FaultPlan(faults=[Fault(kind="silent", ids=[dead], at_s=0.5)])).attach(chain)
    result = run(graph({"plan": "full_feedback"}), duration=4.0)
    assert [d.servo_id for d in result.events(ServoDegraded)] == [dead]
    degraded_at = result.events(ServoDegraded)[0].t
    times = [s.t for s in result.messages("state", of=ServoStates)]
    before = [b - a for a, b in itertools.pairwise(times) if b < 0.5]
    after = [b - a for a, b in itertools.pairwise(times) if a > degraded_at + 0.05]
    nominal = statistics.median(before)
    assert len(after) > 100
    assert max(after) <= 2 * nominal  # 6 probes happened in there
