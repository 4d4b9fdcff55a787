"""A stance shares its load (:mod:`whexar.actors.locomotion.steps`), called directly."""

from __future__ import annotations

import pytest

from whexar.actors.locomotion.steps import Step, advance, load_error
from whexar.config import RobotConfig

CFG = RobotConfig().contact
DT = 0.01
GAIN = 5e-5
"""m/s per count: the default, which the reflex campaign measured (docs/reflexes.md)."""


def stance(*, gain: float = GAIN) -> Step:
    return Step(
        "stance",
        0.0,
        10.0,
        [0.2, -0.1, -0.29],
        (0.2, -0.1, -0.29),
        0.0,
        None,
        balance_gain=gain,
        balance_speed=CFG.balance_speed_m_s,
        balance_m=CFG.balance_m,
    )


def hold_for(step: Step, foot: list[float], seconds: float, load_error: float | None) -> str:
    phase = ""
    for k in range(round(seconds / DT)):
        phase, _, outcome = advance(
            step, foot, (0.0, 0.0, 0.0), (k + 1) * DT, DT, True, "fsr", load_error
        )
        assert outcome is None
    return phase


def test_a_foot_that_carries_less_than_the_others_goes_down_one_that_carries_more_up() -> None:
    light, heavy = stance(), stance()
    a, b = [0.2, -0.1, -0.29], [0.2, -0.1, -0.29]
    # 100 counts below the loaded feet's mean, 100 above, for 0.2 s: 5e-5 · 100 = 5 mm/s.
    assert hold_for(light, a, 0.2, 100.0) == "stance"
    hold_for(heavy, b, 0.2, -100.0)
    assert a[2] == pytest.approx(-0.29 - 0.001)
    assert b[2] == pytest.approx(-0.29 + 0.001)  # the two moves sum to nothing
    assert a[:2] == [0.2, -0.1]  # only the height


def test_a_foot_that_carries_nothing_goes_down_at_most_so_fast_and_so_far() -> None:
    step, foot = stance(), [0.2, -0.1, -0.29]
    hold_for(step, foot, 0.5, 700.0)  # 5e-5 · 700 = 35 mm/s, held to 20 mm/s
    assert foot[2] == pytest.approx(-0.29 - CFG.balance_speed_m_s * 0.5)
    hold_for(step, foot, 5.0, 700.0)
    assert foot[2] == pytest.approx(-0.29 - CFG.balance_m)


def test_without_a_load_reading_or_a_gain_the_foot_holds_its_height() -> None:
    step, foot = stance(), [0.2, -0.1, -0.29]
    hold_for(step, foot, 1.0, None)
    assert foot[2] == -0.29
    step, foot = stance(gain=0.0), [0.2, -0.1, -0.29]
    hold_for(step, foot, 1.0, 500.0)
    assert foot[2] == -0.29


def test_the_load_error_is_against_the_loaded_feet_and_needs_three_of_them() -> None:
    on = (True, True, True, False, False, False)
    assert load_error((100, 400, 400, 0, 0, 0), on, 0) == pytest.approx(200.0)
    assert load_error((100, 400, 400, 0, 0, 0), on, 3) == pytest.approx(300.0)
    assert load_error((100, 400, 0, 0, 0, 0), (True, True) + (False,) * 4, 0) is None
