"""The goal policy, called directly: latest goal per joint, clamp and refuse, the writes of
a cycle (no runtime, no port, no clock)."""

from __future__ import annotations

import math

import pytest
from dynamixel_sdk import COMM_TX_FAIL

from whexar.actors.bus.goals import GoalPolicy, Write
from whexar.actors.bus.servos import GOAL_POSITION, GOAL_VELOCITY, servo_table, tick_limits
from whexar.actors.messages import GoalClamped, GoalRefused, JointGoal, JointGoals, WriteFailed
from whexar.bus import control_table as ct
from whexar.bus.sdk import COMM_SUCCESS
from whexar.config import RobotConfig
from whexar.robot import JOINT_NAMES, servo_id

CFG = RobotConfig()
FEMUR, TIBIA, WHEEL = (JOINT_NAMES.index(j) for j in ("femur", "tibia", "wheel"))
KEEPALIVE_S = 0.05


def policy() -> GoalPolicy:
    return GoalPolicy(servo_table(CFG), "bus", KEEPALIVE_S)


def msg(*goals: JointGoal, reflex: bool = False) -> JointGoals:
    return JointGoals(t=0.0, source="test", goals=goals, reflex=reflex)


def pos(leg: int, joint: int, q: float) -> JointGoal:
    return JointGoal(t=0.0, source="test", leg=leg, joint=joint, position_rad=q)


def speed(leg: int, w: float) -> JointGoal:
    return JointGoal(t=0.0, source="test", leg=leg, joint=WHEEL, velocity_rad_s=w)


def goal_of(p: GoalPolicy, leg: int, joint: str) -> int | None:
    return p.slots[servo_id(leg, joint)].goal


# --------------------------------------------------------------------------- goals in


def test_the_latest_goal_per_joint_wins_whatever_its_reflex_mark() -> None:
    p = policy()
    events = p.take(
        1.0,
        [
            msg(pos(0, FEMUR, 0.5), reflex=True),
            msg(pos(0, FEMUR, -0.2), pos(1, FEMUR, 0.1)),
            msg(pos(1, FEMUR, 0.3)),
        ],
    )
    assert events == []
    assert goal_of(p, 0, "femur") == ct.rad_to_ticks(-0.2)
    assert goal_of(p, 1, "femur") == ct.rad_to_ticks(0.3)
    # Every goal of a cycle is taken, but a joint's goal is written once.
    writes = p.writes(1.0, set())
    assert len(writes) == 1
    assert writes[0].values == {
        servo_id(0, "femur"): ct.rad_to_ticks(-0.2),
        servo_id(1, "femur"): ct.rad_to_ticks(0.3),
    }


def test_a_position_beyond_a_limit_is_clamped_to_a_tick_inside_it() -> None:
    p = policy()
    lo, hi = CFG.joints.by_name("tibia").limits_rad or (0.0, 0.0)
    events = p.take(2.0, [msg(pos(1, TIBIA, 4.0))])
    assert len(events) == 1
    clamp = events[0]
    assert isinstance(clamp, GoalClamped)
    assert (clamp.t, clamp.servo_id, clamp.requested_rad, clamp.unit) == (
        2.0,
        servo_id(1, "tibia"),
        4.0,
        "rad",
    )
    assert clamp.sent_rad == pytest.approx(hi)
    tick = goal_of(p, 1, "tibia")
    assert tick == tick_limits(lo, hi)[1]
    assert tick is not None
    assert ct.ticks_to_rad(tick) <= hi  # no tolerance
    assert p.clamped == 1


@pytest.mark.parametrize(
    ("goal", "reason"),
    [
        (JointGoal(t=0.0, source="t", leg=6, joint=0, position_rad=0.0), "no joint 0 on leg 6"),
        (JointGoal(t=0.0, source="t", leg=0, joint=9, position_rad=0.0), "no joint 9 on leg 0"),
        (JointGoal(t=0.0, source="t", leg=0, joint=FEMUR), "no goal for servo 3"),
        (
            JointGoal(t=0.0, source="t", leg=0, joint=FEMUR, velocity_rad_s=1.0),
            "a speed for servo 3 (RF femur), a positioned joint",
        ),
        (pos(0, FEMUR, math.nan), "position_rad = nan for servo 3 (RF femur): not a finite"),
        (pos(0, FEMUR, 40.0), "more than a turn beyond its limits"),
        (pos(0, WHEEL, 0.0), "a position for servo 7 (RF wheel), a wheel"),
        (JointGoal(t=0.0, source="t", leg=0, joint=WHEEL), "no goal for servo 7 (RF wheel)"),
        (speed(0, math.inf), "velocity_rad_s = inf for servo 7 (RF wheel): not a speed"),
        (speed(0, 1e9), "not a speed (its Velocity Limit is"),
    ],
)
def test_a_goal_that_is_no_command_is_refused_and_changes_nothing(
    goal: JointGoal, reason: str
) -> None:
    p = policy()
    before = {sid: s.goal for sid, s in p.slots.items()}
    events = p.take(3.0, [msg(goal)])
    assert len(events) == 1
    refused = events[0]
    assert isinstance(refused, GoalRefused)
    assert (refused.t, refused.leg, refused.joint) == (3.0, goal.leg, goal.joint)
    assert reason in refused.reason
    assert {sid: s.goal for sid, s in p.slots.items()} == before
    assert p.clamped == 0


def test_a_wheel_speed_is_clamped_to_the_velocity_limit() -> None:
    p = policy()
    wheel = p.slots[servo_id(2, "wheel")]
    wheel.servo.speed_limit = 100
    limit = ct.velocity_to_rad_s(100)
    assert p.take(0.0, [msg(speed(2, 0.5 * limit))]) == []
    assert wheel.goal == ct.rad_s_to_velocity(0.5 * limit)
    events = p.take(0.0, [msg(speed(2, -3 * limit))])
    assert len(events) == 1
    clamp = events[0]
    assert isinstance(clamp, GoalClamped)
    assert clamp.unit == "rad/s"
    assert clamp.sent_rad == pytest.approx(-limit)
    assert wheel.goal == -100


def test_start_goals_come_within_the_limits_and_say_so() -> None:
    p = policy()
    femur, wheel = servo_id(0, "femur"), servo_id(0, "wheel")
    lo_tick = p.slots[femur].servo.lo_tick
    events = p.start(5.0, {femur: lo_tick - 10, wheel: 0})
    assert p.slots[femur].goal == lo_tick
    assert p.slots[wheel].goal == 0
    assert len(events) == 1
    clamp = events[0]
    assert isinstance(clamp, GoalClamped)
    assert clamp.requested_rad == pytest.approx(ct.ticks_to_rad(lo_tick - 10))
    assert p.clamped == 1


# --------------------------------------------------------------------------- writes out


def test_a_cycle_writes_what_changed_and_what_the_watchdog_would_miss() -> None:
    p = policy()
    femur, tibia, wheel = servo_id(0, "femur"), servo_id(0, "tibia"), servo_id(0, "wheel")
    p.start(0.0, {femur: 2000, tibia: 2100, wheel: 0})
    p.holding([femur, tibia, wheel])
    p.addressed([femur, tibia, wheel], 0.0)
    assert p.writes(0.01, set()) == []  # nothing changed, heard recently
    p.take(0.02, [msg(pos(0, FEMUR, 0.1), speed(0, 1.0))])
    writes = p.writes(0.02, set())
    assert [w.register for w in writes] == [GOAL_POSITION, GOAL_VELOCITY]
    assert writes[0].values == {femur: ct.rad_to_ticks(0.1)}
    assert list(writes[1].values) == [wheel]
    assert p.written(0.02, 0.021, writes, [COMM_SUCCESS, COMM_SUCCESS]) == []
    # Half a watchdog period later, the servos not written since are written again.
    writes = p.writes(KEEPALIVE_S, set())
    assert writes == [Write(GOAL_POSITION, {tibia: 2100})]
    # A servo out of the cycle is never written.
    p.take(0.06, [msg(pos(0, TIBIA, 0.2))])
    assert p.writes(0.06, {tibia}) == []


def test_a_write_that_did_not_go_out_is_reported_and_goes_out_next_cycle() -> None:
    p = policy()
    femur = servo_id(3, "femur")
    p.take(1.0, [msg(pos(3, FEMUR, 0.4))])
    writes = p.writes(1.0, set())
    events = p.written(1.0, 1.002, writes, [COMM_TX_FAIL])
    assert len(events) == 1
    failed = events[0]
    assert isinstance(failed, WriteFailed)
    assert (failed.t, failed.register, failed.servos, failed.result) == (
        1.002,
        "goal_position",
        1,
        "tx_fail",
    )
    assert p.write_failures == 1
    assert p.writes(1.01, set()) == [Write(GOAL_POSITION, {femur: ct.rad_to_ticks(0.4)})]


def test_a_restore_or_a_stop_counts_as_sent() -> None:
    p = policy()
    femur, wheel = servo_id(0, "femur"), servo_id(0, "wheel")
    p.start(0.0, {femur: 2000, wheel: 0})
    p.take(0.0, [msg(speed(0, 1.0))])
    p.restored(femur, 0.01)
    assert p.slots[femur].sent == 2000
    assert p.slots[femur].addressed_at == 0.01
    p.stopped([wheel])
    assert (p.slots[wheel].goal, p.slots[wheel].sent) == (0, 0)
