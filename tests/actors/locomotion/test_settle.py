"""A stance that settles (actors.locomotion.settle): the legs stop pushing each other."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import pytest

from tests.actors.locomotion.test_planner import PerfectLegs, activities, cmd, drive, standing
from whexar.actors.locomotion.settle import SETTLE_MIN_M, settled
from whexar.actors.messages import LegState, StepCommand

NEUTRAL = [(0.38, -0.25, -0.29), (0.38, 0.25, -0.29), (0.0, -0.26, -0.29)]


def test_each_goal_moves_toward_its_foot_less_the_legs_mean_error() -> None:
    goals = list(NEUTRAL)
    # Every foot dragged 30 mm inward, and all of them 10 mm back (a load the legs carry
    # together, as on a slope): only the inward part relaxes.
    measured = [
        (0.38 - 0.010, -0.25 + 0.030, -0.29),
        (0.38 - 0.010, 0.25 - 0.030, -0.29),
        (0.0 - 0.010, -0.26 + 0.030, -0.29),
    ]
    moves = settled(goals, goals, measured, NEUTRAL, fraction=0.5, limit_m=0.04)
    mean_y = (0.030 - 0.030 + 0.030) / 3
    for i in range(3):
        x, y, z = moves[i]
        assert x == pytest.approx(goals[i][0])  # the shared 10 mm back stays
        assert y == pytest.approx(goals[i][1] + 0.5 * (measured[i][1] - goals[i][1] - mean_y))
        assert z == goals[i][2]  # the height holds


def test_a_settled_foot_and_a_missing_one_are_left_alone() -> None:
    goals = list(NEUTRAL)
    measured = [(g[0] + SETTLE_MIN_M / 4, g[1], g[2]) for g in goals]
    assert settled(goals, goals, measured, NEUTRAL, fraction=0.5, limit_m=0.04) == {}
    assert settled([goals[0], None, None], goals, measured, NEUTRAL, fraction=1, limit_m=1) == {}


def test_no_goal_goes_further_than_the_limit_from_its_neutral_point() -> None:
    goals = list(NEUTRAL)
    measured = [(0.38, -0.25 + 0.2, -0.29), (0.38, 0.25, -0.29), (0.0, -0.26, -0.29)]
    moves = settled(goals, goals, measured, NEUTRAL, fraction=1.0, limit_m=0.04)
    assert math.dist(moves[0][:2], NEUTRAL[0][:2]) == pytest.approx(0.04)


Vec = tuple[float, float, float]


class _MeasuredLegs(PerfectLegs):
    """Perfect legs whose servos measure each foot at ``measure(leg, goal's point)``."""

    def __init__(self, legs: PerfectLegs, measure: Callable[[int, Vec], Vec]) -> None:
        super().__init__()
        self.steps, self.feet = legs.steps, legs.feet
        self.measure = measure

    def states(self, t: float, cycle: int) -> list[LegState]:
        out = super().states(t, cycle)
        return [dataclasses.replace(s, measured_foot=self.measure(s.leg, s.foot)) for s in out]


def _dragged_rf(legs: PerfectLegs, held: Vec) -> _MeasuredLegs:
    """Friction holds RF's wheel where it stands: the servos measure it there whatever its
    goal."""
    return _MeasuredLegs(legs, lambda leg, foot: held if leg == 0 else foot)


def test_standing_the_planner_moves_a_dragged_foot_s_goal_to_where_it_is() -> None:
    planner, legs = standing()
    foot = planner.feet[0]
    assert foot is not None
    held = (foot[0], foot[1] + 0.030, foot[2])  # 30 mm inward of its goal
    dragged = _dragged_rf(legs, held)
    said = drive(planner, dragged, 3.0, 6.0)
    moves = [m for m in said if isinstance(m, StepCommand) and m.kind == "move"]
    assert {m.leg for m in moves} == set(range(6))  # the others by the mean's share
    last = planner.feet[0]
    assert last is not None
    # Six time constants later RF's goal stands where its foot is, within the few
    # millimetres left alone (the legs share the last of it).
    assert abs(last[1] - held[1]) < 1.5 * SETTLE_MIN_M
    assert last[2] == foot[2]


def test_with_settling_off_the_goals_hold() -> None:
    planner, legs = standing()
    planner.loco = planner.loco.model_copy(update={"settle_s": 0.0})
    foot = planner.feet[0]
    assert foot is not None
    dragged = _dragged_rf(legs, (foot[0], foot[1] + 0.030, foot[2]))
    said = drive(planner, dragged, 3.0, 4.0)
    assert not [m for m in said if isinstance(m, StepCommand) and m.kind == "move"]


def _pushed(leg: int, foot: Vec) -> Vec:
    """Each foot measured a few millimetres sideways of its goal, the left and right legs
    apart: the settle always has a move to make."""
    return (foot[0], foot[1] + (0.006 if leg % 2 else -0.006), foot[2])


def test_a_gait_starts_though_the_standing_feet_settle() -> None:
    # The start places half the feet 50 mm ahead of their neutral points, beyond the
    # settle's 40 mm. The settle of the cycle the start began in pulled the ones already
    # there back to 40 mm, and the start placed them again, for good (the default course
    # stood still so at x = 5.9 m): the settle leaves a goal put further out where it is.
    planner, legs = standing()
    pushed = _MeasuredLegs(legs, _pushed)
    # LF and RM stand where the start puts them (the walk stopped there), LR does not.
    pushed.steps = dict(legs.steps)
    for leg, dx in ((1, 0.05), (2, 0.05)):
        step, _ = legs.steps[leg]
        x, y, z = planner.neutral_points[leg]
        pushed.steps[leg] = (dataclasses.replace(step, target=(x + dx, y, z)), step.target)
    said = drive(planner, pushed, 3.0, 7.0, commands={3.0: cmd(gait="tripod", vx_m_s=0.1)})
    changes = activities(said)
    assert ("standing", "walking") in changes, changes
    assert changes.count(("standing", "transition")) <= 2, changes
