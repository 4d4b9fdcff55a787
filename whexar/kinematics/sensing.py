"""Conversions of raw sensor readings: IR rangefinder counts and IMU accelerations.

Both are pure and vectorised: numbers in give floats out, arrays in give arrays out.
"""

from __future__ import annotations

import math
from typing import Final, overload

import numpy as np

from whexar._typing import ArrayLike, FloatArray
from whexar.errors import UsageError

IR_K_CM: Final = 149630.2188732250
"""Coefficient of the IR rangefinder calibration, in cm (Žák 2023, 5.3.5, eq. 5.5)."""

IR_EXPONENT: Final = -1.4841404565
"""Exponent of the IR rangefinder calibration (Žák 2023, 5.3.5, eq. 5.5)."""

ADC_MAX: Final = 1023
"""Largest reading of the ATmega2560's 10-bit A/D converter (5.3.5)."""

_SCALARS: Final = (int, float)
"""Exact types taking the scalar fast paths (``bool`` and numpy scalars do not)."""


@overload
def ir_distance(adc_counts: float, k_cm: float = ..., exponent: float = ...) -> float: ...
@overload
def ir_distance(adc_counts: ArrayLike, k_cm: float = ..., exponent: float = ...) -> FloatArray: ...
def ir_distance(
    adc_counts: ArrayLike, k_cm: float = IR_K_CM, exponent: float = IR_EXPONENT
) -> float | FloatArray:
    """Distance (m) to an obstacle from an IR rangefinder's A/D reading (Žák 2023, eq. 5.5).

    Eq. 5.5 is the power-law trend line y = k·x^e through the calibration points of Table 5.4,
    with y in centimetres and x the 10-bit A/D value; the result is converted to metres.
    Readings may be averages (the thesis averages them, 5.3.5, 5.4) and so fractional, but must
    lie in (0, 1023]. The calibration covers 10–140 cm (Table 5.4, counts ≈ 112–723); outside
    that it is an extrapolation.
    """
    if type(adc_counts) in _SCALARS and type(k_cm) in _SCALARS and type(exponent) in _SCALARS:
        # One reading per frame in the sensor reader: plain floats, ten times
        # faster than the array path below and equal to it bit for bit.
        c, k, e = float(adc_counts), float(k_cm), float(exponent)  # type: ignore[arg-type]
        if 0.0 < c <= ADC_MAX and k > 0.0 and math.isfinite(k) and math.isfinite(e):
            return float(0.01 * k * c**e)  # eq. 5.5, cm → m
    x = np.asarray(adc_counts, dtype=np.float64)
    if not np.all(np.isfinite(x)) or np.any(x <= 0.0) or np.any(x > ADC_MAX):
        raise UsageError(
            f"adc_counts = {adc_counts!r}: must be finite A/D readings in (0, {ADC_MAX}] "
            "(10-bit converter; 0 would mean infinite distance)"
        )
    k, e = float(k_cm), float(exponent)
    if not (np.isfinite(k) and k > 0.0 and np.isfinite(e)):
        raise UsageError(f"k_cm = {k_cm!r}, exponent = {exponent!r}: need finite k_cm > 0")
    metres: FloatArray = 0.01 * k * x**e  # eq. 5.5, cm → m
    if np.ndim(adc_counts) == 0 and not isinstance(adc_counts, np.ndarray):
        return float(metres)
    return metres


@overload
def tilt_from_acceleration(ax: float, ay: float, az: float) -> tuple[float, float]: ...
@overload
def tilt_from_acceleration(
    ax: ArrayLike, ay: ArrayLike, az: ArrayLike
) -> tuple[FloatArray, FloatArray]: ...
def tilt_from_acceleration(
    ax: ArrayLike, ay: ArrayLike, az: ArrayLike
) -> tuple[float, float] | tuple[FloatArray, FloatArray]:
    """Tilt angles (rad) from a static accelerometer reading (Žák 2023, 5.4, eq. 5.6–5.7).

    Returns (roll φ, pitch θ) with φ = arctan(acc_x/acc_z) (eq. 5.6) and θ = arctan(acc_y/acc_z)
    (eq. 5.7), evaluated with atan2 so that they cover (−π, π] and stay right when the sensor
    is tipped past 90° (acc_z ≤ 0): Table 6.4 itself lists −90.45° for its −90° row, which no
    plain arctan can return. Accelerations in any unit (m/s² or g), broadcast together.

    Naming: Table 6.4 (6.1.3) calls the angle computed from Y and Z the "roll about x axis",
    while eq. 5.6–5.7 call it pitch; we follow the equations. Mapping the IMU's axes onto the
    body frame is a matter of configuration, not of this function. A zero acceleration vector
    (free fall, or no reading) has no tilt and raises UsageError.
    """
    if type(ax) in _SCALARS and type(ay) in _SCALARS and type(az) in _SCALARS:
        # The sensor readers' case: plain floats, without numpy's per-call cost.
        fx, fy, fz = float(ax), float(ay), float(az)  # type: ignore[arg-type]
        finite = math.isfinite(fx) and math.isfinite(fy) and math.isfinite(fz)
        if finite and (fx, fy, fz) != (0.0, 0.0, 0.0):
            return math.atan2(fx, fz), math.atan2(fy, fz)  # eq. 5.6, 5.7
    x, y, z = (np.asarray(a, dtype=np.float64) for a in (ax, ay, az))
    for name, value, raw in (("ax", x, ax), ("ay", y, ay), ("az", z, az)):
        if not np.all(np.isfinite(value)):
            raise UsageError(f"{name} = {raw!r}: accelerations must be finite")
    try:
        x, y, z = np.broadcast_arrays(x, y, z)
    except ValueError as error:
        raise UsageError(
            f"ax, ay, az have shapes {x.shape}, {y.shape}, {z.shape}: must broadcast together"
        ) from error
    if np.any((x == 0.0) & (y == 0.0) & (z == 0.0)):
        raise UsageError(
            "acceleration (0, 0, 0): no gravity vector, so no tilt can be computed; "
            "at least one component must be non-zero"
        )
    roll: FloatArray = np.arctan2(x, z)  # eq. 5.6
    pitch: FloatArray = np.arctan2(y, z)  # eq. 5.7
    if all(np.ndim(a) == 0 and not isinstance(a, np.ndarray) for a in (ax, ay, az)):
        return float(roll), float(pitch)
    return roll, pitch


__all__ = ["ADC_MAX", "IR_EXPONENT", "IR_K_CM", "ir_distance", "tilt_from_acceleration"]
