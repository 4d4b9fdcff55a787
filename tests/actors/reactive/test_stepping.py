"""The stepping reflex's policy, called directly: a stance foot kept from its goal is
stepped back, once per rest (6.7.1)."""

from __future__ import annotations

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
