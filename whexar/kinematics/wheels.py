"""Wheeled locomotion: steering angles and wheel rates for the six-wheel chassis.

Each leg ends in a steerable wheel: the *direction* joint turns the wheel about the (vertical)
tarsus and the *wheel* joint drives it (Žák 2023, 5.1 and Table 5.2). The thesis drives in four
ways (5.4, Fig. 5.15): straight, sideways, rotation on the spot and turning about a point S
(eq. 5.8–5.16, Fig. 5.16). All four are rigid planar motions of the body, so they are computed
here from one body twist (vx, vy, ω) about the body centre C: the contact point c_i of wheel i
moves with v_i = (vx, vy) + ω ẑ × c_i, the wheel is steered along v_i and rolls at |v_i|. Every
wheel then travels on a circle about the instantaneous centre of rotation and its speed is ω
times its distance from it (eq. 5.17–5.18).

Conventions (body frame, REP-103: x forward, y left, z up; yaw counter-clockwise from above):

* ``heading`` ψ_i is the wheel's rolling direction in the body frame, 0 = straight ahead.
  Minimal steering keeps it in (−π/2, π/2]; a wheel that would point backwards is turned by π
  and driven with negative speed instead.
* ``speed`` is signed: positive rolls the wheel forward along its heading (on both sides).
* ``direction`` is the direction-joint angle: legs are mirror images (5.1), so
  direction_i = s_i·ψ_i − coxa_i with s_i = +1 for right legs and −1 for left legs.
* Turning: S = (0, R) lies on the body's lateral axis; R > 0 puts S on the left (a left,
  counter-clockwise turn when driving forward), R < 0 on the right.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final

import numpy as np

from whexar._typing import ArrayLike, FloatArray
from whexar.errors import UsageError
from whexar.kinematics.geometry import SIDE_SIGN
from whexar.robot import LEG_NAMES, N_LEGS
from whexar.runtime.checks import positive, real

# Below this ground speed (m/s) a wheel is taken to sit at the centre of rotation: its heading
# is then undefined and we keep it neutral instead of amplifying rounding noise through atan2.
_STILL_SPEED: Final = 1e-12


@dataclass(frozen=True, eq=False)
class WheelCommand:
    """Steering and drive set-points for the six wheels, in leg order ``LEG_NAMES``.

    All arrays have shape (6,) and are read-only.
    """

    direction: FloatArray
    """Direction-joint angles (rad): s_i·heading_i − coxa_i."""
    heading: FloatArray
    """Wheel rolling directions in the body frame (rad), in (−π/2, π/2]."""
    speed: FloatArray
    """Signed ground speeds of the wheel contacts (m/s); positive rolls forward along heading."""
    wheel_rate: FloatArray
    """Wheel-joint angular rates (rad/s): speed / wheel radius (eq. 5.18)."""
    twist: tuple[float, float, float]
    """The body twist (vx, vy, ω) about the body centre C (m/s, m/s, rad/s)."""
    centre_of_rotation: FloatArray | None
    """Instantaneous centre of rotation (x, y) in the body frame (m); None for translation.

    It is (−vy/ω, vx/ω) for the twist (vx, vy, ω); with ω = 0 it lies at infinity.
    """


def _contacts(contacts: ArrayLike) -> FloatArray:
    points = np.asarray(contacts, dtype=np.float64)
    if points.shape not in ((N_LEGS, 2), (N_LEGS, 3)):
        raise UsageError(
            f"contacts has shape {points.shape}: expected (6, 2) or (6, 3) wheel contact points "
            f"in the body frame, one row per leg {', '.join(LEG_NAMES)}"
        )
    if not np.isfinite(points).all():
        bad = np.argwhere(~np.isfinite(points))[0]
        raise UsageError(
            f"contacts[{bad[0]}, {bad[1]}] = {points[tuple(bad)]!r}: coordinates must be finite"
        )
    return points[:, :2]


def _coxa(coxa: ArrayLike | None) -> FloatArray:
    if coxa is None:
        return np.zeros(N_LEGS)
    angles = np.asarray(coxa, dtype=np.float64)
    if angles.shape != (N_LEGS,):
        raise UsageError(f"coxa has shape {angles.shape}: expected (6,) angles in rad, one per leg")
    if not np.all(np.isfinite(angles)):
        raise UsageError(f"coxa = {angles.tolist()!r}: angles must be finite")
    return angles


def _real(name: str, value: object) -> float:
    """:func:`~whexar.runtime.checks.real`, with a fast path for the usual finite float
    (the coordinator asks every cycle; the general check costs a microsecond)."""
    if type(value) is float and math.isfinite(value):
        return value
    return real(name, value)


def _readonly(array: FloatArray) -> FloatArray:
    array.setflags(write=False)
    return array


def wheel_twist(
    contacts: ArrayLike,
    vx: float,
    vy: float,
    yaw_rate: float,
    *,
    coxa: ArrayLike | None = None,
    wheel_radius: float,
) -> WheelCommand:
    """Wheel set-points that move the body with twist (vx, vy, ω) about its centre C.

    ``contacts`` are the six wheel contact points in the body frame, shape (6, 2) or (6, 3) in
    metres (z is ignored); ``coxa`` the six coxa angles in rad (default 0), which rotate the
    lower leg and so offset the direction joints; ``wheel_radius`` (m) turns speeds into wheel
    rates (Table 5.2: 33 mm, :attr:`~whexar.kinematics.geometry.LegGeometry.wheel_radius`).
    Each contact moves with v_i = v + ω ẑ × c_i; its wheel is steered along v_i and rolls at
    |v_i| = |ω|·(distance to the centre of rotation) (Žák 2023, 5.4, eq. 5.17–5.18). The
    other motions of this module reduce to this.
    A wheel at the centre of rotation (speed below 1e-12 m/s) has no heading and is kept at 0.
    """
    points = _contacts(contacts)
    coxa_angles = None if coxa is None else _coxa(coxa)
    radius = positive("wheel_radius", wheel_radius, "m")
    vx_, vy_, omega = _real("vx", vx), _real("vy", vy), _real("yaw_rate", yaw_rate)

    # ω ẑ × (x, y) = (−ω y, ω x)
    vel_x = vx_ - omega * points[:, 1]
    vel_y = vy_ + omega * points[:, 0]
    speed = np.hypot(vel_x, vel_y)
    heading = np.arctan2(vel_y, vel_x)
    # The selections below are skipped where they would select nothing (the usual case):
    # the same values, a few numpy calls fewer.
    still = speed < _STILL_SPEED
    if still.any():
        heading = np.where(still, 0.0, heading)
        speed = np.where(still, 0.0, speed)

    # Minimal steering: never turn more than 90° from straight ahead; reverse the drive instead.
    reverse = (heading > np.pi / 2) | (heading <= -np.pi / 2)
    if reverse.any():
        heading = np.where(reverse, heading - np.sign(heading) * np.pi, heading)
        speed = np.where(reverse, -speed, speed)

    centre = None if omega == 0.0 else np.array([-vy_ / omega, vx_ / omega])
    if centre is not None and not np.isfinite(centre).all():
        centre = None  # ω so small that the centre lies beyond float range: a translation
    direction = SIDE_SIGN * heading
    if coxa_angles is not None:  # without them, subtracting zeros would change no bit
        direction = direction - coxa_angles
    return WheelCommand(
        direction=_readonly(direction),
        heading=_readonly(heading),
        speed=_readonly(speed),
        wheel_rate=_readonly(speed / radius),
        twist=(vx_, vy_, omega),
        centre_of_rotation=None if centre is None else _readonly(centre),
    )


def wheel_straight(
    contacts: ArrayLike,
    speed: float,
    *,
    coxa: ArrayLike | None = None,
    wheel_radius: float,
) -> WheelCommand:
    """Drive straight ahead at ``speed`` m/s (negative reverses): wheels not turned (Fig. 5.15a)."""
    v = real("speed", speed)
    return wheel_twist(contacts, v, 0.0, 0.0, coxa=coxa, wheel_radius=wheel_radius)


def wheel_sideways(
    contacts: ArrayLike,
    speed: float,
    angle: float,
    *,
    coxa: ArrayLike | None = None,
    wheel_radius: float,
) -> WheelCommand:
    """Drive at ``speed`` m/s towards body-frame direction ``angle`` (rad, counter-clockwise).

    The body keeps its orientation and all wheels point the same way (Žák 2023, Fig. 5.15b;
    6.5.2 "Driving Sideways" used ±45°). Angles beyond ±90° are reached by reversing the wheels.
    """
    v = real("speed", speed)
    phi = real("angle", angle)
    return wheel_twist(
        contacts, v * np.cos(phi), v * np.sin(phi), 0.0, coxa=coxa, wheel_radius=wheel_radius
    )


def wheel_spin(
    contacts: ArrayLike,
    yaw_rate: float,
    *,
    coxa: ArrayLike | None = None,
    wheel_radius: float,
) -> WheelCommand:
    """Rotate on the spot about the body centre C at ``yaw_rate`` rad/s (positive = left, CCW).

    Each wheel is steered along the tangent of its circle about C, i.e. by α = arctan(P'_z/P'_x)
    from straight ahead, where P' is its contact relative to C (Žák 2023, eq. 5.8–5.10,
    Fig. 5.16a); middle wheels level with C stay at 0.
    """
    return wheel_twist(contacts, 0.0, 0.0, yaw_rate, coxa=coxa, wheel_radius=wheel_radius)


def wheel_turn(
    contacts: ArrayLike,
    radius: float,
    *,
    speed: float | None = None,
    yaw_rate: float | None = None,
    coxa: ArrayLike | None = None,
    wheel_radius: float,
) -> WheelCommand:
    """Turn about S = (0, ``radius``) on the body's lateral axis (Žák 2023, eq. 5.11–5.16).

    ``radius`` R is the signed distance C→S in metres: R > 0 puts S on the left (a left turn
    when driving forward), R < 0 on the right. Give exactly one of ``speed`` (forward speed of
    the body centre, m/s; then ω = v/R) or ``yaw_rate`` ω (rad/s; then v = ωR). The wheels ride
    on concentric circles about S with speeds |ω|·|c_i − S| (eq. 5.17–5.18). A front wheel at
    P' = (lateral distance from S, longitudinal offset from C) is steered by arctan(P'_z/P'_x)
    (eq. 5.15–5.16), the rear wheels by the negative angle and middle wheels level with S by 0.
    Note that eq. 5.11 (P'_x = R − W_b/2 − P_x) describes the wheels on the same side as S,
    although the text of 5.4 names that angle α₁ for the far side; we follow the geometry.
    """
    r = real("radius", radius)
    if r == 0.0:
        raise UsageError(
            "radius = 0: the centre of rotation would be the body centre, which is rotation on "
            "the spot; use wheel_spin, or give a non-zero signed distance to S (m)"
        )
    if (speed is None) == (yaw_rate is None):
        raise UsageError(
            f"speed = {speed!r}, yaw_rate = {yaw_rate!r}: give exactly one of the body-centre "
            "forward speed (m/s) or the yaw rate (rad/s)"
        )
    if speed is not None:
        omega = real("speed", speed) / r
    else:
        assert yaw_rate is not None  # guaranteed by the check above; narrows the type
        omega = real("yaw_rate", yaw_rate)
    # The body centre C rotates about S = (0, R): v_C = ω ẑ × (C − S) = (ωR, 0).
    return wheel_twist(contacts, omega * r, 0.0, omega, coxa=coxa, wheel_radius=wheel_radius)


def direction_for_heading(heading: ArrayLike, coxa: ArrayLike | None = None) -> FloatArray:
    """Direction-joint angles (rad) that point the six wheels along body-frame ``heading``.

    direction_i = s_i·ψ_i − coxa_i with s_i = +1 for right and −1 for left legs, because the
    left legs mirror the right ones (Žák 2023, 5.1; tarsus vertical, eq. 4.19).
    """
    psi = np.asarray(heading, dtype=np.float64)
    if psi.shape != (N_LEGS,) or not np.all(np.isfinite(psi)):
        raise UsageError(f"heading = {psi.tolist()!r}: expected six finite angles in rad")
    result: FloatArray = SIDE_SIGN * psi - _coxa(coxa)
    return result


def heading_from_direction(direction: ArrayLike, coxa: ArrayLike | None = None) -> FloatArray:
    """Body-frame wheel headings (rad) of direction-joint angles: ψ_i = s_i·(coxa_i + dir_i).

    Inverse of :func:`direction_for_heading` (Žák 2023, 5.1; tarsus vertical, eq. 4.19).
    """
    angles = np.asarray(direction, dtype=np.float64)
    if angles.shape != (N_LEGS,) or not np.all(np.isfinite(angles)):
        raise UsageError(f"direction = {angles.tolist()!r}: expected six finite angles in rad")
    result: FloatArray = SIDE_SIGN * (_coxa(coxa) + angles)
    return result


__all__ = [
    "SIDE_SIGN",
    "WheelCommand",
    "direction_for_heading",
    "heading_from_direction",
    "wheel_sideways",
    "wheel_spin",
    "wheel_straight",
    "wheel_turn",
    "wheel_twist",
]
