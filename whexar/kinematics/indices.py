"""Performance indices of walking robots and a current-based leg load estimate.

Duty factor, Froude number and cost of transport (Žák 2023, 3.2.3, eq. 3.7–3.12; 6.8,
eq. 6.1–6.5), and the thesis's torque indicator from servo currents (5.4, eq. 5.19). Every
function accepts numbers or numpy arrays (broadcast together) and returns a float for
scalar input, an array otherwise.
"""

from __future__ import annotations

from typing import Final, overload

import numpy as np

from whexar._typing import ArrayLike, BoolArray, FloatArray
from whexar.errors import UsageError

STANDARD_GRAVITY: Final = 9.81
"""Gravitational acceleration (m/s²) used throughout the thesis (6.8.1)."""

WHEXAR_MASS: Final = 8.8
"""Mass of WHexaR (kg) used for its cost of transport (Žák 2023, 6.8.1)."""

SUPPLY_VOLTAGE: Final = 12.0
"""Supply voltage (V) of the experiments in Žák 2023, 6.8.1."""

SINGULAR_SIN: Final = 1e-6
"""Default |sin α| below which eq. 5.19 is treated as singular."""


def _array(name: str, value: ArrayLike) -> FloatArray:
    array = np.asarray(value, dtype=np.float64)
    if not np.all(np.isfinite(array)):
        raise UsageError(f"{name} = {value!r}: must be finite")
    return array


def _positive(name: str, value: ArrayLike, unit: str) -> FloatArray:
    array = _array(name, value)
    if np.any(array <= 0.0):
        raise UsageError(f"{name} = {value!r}: must be > 0 {unit}")
    return array


def _nonnegative(name: str, value: ArrayLike, unit: str) -> FloatArray:
    array = _array(name, value)
    if np.any(array < 0.0):
        raise UsageError(f"{name} = {value!r}: must be ≥ 0 {unit}")
    return array


def _scalar_in(*values: ArrayLike) -> bool:
    return all(np.ndim(v) == 0 and not isinstance(v, np.ndarray) for v in values)


def _out(result: FloatArray, *inputs: ArrayLike) -> float | FloatArray:
    # Plain numbers in, plain float out; arrays (even 0-d) in, array out.
    return float(result) if _scalar_in(*inputs) else result


@overload
def duty_factor(support_time: float, cycle_time: float) -> float: ...
@overload
def duty_factor(support_time: ArrayLike, cycle_time: ArrayLike) -> FloatArray: ...
def duty_factor(support_time: ArrayLike, cycle_time: ArrayLike) -> float | FloatArray:
    """Duty factor β = support period / cycle time (Žák 2023, eq. 3.7), in [0, 1].

    β ≥ 0.5 is walking, β < 0.5 running (3.2.3). Times in seconds; the support time may not
    exceed the cycle time.
    """
    support = _nonnegative("support_time", support_time, "s")
    cycle = _positive("cycle_time", cycle_time, "s")
    if np.any(support > cycle):
        raise UsageError(
            f"support_time = {support_time!r} exceeds cycle_time = {cycle_time!r}: a leg cannot "
            "support for longer than one cycle"
        )
    return _out(support / cycle, support_time, cycle_time)


@overload
def froude_number(speed: float, hip_height: float, g: float = ...) -> float: ...
@overload
def froude_number(speed: ArrayLike, hip_height: ArrayLike, g: float = ...) -> FloatArray: ...
def froude_number(
    speed: ArrayLike, hip_height: ArrayLike, g: float = STANDARD_GRAVITY
) -> float | FloatArray:
    """Froude number Fr = v²/(g·h) (Žák 2023, eq. 3.8).

    ``speed`` v in m/s, ``hip_height`` h (hip joint above ground) in m, ``g`` in m/s².
    """
    v = _array("speed", speed)
    h = _positive("hip_height", hip_height, "m")
    gravity = _positive("g", g, "m/s²")
    return _out(v**2 / (gravity * h), speed, hip_height)


@overload
def froude_number_from_frequency(hip_height: float, frequency: float, g: float = ...) -> float: ...
@overload
def froude_number_from_frequency(
    hip_height: ArrayLike, frequency: ArrayLike, g: float = ...
) -> FloatArray: ...
def froude_number_from_frequency(
    hip_height: ArrayLike, frequency: ArrayLike, g: float = STANDARD_GRAVITY
) -> float | FloatArray:
    """Froude number from the stride frequency: Fr = (h·f)²/(g·h) = h·f²/g (Žák 2023, eq. 3.9).

    ``hip_height`` h in m, ``frequency`` f in Hz, ``g`` in m/s².
    """
    h = _positive("hip_height", hip_height, "m")
    f = _nonnegative("frequency", frequency, "Hz")
    gravity = _positive("g", g, "m/s²")
    return _out(h * f**2 / gravity, hip_height, frequency)


@overload
def electric_power(voltage: float, current: float) -> float: ...
@overload
def electric_power(voltage: ArrayLike, current: ArrayLike) -> FloatArray: ...
def electric_power(voltage: ArrayLike, current: ArrayLike) -> float | FloatArray:
    """Electric power P = U·I in W (Žák 2023, eq. 3.12 and 6.5); U in V, I in A."""
    return _out(_array("voltage", voltage) * _array("current", current), voltage, current)


@overload
def cost_of_transport(power: float, mass: float, speed: float, g: float = ...) -> float: ...
@overload
def cost_of_transport(
    power: ArrayLike, mass: ArrayLike, speed: ArrayLike, g: float = ...
) -> FloatArray: ...
def cost_of_transport(
    power: ArrayLike, mass: ArrayLike, speed: ArrayLike, g: float = STANDARD_GRAVITY
) -> float | FloatArray:
    """Energetic cost of transport ε = P/(m·g·v), dimensionless (Žák 2023, eq. 3.11 and 6.4).

    ``power`` P ≥ 0 W consumed while moving, ``mass`` m > 0 kg, ``speed`` v > 0 m/s (standing
    still has no cost per distance), ``g`` in m/s².
    """
    p = _nonnegative("power", power, "W")
    m = _positive("mass", mass, "kg")
    v = _positive("speed", speed, "m/s (the cost per distance needs motion)")
    gravity = _positive("g", g, "m/s²")
    return _out(p / (m * gravity * v), power, mass, speed)


@overload
def cost_of_transport_from_current(
    current: float, speed: float, mass: float = ..., voltage: float = ..., g: float = ...
) -> float: ...
@overload
def cost_of_transport_from_current(
    current: ArrayLike, speed: ArrayLike, mass: float = ..., voltage: float = ..., g: float = ...
) -> FloatArray: ...
def cost_of_transport_from_current(
    current: ArrayLike,
    speed: ArrayLike,
    mass: float = WHEXAR_MASS,
    voltage: float = SUPPLY_VOLTAGE,
    g: float = STANDARD_GRAVITY,
) -> float | FloatArray:
    """Cost of transport ε = U·I/(m·g·v) from the supply current (Žák 2023, eq. 6.4–6.5).

    Defaults are those of the thesis experiments: m = 8.8 kg, U = 12 V, g = 9.81 m/s² (6.8.1),
    with which Table 6.7 was computed. ``current`` I ≥ 0 A, ``speed`` v > 0 m/s.
    """
    i = _nonnegative("current", current, "A")
    u = _positive("voltage", voltage, "V")
    power = electric_power(u, i)
    return _out(cost_of_transport(power, mass, _array("speed", speed), g), current, speed)


@overload
def leg_torque_estimate(
    current: float, segment_length: float, next_joint_angle: float, *, min_abs_sin: float = ...
) -> float: ...
@overload
def leg_torque_estimate(
    current: ArrayLike,
    segment_length: ArrayLike,
    next_joint_angle: ArrayLike,
    *,
    min_abs_sin: float = ...,
) -> FloatArray: ...
def leg_torque_estimate(
    current: ArrayLike,
    segment_length: ArrayLike,
    next_joint_angle: ArrayLike,
    *,
    min_abs_sin: float = SINGULAR_SIN,
) -> float | FloatArray:
    """The thesis's load indicator F_i = I_i / (L_i·sin α_{i+1}) (Žák 2023, 5.4, eq. 5.19).

    ``current`` I_i is the present current of servo i (A, signed as the servo reports it),
    ``segment_length`` L_i the length of segment i to the next joint (m, Table 5.2) and
    ``next_joint_angle`` α_{i+1} the present angle of the next servo (rad). The thesis calls F_i
    a torque and uses it to detect leg contact with the ground or an obstacle in place of the
    foot force sensors; it is a relative indicator, not a calibrated torque — its unit is A/m,
    not N·m. Where |sin α_{i+1}| < ``min_abs_sin`` the formula is singular and UsageError is
    raised instead of returning ±inf.
    """
    i = _array("current", current)
    length = _positive("segment_length", segment_length, "m")
    alpha = _array("next_joint_angle", next_joint_angle)
    sin_alpha = np.sin(alpha)
    singular = np.abs(sin_alpha) < min_abs_sin
    if np.any(singular):
        bad = float(np.broadcast_to(alpha, singular.shape)[singular].flat[0])
        raise UsageError(
            f"next_joint_angle = {bad!r} rad: sin α = {np.sin(bad):.3g} makes eq. 5.19 singular; "
            f"allowed are angles with |sin α| ≥ {min_abs_sin:g} (away from 0 and ±π)"
        )
    return _out(i / (length * sin_alpha), current, segment_length, next_joint_angle)


def servo_currents(samples: ArrayLike, valid: ArrayLike | None = None) -> FloatArray:
    """Current of each servo, the mean absolute value of its samples (Žák 2023, eq. 6.1).

    ``samples`` (..., n) in A, the last axis being the n readings of one servo; ``valid`` an
    optional boolean mask of the same shape marking the accepted readings (the thesis drops
    timed-out or corrupted responses, 6.8). Every servo needs at least one accepted reading.
    """
    x = _array("samples", samples)
    if x.ndim == 0 or x.shape[-1] == 0:
        raise UsageError(f"samples has shape {x.shape}: expected (..., n) readings with n ≥ 1")
    mask: BoolArray = np.ones(x.shape, dtype=np.bool_)
    if valid is not None:
        mask = np.asarray(valid, dtype=np.bool_)
        if mask.shape != x.shape:
            raise UsageError(f"valid has shape {mask.shape}: expected {x.shape} like samples")
    count = mask.sum(axis=-1)
    if np.any(count == 0):
        where = np.argwhere(count == 0)[0].tolist()
        raise UsageError(f"servo at index {where} has no accepted reading: need at least one")
    result: FloatArray = np.where(mask, np.abs(x), 0.0).sum(axis=-1) / count
    return result


def stance_current(servo_samples: ArrayLike, valid: ArrayLike | None = None) -> float:
    """Total current of a stance or motion (A) from per-servo readings (Žák 2023, eq. 6.1–6.3).

    ``servo_samples`` has shape (legs, servos, n): I_s is the mean absolute reading of each
    servo (eq. 6.1, see :func:`servo_currents`), I_l = Σ_s I_s per leg (eq. 6.2) and the result
    I = Σ_l I_l (eq. 6.3).
    """
    x = _array("servo_samples", servo_samples)
    if x.ndim != 3:
        raise UsageError(f"servo_samples has shape {x.shape}: expected (legs, servos, samples)")
    per_servo = servo_currents(x, valid)
    return float(per_servo.sum(axis=1).sum(axis=0))


__all__ = [
    "SINGULAR_SIN",
    "STANDARD_GRAVITY",
    "SUPPLY_VOLTAGE",
    "WHEXAR_MASS",
    "cost_of_transport",
    "cost_of_transport_from_current",
    "duty_factor",
    "electric_power",
    "froude_number",
    "froude_number_from_frequency",
    "leg_torque_estimate",
    "servo_currents",
    "stance_current",
]
