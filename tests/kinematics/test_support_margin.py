"""The scalar support margin (a coordinator asks it every cycle) is the vectorised one."""

from __future__ import annotations

import math

import numpy as np
import pytest

from whexar.kinematics.stability import static_stability_margin, support_margin


@pytest.mark.parametrize("seed", range(40))
def test_support_margin_matches_static_stability_margin(seed: int) -> None:
    rng = np.random.default_rng(seed)
    k = int(rng.integers(3, 7))
    points = rng.uniform(-0.4, 0.4, (k, 2))
    cog = rng.uniform(-0.2, 0.2, 2)
    expected = static_stability_margin(points, cog)
    got = support_margin([(float(x), float(y)) for x, y in points], (float(cog[0]), float(cog[1])))
    assert got == pytest.approx(expected, abs=1e-12)


def test_fewer_than_three_supports_have_no_margin() -> None:
    assert support_margin([(0.0, 0.0), (1.0, 0.0)], (0.0, 0.0)) == -math.inf


@pytest.mark.parametrize(
    "points",
    [
        [(0.0, 0.0), (1.0, 0.0), (2.0, 0.0)],  # collinear
        [(0.5, 0.5), (0.5, 0.5), (0.5, 0.5)],  # coincident
        [(0.0, 0.0), (1.0, 1.0), (0.0, 0.0), (1.0, 1.0)],  # two points, twice
    ],
)
def test_degenerate_supports_agree_too(points: list[tuple[float, float]]) -> None:
    cog = (0.3, -0.2)
    assert support_margin(points, cog) == pytest.approx(
        static_stability_margin(np.array(points), cog), abs=1e-12
    )
    assert support_margin(points, cog) <= 0.0
