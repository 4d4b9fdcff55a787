"""The stepping reflex's policy, called directly: a stance foot kept from its goal is
stepped back, once per rest (6.7.1)."""

from __future__ import annotations

import math

import pytest

from whexar.actors.messages import LegState, ReflexRequest
from whexar.actors.reactive import Command, check_params
from whexar.actors.reactive.stepping import Stepping
from whexar.config import RobotConfig
from whexar.testing.reflexes import leg_state


def stepping(**params: object) -> Stepping:
    return Stepping(check_params(Stepping, params), name="reflex-stepping", cfg=RobotConfig())


def state(t: float, error_m: float | None, phase: str = "stance", leg: int = 0) -> LegState:
    return leg_state(t, leg, phase, foot_error_m=error_m)


def requests(out: list[Command]) -> list[ReflexRequest]:
    return [m for m in out if isinstance(m, ReflexRequest)]


def feed(
    s: Stepping, t0: float, t1: float, error_m: float | None, phase: str = "stance"
) -> list[Command]:
    out: list[Command] = []
    k = 0
    while t0 + 0.01 * k < t1 - 1e-9:
        t = round(t0 + 0.01 * k, 6)
        out += s.react(t, state(t, error_m, phase))
        out += s.tick(t)
        k += 1
    return out


def test_a_stance_foot_kept_from_its_goal_is_stepped_back() -> None:
    s = stepping()
    assert requests(feed(s, 1.0, 2.0, 0.02)) == []  # within the walk's own error
    (req,) = requests(feed(s, 2.0, 2.5, 0.06))
    assert req.restep_leg == 0
    assert req.t == pytest.approx(2.2)  # held for hold_s
    assert s.active
    assert s.reason == "RF kept 60 mm from its goal: stepped back"


def test_once_per_rest_then_quiet() -> None:
    s = stepping(rest_s=2.0)
    first = requests(feed(s, 1.0, 3.0, 0.06))
    assert len(first) == 1
    assert s.active
    again = requests(feed(s, 3.0, 3.5, 0.06))
    assert len(again) == 1  # the rest over, still kept: stepped again
    feed(s, 3.5, 6.0, 0.01)
    assert not s.active


@pytest.mark.parametrize(("phase", "error"), [("swing", 0.08), ("stance", None)])
def test_only_a_stance_with_a_known_error_counts(phase: str, error: float | None) -> None:
    assert requests(feed(stepping(), 1.0, 2.0, error, phase)) == []


def test_it_holds_back_the_searching_and_elevator_reflexes() -> None:
    assert set(Stepping.inhibits) == {"reflex-searching", "reflex-elevator"}


def test_a_leg_whose_error_spreads_wide_is_kept_only_beyond_its_spread() -> None:
    # A loaded rear leg on 30°: its stance error swings 10–46 mm with the stride (about a
    # 28 mm mean, 13 mm standard deviation), which is its load, not a leg kept away.
    s = stepping()
    feed(s, 0.0, 1.0, 0.028, "hold")  # it stood on the slope before it walked
    out: list[Command] = []
    for k in range(2000):
        t = 1.0 + 0.01 * k
        err = 0.028 + 0.018 * math.sin(2 * math.pi * t / 1.5)
        out += s.react(t, state(t, err))
    assert requests(out) == []
    assert s.limit(0) > 0.028 + 0.04
    # The same leg snagged: far beyond its spread, stepped back.
    (req,) = requests(feed(s, 21.0, 21.5, 0.09))
    assert req.restep_leg == 0
    # A leg steady at 10 mm is kept at 35 mm (error_m over its usual), its spread small.
    steady = stepping()
    feed(steady, 1.0, 5.0, 0.01)
    assert steady.limit(0) == pytest.approx(0.035, abs=1e-3)


def test_an_error_falling_after_a_touchdown_is_the_servos_catching_up() -> None:
    s = stepping()
    feed(s, 1.0, 3.0, 0.01)
    out: list[Command] = []
    for k in range(30):  # 70 mm at the touchdown, 1.5 mm less each cycle
        t = 3.0 + 0.01 * k
        out += s.react(t, state(t, 0.07 - 0.0015 * k))
    assert requests(out) == []
    # Held where it is instead (a snag): stepped back after hold_s.
    assert len(requests(feed(s, 3.3, 3.6, 0.05))) == 1
