"""The plausibility check behind every static tilt: a reading must be gravity to give one."""

from __future__ import annotations

import math

import pytest

from whexar.errors import UsageError
from whexar.kinematics.sensing import tilt_from_acceleration
from whexar.sensors.gravity import (
    GRAVITY_TOLERANCE_G,
    GravityCheck,
    magnitude_g,
    plausible,
)
from whexar.testing import thesis

G = 9.81


def test_the_thesis_imu_readings_are_all_plausible() -> None:
    # Table 6.4 (6.1.3): 0.96–1.02 g, its calibration error; every row gives a tilt.
    for _, x, y, z, _ in thesis.TABLE_6_4:
        assert plausible((x / G, y / G, z / G))
        assert 0.96 < magnitude_g((x / G, y / G, z / G)) < 1.02


def test_what_is_not_gravity() -> None:
    # An unfitted ADXL335 read at 0 V on the default calibration: (-5, -5, -5) g.
    unfitted = ((0 - 337.6) / 67.5,) * 3
    assert magnitude_g(unfitted) == pytest.approx(8.66, abs=0.01)
    assert not plausible(unfitted)
    assert tilt_from_acceleration(*unfitted) == pytest.approx((-3 * math.pi / 4,) * 2)  # -135°
    assert not plausible((0.0, 0.0, 0.0))  # free fall
    assert not plausible((0.0, 0.0, math.nan))
    assert not plausible((0.0, 0.0, math.inf))
    assert plausible((0.0, 0.0, 1.0 + GRAVITY_TOLERANCE_G))  # the bound is inclusive
    assert not plausible((0.0, 0.0, 1.0 + GRAVITY_TOLERANCE_G + 1e-9))
    assert not plausible((0.0, 0.0, 1.0 - GRAVITY_TOLERANCE_G - 1e-9))


def test_check_reports_changes_once_each_way() -> None:
    check = GravityCheck(0.2)
    level = check.check((0.0, 0.0, 1.0))
    assert level.tilt == (0.0, 0.0)
    assert level.change is None
    verdicts = [check.check((0.0, 0.0, 0.0)), check.check((0.0, 0.0, 2.0))]
    assert [v.change for v in verdicts] == ["implausible", None]
    assert [v.tilt for v in verdicts] == [None, None]
    assert [v.withheld for v in verdicts] == [1, 2]
    back = check.check((0.0, math.sin(0.3), math.cos(0.3)))
    assert back.change == "plausible"
    assert back.withheld == 2
    assert back.tilt == pytest.approx((0.0, 0.3))
    again = check.check((0.0, 0.0, 1.05))
    assert (again.change, again.withheld) == (None, 0)


def test_the_first_reading_may_already_be_implausible() -> None:
    first = GravityCheck().check((-5.0, -5.0, -5.0))
    assert first.change == "implausible"
    assert first.tilt is None


def test_tolerance_must_stay_below_1_g() -> None:
    for bad in (0.0, 1.0, -0.1, math.nan):
        with pytest.raises(UsageError, match="tolerance_g"):
            GravityCheck(bad)


def test_a_short_run_withholds_the_tilt_and_says_nothing() -> None:
    # A footfall's shock: 0.02-0.1 s out of the band (docs/robot.md); the hold-off is 0.25 s.
    check = GravityCheck(0.2, hold_s=0.25)
    shock = [check.check((0.0, 0.0, 1.5), t) for t in (1.00, 1.02, 1.04, 1.06, 1.08, 1.10)]
    assert [v.tilt for v in shock] == [None] * 6
    assert [v.change for v in shock] == [None] * 6
    after = check.check((0.0, 0.0, 1.0), 1.12)
    assert (after.change, after.withheld, after.tilt) == (None, 0, (0.0, 0.0))


def test_a_lasting_run_is_said_once_the_hold_off_has_passed() -> None:
    check = GravityCheck(0.2, hold_s=0.25)
    times = [2.0 + 0.02 * k for k in range(20)]
    changes = [check.check((0.0, 0.0, 0.0), t).change for t in times]
    first = changes.index("implausible")
    assert times[first] - times[0] == pytest.approx(0.26)  # the first reading ≥ 0.25 s in
    assert changes.count("implausible") == 1
    back = check.check((0.0, 0.0, 1.0), 2.5)
    assert (back.change, back.withheld) == ("plausible", 20)


def test_the_hold_off_must_be_a_time() -> None:
    for bad in (-0.1, math.nan, math.inf):
        with pytest.raises(UsageError, match="hold_s"):
            GravityCheck(0.2, hold_s=bad)
