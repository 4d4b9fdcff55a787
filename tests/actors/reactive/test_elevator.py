"""The elevator reflex's policy, called directly: a blocked swing raises the step, up to
its bound; the raise is withdrawn once no swing has been blocked for its hold and the body
has walked its distance since; a swing that met something light and pushed it (the foot
went on) raises nothing."""

from __future__ import annotations

from collections.abc import Sequence

import pytest

from whexar.actors.messages import LegState, ReflexRequest, SwingEnded
from whexar.actors.reactive import check_params
from whexar.actors.reactive.elevator import Elevator
from whexar.config import RobotConfig
from whexar.testing.reflexes import locomotion_state


def elevator(**params: object) -> Elevator:
    return Elevator(check_params(Elevator, params), name="reflex-elevator", cfg=RobotConfig())


def ended(t: float, outcome: str, leg: int = 0) -> SwingEnded:
    return SwingEnded(t=t, source="leg", leg=leg, outcome=outcome, ground_offset_m=0.0)  # type: ignore[arg-type]


def raises(out: object) -> list[float | None]:
    return [r.step_raise_m for r in out if isinstance(r, ReflexRequest)]  # type: ignore[attr-defined]


def test_each_blocked_swing_raises_the_step_up_to_the_bound() -> None:
    e = elevator(confirm_s=0.0)
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
    e = elevator(hold_s=3.0, hold_m=0.0, confirm_s=0.0)
    e.react(1.0, ended(1.0, "blocked"))
    assert raises(e.tick(3.9)) == []
    e.react(2.0, ended(2.0, "blocked"))  # a new block: the hold starts again
    assert raises(e.tick(4.9)) == []
    assert raises(e.tick(5.0)) == [0.0]
    assert not e.active
    assert raises(e.tick(6.0)) == []


def walk(e: Elevator, t0: float, t1: float, activity: str = "walking") -> list[float | None]:
    """The coordinator's state every 10 ms from ``t0`` to ``t1``, then a tick: what is asked."""
    for k in range(round((t1 - t0) / 0.01) + 1):
        t = t0 + 0.01 * k
        e.react(t, locomotion_state(t, activity, twist=(0.1, 0.0, 0.0), gait="tetrapod"))
    return raises(e.tick(t1))


def test_the_raise_is_kept_until_the_body_has_walked_past_what_blocked() -> None:
    """A front foot's block is the rear feet's 0.67 m later: time alone does not say
    they are past it when the walk halts (a step around, a measurement) or is slow."""
    e = elevator(hold_s=1.0, hold_m=0.8, confirm_s=0.0)
    e.react(1.0, ended(1.0, "blocked"))
    assert walk(e, 1.0, 5.0, activity="standing") == []  # held still: 0 m walked
    assert walk(e, 5.0, 12.9) == []  # 0.79 m at 0.1 m/s
    e.react(13.0, ended(13.0, "blocked", leg=4))  # a rear leg meets it: counted afresh
    assert walk(e, 13.0, 20.9) == []
    assert walk(e, 20.9, 21.1) == [0.0]
    assert not e.active


def leg(t: float, error_m: float | None, leg: int = 0, phase: str = "swing") -> LegState:
    return LegState(
        t=t,
        source="leg",
        leg=leg,
        cycle=0,
        phase=phase,
        progress=0.3,
        foot=(0.2, 0.2, -0.1),
        measured_foot=None,
        contact=True,
        contact_source="fsr",
        load=(None, None),
        foot_error_m=error_m,
    )


def follow(e: Elevator, t0: float, errors: Sequence[float | None]) -> list[float | None]:
    """The leg's states every 10 ms from ``t0``, with these foot errors: what is asked."""
    out: list[float | None] = []
    for k, err in enumerate(errors):
        t = t0 + 0.01 * (k + 1)
        out += raises(e.react(t, leg(t, err)))
    return out


def test_a_blocked_swing_is_confirmed_by_the_foot_held_back() -> None:
    e = elevator()  # held_m 34 mm within confirm_s 0.25 s
    assert raises(e.react(1.0, ended(1.0, "blocked"))) == []  # not yet: is it held?
    # The foot falls behind its goal: 20 mm, growing past 34 mm at the 9th state.
    asked = follow(e, 1.0, [0.020 + 0.002 * k for k in range(12)])
    assert asked == [pytest.approx(0.03)]
    assert e.active


def test_a_light_obstacle_pushed_away_raises_nothing() -> None:
    e = elevator()
    e.react(1.0, ended(1.0, "blocked"))
    # The foot goes on: its error stays a swing's own (at most 27 mm) for confirm_s.
    assert follow(e, 1.0, [0.018 + 0.0003 * k for k in range(30)]) == []
    assert not e.active
    assert e.pushed == 1
    assert follow(e, 1.3, [0.05]) == []  # a late error is a new swing's affair


def test_a_leg_that_cannot_tell_is_taken_as_blocked() -> None:
    e = elevator()
    e.react(1.0, ended(1.0, "blocked"))
    assert follow(e, 1.0, [None] * 30) == [pytest.approx(0.03)]


def swings(e: Elevator, t0: float, peaks: list[float]) -> float:
    """Unblocked swings of leg 0 from ``t0``, each lagging up to its peak, then a stance."""
    t = t0
    for peak in peaks:
        for k in range(5):
            t = round(t + 0.01, 9)
            e.react(t, leg(t, peak * (k + 1) / 5))
        t = round(t + 0.01, 9)
        e.react(t, leg(t, 0.002, phase="stance"))
    return t


def test_a_swing_lagging_as_much_as_its_own_swings_do_is_not_held() -> None:
    # On 30° the wave's swings lag 35–60 mm by themselves; LR's foot scraped the slope
    # 61 mm behind its goal, its swings before lagging 55 mm: no block.
    e = elevator()
    t = swings(e, 0.0, [0.055])
    assert e.held(0) == pytest.approx(0.068)
    e.react(t, ended(t, "blocked"))
    assert follow(e, t, [0.060, 0.061, 0.060] + [0.05] * 25) == []
    assert e.pushed == 1
    # A foot held back past its own lag is a block.
    t = swings(e, t + 0.3, [0.055] * 3)
    e.react(t, ended(t, "blocked"))
    assert follow(e, t, [0.06 + 0.004 * k for k in range(10)]) == [pytest.approx(0.03)]


def test_on_the_flat_held_m_decides_and_a_met_swing_teaches_nothing() -> None:
    e = elevator()
    t = swings(e, 0.0, [0.019] * 4)  # the tripod's own lag: 18–19 mm
    assert e.held(0) == pytest.approx(0.034)
    e.react(t, ended(t, "blocked"))
    follow(e, t, [0.020] * 30)  # pushed: its 20 mm is its own lag, not learnt twice
    t = swings(e, t + 0.3, [])  # … and that swing ends: it met something, nothing learnt
    e.react(t + 0.01, leg(t + 0.01, 0.08))
    e.react(t + 0.02, leg(t + 0.02, 0.002, phase="stance"))
    assert e.lag[0] == pytest.approx(0.019)
