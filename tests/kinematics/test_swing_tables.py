"""The scalar fast paths of the foot trajectories: the minimum-jerk blend and the swing
tables a leg controller reads every cycle."""

from __future__ import annotations

import numpy as np
import pytest

from whexar.kinematics.cpg import OSCILLATORS
from whexar.kinematics.trajectory import SWING_SAMPLES, TRAJECTORIES, min_jerk, swing_table

DUTY_FACTORS = (0.5, 2 / 3, 5 / 6)
"""Tripod; tetrapod and ripple; wave."""


# --------------------------------------------------------------------------- min_jerk


def test_min_jerk_ends_middle_and_clamp() -> None:
    assert min_jerk(0.0) == 0.0
    assert min_jerk(1.0) == 1.0
    assert min_jerk(0.5) == pytest.approx(0.5)
    assert min_jerk(-0.3) == 0.0
    assert min_jerk(1.7) == 1.0


def test_min_jerk_is_monotonic_symmetric_and_starts_and_stops_at_rest() -> None:
    u = np.linspace(0.0, 1.0, 1001)
    s = np.array([min_jerk(float(x)) for x in u])
    assert np.all(np.diff(s) >= 0.0)
    np.testing.assert_allclose(s + s[::-1], 1.0, atol=1e-12)
    h = 1e-4
    for end in (0.0, 1.0 - h):
        assert (min_jerk(end + h) - min_jerk(end)) / h < 1e-6  # no speed at either end
    peak = (min_jerk(0.5 + h) - min_jerk(0.5 - h)) / (2 * h)
    assert peak == pytest.approx(1.875, rel=1e-6)  # 30u²(1 − u)² at u = ½


# --------------------------------------------------------------------------- swing shapes


@pytest.mark.parametrize("beta", DUTY_FACTORS)
@pytest.mark.parametrize("name", TRAJECTORIES)
def test_swing_table_table(name: str, beta: float) -> None:
    shape = swing_table(name, beta)
    assert shape.name == name
    u, f, h = np.array(shape.u), np.array(shape.forward), np.array(shape.height)
    assert len(u) == len(f) == len(h) == SWING_SAMPLES + 1
    assert (u[0], u[-1]) == (0.0, 1.0)
    assert np.all(np.diff(u) > 0.0)
    # Forward progress goes from the lift-off point (0) to the target (1).
    assert f[0] == pytest.approx(0.0, abs=1e-12)
    assert f[-1] == pytest.approx(1.0, abs=1e-12)
    if name in OSCILLATORS:
        # A CPG orbit may swing back a little, or past the target, on its way (stick-slip
        # does), but not by much, nor jerkily.
        assert f.min() >= -0.15
        assert f.max() <= 1.05
        assert np.all(np.diff(f) >= -0.02)
    else:
        assert np.all(np.diff(f) >= -1e-12)
    # Height: on the ground at both ends, never below it, at most the step height.
    assert h[0] == h[-1] == 0.0
    assert np.all(h >= 0.0)
    assert h.max() <= 1.0 + 1e-9
    assert 0.0 < shape.apex_u < 1.0
    assert h[round(shape.apex_u * SWING_SAMPLES)] == h.max()


@pytest.mark.parametrize("beta", DUTY_FACTORS)
@pytest.mark.parametrize(
    "name",
    TRAJECTORIES,
)
def test_swing_table_reaches_the_step_height(name: str, beta: float) -> None:
    """A swing's apex is the commanded step height (StepCommand.height_m): max h = 1."""
    assert max(swing_table(name, beta).height) == pytest.approx(1.0, abs=0.01)


@pytest.mark.parametrize("name", TRAJECTORIES)
def test_swing_table_lookup_interpolates_and_clamps(name: str) -> None:
    shape = swing_table(name, 0.5)
    assert shape.at(0.0) == pytest.approx((0.0, 0.0), abs=1e-12)
    assert shape.at(1.0) == pytest.approx((1.0, 0.0), abs=1e-12)
    assert shape.at(-0.2) == shape.at(0.0)
    assert shape.at(1.3) == shape.at(1.0)
    k = SWING_SAMPLES // 4
    assert shape.at(shape.u[k]) == pytest.approx((shape.forward[k], shape.height[k]))
    middle = 0.5 * (shape.u[k] + shape.u[k + 1])
    f, h = shape.at(middle)
    assert f == pytest.approx(0.5 * (shape.forward[k] + shape.forward[k + 1]))
    assert h == pytest.approx(0.5 * (shape.height[k] + shape.height[k + 1]))


def test_swing_tables_are_cached_per_duty_factor() -> None:
    assert swing_table("parabola", 0.5) is swing_table("parabola", 0.5)
    assert swing_table("parabola", 2 / 3) is swing_table("parabola", 2.0 / 3.0)
    assert swing_table("hopf", 0.5) is not swing_table("hopf", 5 / 6)
