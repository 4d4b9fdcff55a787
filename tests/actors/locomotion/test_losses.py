"""A lost servo reported to the coordinator, which walks on without it where it can
(:mod:`whexar.actors.locomotion.losses`): the watch of the reads, then the policy."""

from __future__ import annotations

import math
from collections.abc import Callable

import pytest

from tests.actors.locomotion.test_planner import CFG, T0, cmd, drive, standing, walked
from whexar.actors.locomotion.losses import LostJoints
from whexar.actors.messages import (
    BodyMotion,
    CommandRefused,
    JointBack,
    JointLost,
    JointState,
    LocomotionState,
    ServoStates,
    StepCommand,
)
from whexar.robot import N_LEGS

RM, COXA, TROCHANTER, DIRECTION = 2, 0, 1, 5


def states(t: float, keys: list[tuple[int, int]]) -> ServoStates:
    joints = tuple(JointState(leg, j, 1 + leg * 7 + j, 0.1) for leg, j in keys)
    return ServoStates(t=t, source="bus", cycle=round(t * 100), joints=joints)


def test_a_joint_unread_for_lost_after_s_is_lost_and_back_once_read() -> None:
    watch = LostJoints(0.3)
    every, rare = (0, 0), (0, 1)
    found: list[tuple[float, list[tuple[int, int]], list[tuple[int, int]]]] = []
    for k in range(300):
        t = k * 0.01
        keys = []
        if t < 1.0 or t >= 2.0:
            keys.append(every)  # read every cycle, but not from 1 s to 2 s
        if k % 50 == 0 and t < 1.5:
            keys.append(rare)  # read every half second, then no more
        lost, back = watch.take(states(t, keys))
        if lost or back:
            found.append((round(t, 2), lost, back))
    # The every-cycle joint: lost 0.3 s (checked every 75 ms) after its last read, back when
    # read. The rare one: after three of its periods (1.5 s), not after lost_after_s.
    (t_lost, lost, _), (t_back, _, back), (t_rare, rare_lost, _) = found
    assert lost == [every]
    assert 1.29 < t_lost <= 1.39
    assert back == [every]
    assert t_back == 2.0
    assert rare_lost == [rare]
    assert 2.5 < t_rare <= 2.6


def test_a_joint_read_once_is_never_judged() -> None:
    watch = LostJoints(0.3)
    watch.take(states(0.0, [(0, 1)]))
    assert watch.take(states(10.0, [])) == ([], [])


def all_joints_but(
    lost: set[tuple[int, int]], from_t: float, until_t: float = math.inf
) -> Callable[[float], tuple[JointState, ...]]:
    keys = [(leg, j) for leg in range(N_LEGS) for j in range(7)]

    def joints(t: float) -> tuple[JointState, ...]:
        gone = from_t <= t < until_t
        return tuple(
            JointState(leg, j, 1 + leg * 7 + j, 0.0, 0.0)
            for leg, j in keys
            if not (gone and (leg, j) in lost)
        )

    return joints


def test_a_lost_coxa_leg_rides_its_wheel_while_the_others_walk() -> None:
    t0 = T0
    _, said = walked(8.0, joints=all_joints_but({(RM, COXA)}, t0 + 2.0))
    lost = [e for e in said if isinstance(e, JointLost)]
    assert [(e.leg, e.joint) for e in lost] == [(RM, COXA)]
    assert "rides its wheel" in lost[0].action
    at = lost[0].t
    assert t0 + 2.3 <= at < t0 + 2.4
    after = [m for m in said if m.t > at + 1.0]
    # It never lifts again, and it rides; the others go on swinging.
    swings = [m for m in after if isinstance(m, StepCommand) and m.kind == "swing"]
    assert swings
    assert all(s.leg != RM for s in swings)
    rides = [m for m in said if isinstance(m, StepCommand) and m.leg == RM and m.kind == "ride"]
    assert rides
    # Its wheel rolls at the body's speed (straight ahead: the same speed), the others held.
    motion = [m for m in after if isinstance(m, BodyMotion) and m.twist[0] > 0.09]
    assert motion
    assert all(m.steer_legs == (RM,) and not m.steer for m in motion)
    for m in motion:
        assert m.wheel_speed_m_s[RM] == pytest.approx(m.twist[0], rel=1e-6)
        assert all(v == 0.0 for i, v in enumerate(m.wheel_speed_m_s) if i != RM)
    # It still carries its share: the walk keeps its margin and its speed.
    walking = [m for m in after if isinstance(m, LocomotionState) and m.activity == "walking"]
    assert walking
    assert max(s.twist[0] for s in walking) == pytest.approx(0.1)
    assert min(s.margin_m for s in walking) >= CFG.locomotion.min_stability_margin_mm / 1000


def test_a_coxa_read_again_walks_its_leg_again() -> None:
    t0 = T0
    planner, said = walked(8.0, joints=all_joints_but({(RM, COXA)}, t0 + 1.0, t0 + 3.0))
    back = [e for e in said if isinstance(e, JointBack)]
    assert [(e.leg, e.joint, e.t) for e in back] == [(RM, COXA, t0 + 3.0)]
    swings = [m for m in said if isinstance(m, StepCommand) and m.kind == "swing" and m.t > t0 + 3]
    assert any(s.leg == RM for s in swings)
    assert not planner.riders


def test_a_lost_wheel_refuses_riding_and_a_lost_trochanter_holds_its_angle() -> None:
    planner, legs = standing()
    t0 = 3.0
    said = drive(
        planner,
        legs,
        t0,
        t0 + 3.0,
        {t0 + 1.0: cmd(mode="ride")},
        joints=all_joints_but({(RM, DIRECTION), (0, TROCHANTER)}, t0 + 0.5),
    )
    lost = {(e.leg, e.joint): e.action for e in said if isinstance(e, JointLost)}
    assert "riding refused" in lost[(RM, DIRECTION)]
    assert "trochanters hold" in lost[(0, TROCHANTER)]
    refused = [e for e in said if isinstance(e, CommandRefused)]
    assert refused
    assert "wheel of RM is lost" in refused[0].reason
    assert planner.mode == "walk"
    assert planner.want.mode == "walk"
    assert planner.trochanter_held == 0.0


def test_the_trochanters_hold_until_every_lost_one_is_back() -> None:
    planner, legs = standing()
    t0 = 3.0
    first = all_joints_but({(0, TROCHANTER)}, t0, t0 + 2.0)
    second = all_joints_but({(1, TROCHANTER)}, t0 + 1.0, t0 + 4.0)

    def joints(t: float) -> tuple[JointState, ...]:
        both = set(second(t))
        return tuple(j for j in first(t) if j in both)

    drive(planner, legs, t0, t0 + 3.0, joints=joints)
    assert planner.trochanter_held == 0.0  # the first is back, the second still lost
    said = drive(planner, legs, t0 + 3.0, t0 + 5.0, joints=joints)
    assert [(e.leg, e.joint) for e in said if isinstance(e, JointBack)] == [(1, TROCHANTER)]
    assert planner.trochanter_held is None
