"""Body height and pose over the feet, the trochanters following the pitch (eq. 4.18),
and walking on a CPG orbit's swing."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import pytest

from whexar.actors.locomotion.wire_goals import HALF_TICK_RAD
from whexar.actors.messages import (
    BodyMotion,
    BodyTilt,
    GoalClamped,
    GoalRefused,
    IkFailed,
    JointGoals,
    LegState,
    LocomotionState,
    ServoStates,
    SwingEnded,
)
from whexar.config import RobotConfig
from whexar.kinematics.leg import fk_point
from whexar.runtime.messages import ActorFailed
from whexar.testing import RunResult
from whexar.testing.walk import command, run_walk, walk_graph

# Whole walks on the emulators, a second or more each.
pytestmark = pytest.mark.slow

FULL_FEEDBACK = {"plan": "full_feedback"}


def _faults(run: RunResult) -> list[object]:
    kinds = (GoalClamped, GoalRefused, IkFailed, ActorFailed)
    return [e for kind in kinds for e in run.log.events(of=kind)]


def _trochanter_goals(run: RunResult, after: float) -> list[float]:
    """The trochanter goals in force after ``after``: each leg's last one before it, then
    every one sent (a leg sends a goal again only when it changed)."""
    before: dict[int, float] = {}
    later: list[float] = []
    for m in run.log.messages("goals", of=JointGoals):
        for g in m.goals:
            if g.joint != 1 or g.position_rad is None or m.reflex:
                continue
            if m.t <= after:
                before[g.leg] = g.position_rad
            else:
                later.append(g.position_rad)
    return [*before.values(), *later]


def test_a_commanded_pitch_turns_the_trochanters_and_keeps_the_feet() -> None:
    run = run_walk([(3.0, command(pitch_rad=0.15))], duration=6.0)
    assert _faults(run) == []
    motion = [m for m in run.log.messages("motion", of=BodyMotion) if 5.0 < m.t < 5.9]
    assert all(m.pose[4] == pytest.approx(0.15) for m in motion)
    assert all(m.trochanter_rad == pytest.approx(0.15) for m in motion)
    goals = _trochanter_goals(run, 5.0)
    assert goals
    assert all(g == pytest.approx(0.15, abs=HALF_TICK_RAD) for g in goals)
    # The feet stay where they stood: only the body turned over them.
    feet = [s.foot for s in run.log.messages("legs", of=LegState) if 5.0 < s.t < 5.9]
    standing = [s.foot for s in run.log.messages("legs", of=LegState) if 2.6 < s.t < 2.9]
    assert max(abs(a[0] - b[0]) for a, b in zip(feet[-6:], standing[-6:], strict=True)) < 1e-9


def test_the_trochanters_follow_the_measured_pitch_too() -> None:
    tilt = BodyTilt(
        t=0.0,
        source="imu",
        seq=1,
        sensor="imu",
        roll_rad=0.0,
        pitch_rad=0.2,
        accel_g=(0.0, 0.0, 1.0),
    )
    run = run_walk(duration=8.5, graph=walk_graph(tilt=True), messages=[(2.5, "tilt", tilt)])
    assert _faults(run) == []
    # The measured pitch goes through a low-pass (locomotion.tilt_filter_s = 1 s): the
    # trochanters turn smoothly, and 5 time constants later they stand at the slope.
    goals = _trochanter_goals(run, 2.5)
    assert goals
    assert max(abs(b - a) for a, b in itertools.pairwise(goals)) < 0.01
    late = _trochanter_goals(run, 8.0)
    assert late
    assert all(g == pytest.approx(0.2, abs=0.002 + HALF_TICK_RAD) for g in late)


def test_a_body_height_raises_the_body_over_the_standing_feet() -> None:
    graph = walk_graph(bus_params=FULL_FEEDBACK)
    run = run_walk([(3.0, command(body_height_m=0.33))], duration=7.0, graph=graph)
    assert _faults(run) == []
    motion = [m for m in run.log.messages("motion", of=BodyMotion) if 6.0 < m.t < 6.9]
    assert all(m.pose[2] == pytest.approx(0.33 - 0.29) for m in motion)
    # The feet stay on the ground (the neutral frame); the servos' angles put each wheel
    # 330 mm below its coxa joint: the body stands 40 mm higher.
    geometry = RobotConfig().leg_geometry()
    late = [m for m in run.log.messages("servo-state", of=ServoStates) if 6.5 < m.t < 6.9]
    assert late
    for states in late:
        for leg in range(6):
            angles = [j.position_rad for j in states.joints if j.leg == leg and j.joint < 5]
            assert None not in angles
            _, down, _ = fk_point([a for a in angles if a is not None], geometry)
            assert down == pytest.approx(0.33, abs=0.003)


@pytest.mark.parametrize("trajectory", ["half_sine", "hopf"])
def test_walking_on_another_swing_shape(trajectory: str, tmp_path: Path) -> None:
    config = tmp_path / "robot.toml"
    config.write_text(f'[locomotion]\ntrajectory = "{trajectory}"\n')
    run = run_walk(
        [(3.0, command(vx_m_s=0.08))], duration=8.0, graph=walk_graph(config=str(config))
    )
    assert _faults(run) == []
    # No contact sensing here: every swing runs its course.
    outcomes = {e.outcome for e in run.log.messages("swings", of=SwingEnded)}
    assert outcomes == {"completed"}
    swings = [s for s in run.log.messages("legs", of=LegState) if s.phase == "swing"]
    assert {s.leg for s in swings} == set(range(6))
    # The apex is the step height (60 mm) above the ground (290 mm below the coxa joints).
    top = max(s.foot[2] for s in swings)
    assert top == pytest.approx(-0.29 + 0.06, abs=0.004)
    states = run.log.messages("locomotion", of=LocomotionState)
    assert states[-1].t > 7.0
    assert any(s.activity == "walking" for s in states)
    assert not math.isnan(top)
