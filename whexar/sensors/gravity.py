"""Is an accelerometer reading gravity? The plausibility check behind every static tilt.

Theory of operation
-------------------
Eq. 5.6–5.7 (Žák 2023, 5.4) turn an acceleration into roll and pitch on the
assumption that the sensor feels gravity and nothing else, so the reading
has a magnitude of 1 g. When it does not, the angles are wrong, and often
wildly: an analog accelerometer that is not fitted reads 0 V on every axis,
which the ADXL335 calibration turns into (−5, −5, −5) g and eq. 5.6–5.7 into
−135° of roll and pitch; a sensor in free fall, a shock or a broken
calibration do the same on a smaller scale. So a reading whose magnitude is
more than ``tolerance_g`` away from 1 g gives *no* tilt.

The default tolerance, :data:`GRAVITY_TOLERANCE_G` = 0.2 g, sits between
two needs:

* keep a good sensor: the thesis's own IMU readings (Table 6.4) have
  magnitudes of 0.96–1.02 g (its calibration error, 6.1.3), and a calibrated
  ADXL335 or LSM9DS1 stays within a few per cent;
* refuse what misleads: an unfitted analog accelerometer (8.7 g), a dead or
  unpowered one, free fall (0 g), a bump or a shock. A disturbance of δ g
  tilts the computed angle by up to asin(δ), 11.5° at 0.2 g — over half the
  smallest tilt threshold of the gait selector (20°, Table 5.9 with 6.7.5) —
  so a larger tolerance would let through readings worth less than none.

A magnitude test sees a disturbance along gravity in full but one across
it hardly (the magnitude becomes √(1 + δ²)): it catches the gross failures
above, not every sideways acceleration of a moving body, which only fusing
the gyroscope could.

:class:`GravityCheck` applies the rule to a stream of readings and says when
it *changes*, so that a reader reports one event when its readings become
implausible and one when they are plausible again, not one per sample. It is
sans-IO: values in, a verdict out, no clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final, Literal

from whexar.errors import UsageError
from whexar.kinematics.sensing import tilt_from_acceleration

GRAVITY_TOLERANCE_G: Final = 0.2
"""How far from 1 g a reading's magnitude may be and still give a tilt (module docstring)."""

Vector = tuple[float, float, float]


def magnitude_g(accel_g: Vector) -> float:
    """The length of an acceleration in g (``nan`` if any component is not finite)."""
    x, y, z = accel_g
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        return math.nan
    return math.sqrt(x * x + y * y + z * z)


def plausible(accel_g: Vector, tolerance_g: float = GRAVITY_TOLERANCE_G) -> bool:
    """Whether ``accel_g`` can be gravity: its magnitude within ``tolerance_g`` of 1 g."""
    return abs(magnitude_g(accel_g) - 1.0) <= tolerance_g  # nan compares False


@dataclass(frozen=True, slots=True)
class GravityVerdict:
    """What :meth:`GravityCheck.check` found for one reading.

    ``tilt`` is (roll, pitch) in rad by eq. 5.6–5.7, or ``None`` when the
    reading is implausible. ``change`` is ``"implausible"`` on the first
    implausible reading after plausible ones (or the first reading of all),
    ``"plausible"`` on the first plausible one after implausible ones, else
    ``None``. ``withheld`` is how many readings in a row gave no tilt, counted
    up to this one (on a ``"plausible"`` change: the run that just ended).
    """

    tilt: tuple[float, float] | None
    magnitude_g: float
    change: Literal["implausible", "plausible"] | None = None
    withheld: int = 0


class GravityCheck:
    """Tilt from a stream of accelerometer readings, withheld while they are not gravity."""

    __slots__ = ("implausible", "tolerance_g", "withheld")

    def __init__(self, tolerance_g: float = GRAVITY_TOLERANCE_G) -> None:
        if not 0.0 < tolerance_g < 1.0:
            raise UsageError(
                f"tolerance_g = {tolerance_g!r}: must lie in (0, 1) g "
                "(1 g or more would accept free fall)"
            )
        self.tolerance_g = tolerance_g
        self.implausible = False
        """The last reading was implausible."""
        self.withheld = 0

    def check(self, accel_g: Vector) -> GravityVerdict:
        """The tilt of ``accel_g``, or why there is none; see :class:`GravityVerdict`."""
        size = magnitude_g(accel_g)
        if abs(size - 1.0) <= self.tolerance_g:
            # Finite and near 1 g, so never the zero vector eq. 5.6-5.7 refuse.
            tilt = tilt_from_acceleration(*accel_g)
            if self.implausible:
                withheld, self.implausible, self.withheld = self.withheld, False, 0
                return GravityVerdict(tilt, size, "plausible", withheld)
            return GravityVerdict(tilt, size)
        self.withheld += 1
        if self.implausible:
            return GravityVerdict(None, size, None, self.withheld)
        self.implausible = True
        return GravityVerdict(None, size, "implausible", self.withheld)


__all__ = [
    "GRAVITY_TOLERANCE_G",
    "GravityCheck",
    "GravityVerdict",
    "magnitude_g",
    "plausible",
]
