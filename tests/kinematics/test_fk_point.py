"""The scalar forward kinematics a leg controller asks every cycle (:func:`fk_point`) is
:func:`fk` of one pose."""

from __future__ import annotations

import math

import numpy as np
import pytest

from whexar._typing import FloatArray
from whexar.config import RobotConfig
from whexar.kinematics.leg import fk, fk_point

GEOMETRY = RobotConfig().leg_geometry()
FLIPPED_TROCHANTER = -math.pi
"""A flipped leg's trochanter (the leg controller's)."""


def random_angles(n: int, seed: int) -> FloatArray:
    """``n`` joint angle sets within the limits; the trochanter (±360°) within one turn."""
    rng = np.random.default_rng(seed)
    lo = np.maximum(GEOMETRY.lower_limits, -math.pi)
    hi = np.minimum(GEOMETRY.upper_limits, math.pi)
    return rng.uniform(lo, hi, size=(n, 5))


def test_fk_point_is_the_dh_chain() -> None:
    angles = random_angles(500, seed=5)
    assert np.any(np.abs(angles[:, 1]) > 1.0)  # the trochanter really turns
    want = fk(angles, GEOMETRY, point="contact")
    got = np.array([fk_point(list(a), GEOMETRY) for a in angles])
    np.testing.assert_allclose(got, want, atol=1e-12)


@pytest.mark.parametrize("trochanter", [0.0, 0.3, -0.7, math.pi / 2, FLIPPED_TROCHANTER])
def test_fk_point_at_chosen_trochanter_angles(trochanter: float) -> None:
    angles = random_angles(50, seed=11)
    angles[:, 1] = trochanter
    want = fk(angles, GEOMETRY, point="contact")
    got = np.array([fk_point(list(a), GEOMETRY) for a in angles])
    np.testing.assert_allclose(got, want, atol=1e-12)


def test_fk_point_of_a_flipped_leg_mirrors_it() -> None:
    """Turned by −π about its long axis the leg reaches as far, on the other side (y)."""
    angles = random_angles(50, seed=3)
    angles[:, 1] = 0.0
    flipped = angles.copy()
    flipped[:, 1] = FLIPPED_TROCHANTER
    for a, b in zip(angles, flipped, strict=True):
        x, y, z = fk_point(list(a), GEOMETRY)
        assert fk_point(list(b), GEOMETRY) == pytest.approx((x, -y, z), abs=1e-12)
