"""The elevator reflex's policy, called directly: a blocked swing raises the step, up to
its bound; the raise is withdrawn once no swing has been blocked for its hold."""

from __future__ import annotations

import pytest

from whexar.actors.messages import ReflexRequest, SwingEnded
from whexar.actors.reactive import check_params
from whexar.actors.reactive.elevator import Elevator
from whexar.config import RobotConfig


def elevator(**params: object) -> Elevator:
    return Elevator(check_params(Elevator, params), name="reflex-elevator", cfg=RobotConfig())


def ended(t: float, outcome: str, leg: int = 0) -> SwingEnded:
    return SwingEnded(t=t, source="leg", leg=leg, outcome=outcome, ground_offset_m=0.0)  # type: ignore[arg-type]


def raises(out: object) -> list[float | None]:
    return [r.step_raise_m for r in out if isinstance(r, ReflexRequest)]  # type: ignore[attr-defined]


def test_each_blocked_swing_raises_the_step_up_to_the_bound() -> None:
    e = elevator()
    assert raises(e.react(1.0, ended(1.0, "blocked"))) == [pytest.approx(0.03)]
    assert e.active
    assert e.reason == "leg 0 blocked on its way up: the step +3 cm"
    assert raises(e.react(1.5, ended(1.5, "blocked", leg=1))) == [pytest.approx(0.06)]
    assert raises(e.react(2.0, ended(2.0, "blocked"))) == []  # at its bound: nothing new


@pytest.mark.parametrize("outcome", ["completed", "early_contact", "no_contact"])
def test_other_swing_ends_raise_nothing(outcome: str) -> None:
    e = elevator()
    assert raises(e.react(1.0, ended(1.0, outcome))) == []
    assert not e.active


def test_the_raise_is_withdrawn_after_the_hold_without_a_block() -> None:
    e = elevator(hold_s=3.0)
    e.react(1.0, ended(1.0, "blocked"))
    assert raises(e.tick(3.9)) == []
    e.react(2.0, ended(2.0, "blocked"))  # a new block: the hold starts again
    assert raises(e.tick(4.9)) == []
    assert raises(e.tick(5.0)) == [0.0]
    assert not e.active
    assert raises(e.tick(6.0)) == []
