"""Scalar argument checks: a bad number is a typed error naming it, never a NaN later."""

import math

import numpy as np
import pytest

from whexar.errors import UsageError
from whexar.kinematics.wheels import wheel_straight
from whexar.runtime.checks import non_negative, positive, real


@pytest.mark.parametrize("bad", ["1.0", None, True, math.nan, -math.inf, [1.0]])
def test_real_refuses_what_is_not_a_finite_number(bad: object) -> None:
    with pytest.raises(UsageError, match="speed = "):
        real("speed", bad)


def test_sign_checks_name_the_unit() -> None:
    assert real("x", np.float32(2.5)) == 2.5
    assert positive("radius", 3) == 3.0
    assert non_negative("height", 0.0) == 0.0
    with pytest.raises(UsageError, match=r"radius = 0: must be > 0 m"):
        positive("radius", 0, "m")
    with pytest.raises(UsageError, match=r"height = -1: must be ≥ 0"):
        non_negative("height", -1)


def test_wheels_refuse_a_string_speed() -> None:
    contacts = np.zeros((6, 2))
    with pytest.raises(UsageError, match="speed = 'fast'"):
        wheel_straight(contacts, "fast", wheel_radius=0.033)  # type: ignore[arg-type]
