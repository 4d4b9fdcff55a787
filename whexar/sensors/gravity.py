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
sans-IO: values and their times in, a verdict out, no clock.

*Hold-off.* Every implausible reading withholds its tilt at once, but the
change is said only once the readings have stayed implausible for ``hold_s``:
a walking robot's accelerometer leaves the 1 g band for a sample or a few at
every footfall (the shock of a foot landing), and a warning per footfall would
drown the one that means trouble. A failure — a sensor unplugged, not fitted,
a robot falling over — lasts; a footfall does not (docs/robot.md, "The
accelerometer's hold-off", gives the measured runs).
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
    """Tilt from a stream of accelerometer readings, withheld while they are not gravity;
    a change said once it has held for ``hold_s`` (module docstring; 0: at once)."""

    __slots__ = ("hold_s", "implausible", "since", "tolerance_g", "withheld")

    def __init__(self, tolerance_g: float = GRAVITY_TOLERANCE_G, hold_s: float = 0.0) -> None:
        if not 0.0 < tolerance_g < 1.0:
            raise UsageError(
                f"tolerance_g = {tolerance_g!r}: must lie in (0, 1) g "
                "(1 g or more would accept free fall)"
            )
        if not (math.isfinite(hold_s) and hold_s >= 0.0):
            raise UsageError(f"hold_s = {hold_s!r}: must be a number of seconds ≥ 0")
        self.tolerance_g = tolerance_g
        self.hold_s = hold_s
        self.implausible = False
        """Implausible readings have been said (they held for ``hold_s``)."""
        self.since: float | None = None
        """Time of the first implausible reading of the present run, if one is under way."""
        self.withheld = 0

    def check(self, accel_g: Vector, t: float = 0.0) -> GravityVerdict:
        """The tilt of ``accel_g``, read at ``t`` (s), or why there is none; see
        :class:`GravityVerdict`."""
        size = magnitude_g(accel_g)
        if abs(size - 1.0) <= self.tolerance_g:
            # Finite and near 1 g, so never the zero vector eq. 5.6-5.7 refuse.
            tilt = tilt_from_acceleration(*accel_g)
            withheld, said = self.withheld, self.implausible
            self.implausible, self.withheld, self.since = False, 0, None
            if said:
                return GravityVerdict(tilt, size, "plausible", withheld)
            return GravityVerdict(tilt, size)
        self.withheld += 1
        if self.since is None:
            self.since = t
        if self.implausible or t - self.since < self.hold_s:
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
