"""Riding within what the wheel servos can do, with the read plan the robot runs by default."""

from __future__ import annotations

import pytest

from whexar.actors.messages import (
    CommandClamped,
    GoalClamped,
    GoalRefused,
    IkFailed,
    LocomotionChanged,
    LocomotionState,
)
from whexar.runtime.messages import ActorFailed
from whexar.testing.walk import command, run_walk

# Whole rides on the emulators, a second or more each.
pytestmark = pytest.mark.slow


def test_riding_at_the_thesis_top_speed_is_limited_by_the_wheel_servo() -> None:
    # 0.2 m/s (6.5.1) turns a 33 mm wheel at 6.1 rad/s, beyond the MX-28's Velocity Limit
    # of 230 × 0.229 rev/min (5.5 rad/s): the coordinator clamps, the bus never has to.
    run = run_walk([(3.0, command(mode="ride", vx_m_s=0.2))], duration=9.0)
    clamped = run.log.events(of=CommandClamped)
    assert [c.field for c in clamped] == ["speed"]
    assert clamped[0].applied < 0.2
    assert "Velocity Limit" in clamped[0].reason
    for bad in (GoalClamped, GoalRefused, IkFailed, ActorFailed):
        assert run.log.events(of=bad) == []
    riding = [s for s in run.log.messages("locomotion", of=LocomotionState) if 7.5 < s.t < 8.5]
    assert riding[-1].activity == "riding"
    assert riding[-1].twist[0] == clamped[0].applied


def test_alignment_without_direction_readings_waits_for_the_turn_not_the_timeout() -> None:
    # The default read plan reads no direction servo: the wait is the turn at the servo's
    # Velocity Limit, well under align_timeout_s (1.5 s), and the servos are there by then.
    run = run_walk([(3.0, command(mode="ride", vy_m_s=0.1))], duration=8.0)
    activity = [
        (e.t, e.after) for e in run.log.events(of=LocomotionChanged) if e.what == "activity"
    ]
    mode_at = next(e.t for e in run.log.events(of=LocomotionChanged) if e.what == "mode")
    align_start = next(t for t, a in activity if a == "transition" and t >= mode_at)
    align_end = next(t for t, a in activity if t > align_start and a != "transition")
    assert 0.1 < align_end - align_start < 1.0
