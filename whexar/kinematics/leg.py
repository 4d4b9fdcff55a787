"""Forward and inverse kinematics of one WHexaR leg, vectorised over many targets.

Joint angles are in the convention of Table 6.5 (Žák 2023), ordered coxa,
trochanter, femur, tibia, tarsus, radians:

* coxa positive swings the leg forward (towards +z of the leg frame);
* femur positive lifts the leg; tibia negative folds it down;
* tarsus = −π/2 − femur − tibia keeps the last segment parallel to gravity
  (eq. 4.19), which is how every row of Table 6.5 was computed;
* trochanter = body pitch (eq. 4.18): it turns the whole leg about its own
  long axis so the leg plane stays vertical when the body pitches, carrying the
  foot along with it (:func:`trochanter_arc`).

Points are in the leg frame of :mod:`whexar.kinematics.geometry` (x outward,
y down, z forward; metres). The *target* point of the IK is the tarsus joint,
as in the thesis (eq. 4.7–4.17), or the wheel's ground contact, which lies
``contact_offset`` further along the vertical last segment.

Theory of operation (IK). With the trochanter at θ₁ the tarsus joint lies at
(ρ, s·cos θ₁, ζ) before the coxa turns it about the vertical, where ρ = d₁ + r
and ζ = s·sin θ₁, and (r, s) is the tarsus joint in the leg plane (outward,
down) measured from the femur joint. So s = y / cos θ₁, ρ follows from
x² + z² = ρ² + ζ², the coxa from the two angles, and the femur and tibia from
the planar triangle of eq. 4.8–4.17. With θ₁ = 0 this is exactly the thesis's
solution; γ uses atan2 so targets inside the femur joint still solve.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from whexar._typing import ArrayLike, BoolArray, FloatArray
from whexar.errors import JointLimitError, UnreachableError, UsageError
from whexar.kinematics.geometry import DH_TO_LEG, LegGeometry
from whexar.robot import POSITIONING_JOINTS

Target = Literal["tarsus", "contact"]

_HALF_PI = math.pi / 2
_TWO_PI = 2 * math.pi
_REACH_EPS = 1e-12
"""Slack (m) on the reach triangle so that a target exactly at full stretch solves."""

CHAIN_POINTS = ("coxa", "femur", "tibia", "tarsus", "direction", "wheel_axle", "contact")
"""Points returned by :func:`fk_chain`, from the body outwards."""


@dataclass(frozen=True, eq=False)
class IKSolution:
    """Joint angles for a batch of targets, and what had to give.

    ``angles[..., k]`` is joint k (coxa, trochanter, femur, tibia, tarsus) in
    radians; every angle lies within the joint limits of the geometry.
    """

    angles: FloatArray
    reachable: BoolArray
    """The target lies in the workspace (ignoring joint limits)."""
    clamped: BoolArray
    """The angles do not reach the target exactly: out of reach, or a limit was hit."""

    @property
    def degrees(self) -> FloatArray:
        """The angles in degrees."""
        return np.degrees(self.angles)

    @property
    def any_clamped(self) -> bool:
        """True when at least one target was not met exactly."""
        return bool(self.clamped.any())


def _points(points: ArrayLike, what: str = "target") -> FloatArray:
    array = np.asarray(points, dtype=np.float64)
    if array.ndim == 0 or array.shape[-1] != 3:
        raise UsageError(
            f"{what} points have shape {array.shape}; allowed: (..., 3) as (x, y, z) in metres"
        )
    if not np.isfinite(array).all():
        bad = np.argwhere(~np.isfinite(array))[0]
        raise UsageError(
            f"{what} point {tuple(int(i) for i in bad[:-1])} has "
            f"{'xyz'[bad[-1]]} = {array[tuple(bad)]}; allowed: finite numbers"
        )
    return array


def _mm(point: FloatArray) -> str:
    return "(" + ", ".join(f"{1000 * c:.1f}" for c in point) + ") mm"


def ik(
    points: ArrayLike,
    geometry: LegGeometry,
    *,
    pitch: ArrayLike = 0.0,
    target: Target = "tarsus",
    clamp: bool = False,
) -> IKSolution:
    """Inverse kinematics (eq. 4.7–4.19) for targets of shape (..., 3) in the leg frame.

    ``pitch`` (rad, broadcast against the targets) is the body pitch the
    trochanter follows (eq. 4.18); it must lie strictly between ±90°.

    By default a target that cannot be met raises :class:`UnreachableError`
    (outside the workspace) or :class:`JointLimitError` (a joint would leave its
    limits), naming the target. With ``clamp=True`` every target gets angles
    within the limits — the nearest the leg can do along the same direction —
    and :attr:`IKSolution.clamped` says which ones were not met exactly.
    """
    g = geometry
    p = _points(points)
    if target not in ("tarsus", "contact"):
        raise UsageError(f"IK target {target!r}; allowed: 'tarsus' or 'contact'")
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    offset = g.contact_offset if target == "contact" else 0.0

    if isinstance(pitch, (int, float)) and pitch == 0:
        # Level trochanter, the thesis's case and the hot path: ζ = 0.
        theta1: FloatArray | float = 0.0
        s = y - offset
        rho = np.hypot(x, z)
        coxa = np.arctan2(z, x)
        in_plane: BoolArray | bool = True
    else:
        theta1 = _pitch(pitch)
        s_target = y / np.cos(theta1)  # in-plane depth of the target below the coxa axis
        zeta = s_target * np.sin(theta1)
        s = s_target - offset
        rho_sq = x * x + z * z - zeta * zeta
        in_plane = rho_sq >= 0.0
        rho = np.sqrt(np.maximum(rho_sq, 0.0))
        coxa = np.arctan2(z, x) - np.arctan2(zeta, rho)

    r = rho - g.trochanter_offset
    lt = np.hypot(r, s)
    a2, a3 = g.femur, g.tibia
    lo_reach, hi_reach = abs(a2 - a3), a2 + a3
    reachable = (lt <= hi_reach + _REACH_EPS) & (lt >= lo_reach - _REACH_EPS) & in_plane
    lt = np.maximum(lt, _REACH_EPS)
    lt_sq = lt * lt
    gamma = np.arctan2(r, s)  # eq. 4.9, extended to r < 0
    cos_beta = (lt_sq + (a2 * a2 - a3 * a3)) / (2 * a2 * lt)  # eq. 4.11
    cos_alpha = ((a2 * a2 + a3 * a3) - lt_sq) / (2 * a2 * a3)  # eq. 4.14
    # Out of reach the cosines leave [−1, 1]: fully stretched or folded instead.
    beta = np.arccos(np.minimum(np.maximum(cos_beta, -1.0), 1.0))
    alpha = np.arccos(np.minimum(np.maximum(cos_alpha, -1.0), 1.0))

    angles = np.empty((*lt.shape, 5))
    angles[..., 0] = coxa
    angles[..., 1] = theta1
    angles[..., 2] = beta + gamma - _HALF_PI  # eq. 4.16 in Table 6.5's sign
    angles[..., 3] = alpha - math.pi  # eq. 4.17 in Table 6.5's sign
    angles[..., 4] = -_HALF_PI - angles[..., 2] - angles[..., 3]  # eq. 4.19
    # Revolute joints: report each angle in (−π, π], where Table 5.2's limits live.
    angles = (angles + math.pi) % _TWO_PI - math.pi
    lo, hi = g.lower_limits, g.upper_limits
    outside = (angles < lo) | (angles > hi)
    if not clamp:
        if not np.all(reachable) or outside.any():
            _raise_if_unmet(p, angles, np.asarray(reachable), outside, g)
        unmet = np.zeros(lt.shape, dtype=np.bool_)
        return IKSolution(angles, ~unmet, unmet)
    reach = np.broadcast_to(reachable, lt.shape)
    limited = np.minimum(np.maximum(angles, lo), hi)
    # Keep the last segment vertical as far as the clamped femur and tibia allow.
    tarsus = (math.pi / 2 - limited[..., 2] - limited[..., 3]) % _TWO_PI - math.pi
    limited[..., 4] = np.minimum(np.maximum(tarsus, lo[4]), hi[4])
    return IKSolution(limited, reach, ~reach | outside.any(axis=-1))


def ik_point(
    point: tuple[float, float, float] | list[float],
    geometry: LegGeometry,
    *,
    pitch: float = 0.0,
    target: Target = "tarsus",
) -> tuple[float, float, float, float, float]:
    """:func:`ik` of one target, in plain Python: the case a leg controller asks every cycle.

    The same equations and the same results as :func:`ik` (tested equal), without numpy's
    per-call cost. A target it cannot meet goes to :func:`ik`, which raises the error that
    names it.
    """
    g = geometry
    x, y, z = float(point[0]), float(point[1]), float(point[2])
    offset = g.contact_offset if target == "contact" else 0.0
    if target not in ("tarsus", "contact") or not (
        math.isfinite(x) and math.isfinite(y) and math.isfinite(z) and math.isfinite(pitch)
    ):
        return _ik_tuple(ik((x, y, z), g, pitch=pitch, target=target))
    if pitch == 0:
        theta1 = 0.0
        s = y - offset
        rho = math.hypot(x, z)
        coxa = math.atan2(z, x)
        in_plane = True
    else:
        if abs(pitch) >= _HALF_PI:
            return _ik_tuple(ik((x, y, z), g, pitch=pitch, target=target))
        theta1 = pitch
        s_target = y / math.cos(theta1)
        zeta = s_target * math.sin(theta1)
        s = s_target - offset
        rho_sq = x * x + z * z - zeta * zeta
        in_plane = rho_sq >= 0.0
        rho = math.sqrt(max(rho_sq, 0.0))
        coxa = math.atan2(z, x) - math.atan2(zeta, rho)
    r = rho - g.trochanter_offset
    lt = math.hypot(r, s)
    a2, a3 = g.femur, g.tibia
    reach = abs(a2 - a3) - _REACH_EPS <= lt <= a2 + a3 + _REACH_EPS and in_plane
    if not reach:
        return _ik_tuple(ik((x, y, z), g, pitch=pitch, target=target))
    lt = max(lt, _REACH_EPS)
    lt_sq = lt * lt
    gamma = math.atan2(r, s)
    cos_beta = (lt_sq + (a2 * a2 - a3 * a3)) / (2 * a2 * lt)
    cos_alpha = ((a2 * a2 + a3 * a3) - lt_sq) / (2 * a2 * a3)
    beta = math.acos(min(max(cos_beta, -1.0), 1.0))
    alpha = math.acos(min(max(cos_alpha, -1.0), 1.0))
    femur = beta + gamma - _HALF_PI
    tibia = alpha - math.pi
    raw = (coxa, theta1, femur, tibia, -_HALF_PI - femur - tibia)
    lo, hi = _float_limits(g)
    out = []
    for k, a in enumerate(raw):
        a = (a + math.pi) % _TWO_PI - math.pi
        if not lo[k] <= a <= hi[k]:
            return _ik_tuple(ik((x, y, z), g, pitch=pitch, target=target))
        out.append(a)
    return out[0], out[1], out[2], out[3], out[4]


def trochanter_arc(
    point: tuple[float, float, float], pitch: float, depth: float | None = None
) -> tuple[float, float, float]:
    """Where the trochanter at ``pitch`` carries the foot at ``point`` (leg frame, m).

    The thesis's IK (eq. 4.7–4.17) solves coxa, femur and tibia in the leg's plane and
    leaves the trochanter out, so turning the trochanter to the body pitch (eq. 4.18)
    turns the whole leg about its long axis and carries the foot on an arc: a foot
    ``depth`` below the axis (default: the point's own y) moves by depth·sin θ₁ forward
    (the leg frame's z) and up by depth·(1 − cos θ₁). With the body nose up on a slope
    (θ₁ < 0) that carries the feet downhill, under the centre of mass.

    Two choices, each measured (docs/slopes.md):

    * the arc is drawn about the leg's mount axis (its long axis at coxa 0), so every
      foot moves along the body's x, the support polygon shifted whole; the real axis
      turns with the coxa, which at the front and rear legs' ±25° would spread the
      front feet and narrow the rear ones;
    * the stride is not turned with it: the point moves by the arc of the ground it
      stands on, so a foot on the ground moves parallel to the ground (the "arc" of the
      slopes note), where the thesis's robot tilted its stride with the leg.

    For a foot in the middle legs' plane (coxa 0) on the ground this is exactly the
    rigid leg of the thesis (tested).
    """
    x, y, z = point
    if pitch == 0.0:
        return x, y, z
    d = y if depth is None else depth
    return x, y - d * (1.0 - math.cos(pitch)), z + d * math.sin(pitch)


@functools.lru_cache(maxsize=16)
def _float_limits(g: LegGeometry) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """The joint limits as Python floats, per geometry: :func:`ik_point` compares every
    angle with them, and reading a numpy array's element costs more than the comparison."""
    return tuple(g.lower_limits.tolist()), tuple(g.upper_limits.tolist())


def _ik_tuple(solution: IKSolution) -> tuple[float, float, float, float, float]:
    a = [float(v) for v in solution.angles]
    return a[0], a[1], a[2], a[3], a[4]


def _pitch(pitch: ArrayLike) -> FloatArray:
    theta1 = np.asarray(pitch, dtype=np.float64)
    if not np.isfinite(theta1).all() or (np.abs(theta1) >= _HALF_PI).any():
        raise UsageError(f"pitch {pitch!r} rad; allowed: finite, strictly between −π/2 and π/2")
    return theta1


def _raise_if_unmet(
    p: FloatArray,
    angles: FloatArray,
    reachable: BoolArray,
    outside: BoolArray,
    g: LegGeometry,
) -> None:
    if not reachable.all():
        index = tuple(int(i) for i in np.argwhere(~reachable)[0])
        count = int((~reachable).sum())
        more = f" ({count - 1} more targets unreachable)" if count > 1 else ""
        at = f" [{', '.join(map(str, index))}]" if index else ""
        raise UnreachableError(
            f"target{at} {_mm(p[index])} is out of reach: the femur joint to tarsus joint "
            f"distance must lie within {1000 * g.min_reach:.0f}–{1000 * g.max_reach:.0f} mm"
            f"{more}"
        )
    if outside.any():
        where = np.argwhere(outside)[0]
        index, joint = tuple(int(i) for i in where[:-1]), int(where[-1])
        value = math.degrees(angles[(*index, joint)])
        lo, hi = np.degrees(g.limits[joint])
        count = int(outside.any(axis=-1).sum())
        more = f" ({count - 1} more targets outside limits)" if count > 1 else ""
        at = f" [{', '.join(map(str, index))}]" if index else ""
        raise JointLimitError(
            f"target{at} {_mm(p[index])} needs {POSITIONING_JOINTS[joint]} = {value:.2f}°, "
            f"outside its limits [{lo:g}, {hi:g}]°{more}"
        )


def _angles(angles: ArrayLike) -> FloatArray:
    array = np.asarray(angles, dtype=np.float64)
    if array.ndim == 0 or array.shape[-1] != 5:
        raise UsageError(
            f"joint angles have shape {array.shape}; allowed: (..., 5) as "
            f"({', '.join(POSITIONING_JOINTS)}) in radians"
        )
    if not np.isfinite(array).all():
        bad = np.argwhere(~np.isfinite(array))[0]
        raise UsageError(
            f"joint angle {POSITIONING_JOINTS[bad[-1]]} = {array[tuple(bad)]}; "
            "allowed: finite numbers"
        )
    return array


def dh_transforms(angles: ArrayLike, geometry: LegGeometry) -> FloatArray:
    """The five DH link transforms A₀…A₄ (eq. 4.4–4.5), shape (..., 5, 4, 4)."""
    g = geometry
    q = _angles(angles)
    theta = g.theta_sign * q + g.theta_offset
    ct, st = np.cos(theta), np.sin(theta)
    ca, sa = np.cos(g.dh_alpha), np.sin(g.dh_alpha)
    out = np.zeros((*q.shape, 4, 4))
    out[..., 0, 0], out[..., 0, 1], out[..., 0, 2] = ct, -st * ca, st * sa
    out[..., 1, 0], out[..., 1, 1], out[..., 1, 2] = st, ct * ca, -ct * sa
    out[..., 2, 1], out[..., 2, 2] = sa, ca
    out[..., 0, 3], out[..., 1, 3], out[..., 2, 3] = g.dh_a * ct, g.dh_a * st, g.dh_d
    out[..., 3, 3] = 1.0
    return out


def fk_chain(angles: ArrayLike, geometry: LegGeometry) -> FloatArray:
    """Every point of the leg for joint angles (..., 5): shape (..., 7, 3), leg frame.

    The points are :data:`CHAIN_POINTS`: coxa, femur, tibia and tarsus joints
    (eq. 4.6), the end of the tarsus segment (the direction joint), the wheel
    axle and the wheel's ground contact, which continue along the last
    segment by the direction and wheel lengths of Table 5.2.
    """
    g = geometry
    links = dh_transforms(angles, g)
    frames = [links[..., 0, :, :]]
    for k in range(1, 5):
        frames.append(frames[-1] @ links[..., k, :, :])
    last = frames[-1]
    axis = last[..., :3, 0]  # x of the tarsus frame runs along the last segment
    end = last[..., :3, 3]
    dh_points = [np.zeros_like(end), *(f[..., :3, 3] for f in frames[1:])]
    dh_points.append(end + axis * g.direction_length)
    dh_points.append(end + axis * (g.direction_length + g.wheel_radius))
    stacked = np.stack(dh_points, axis=-2)
    return stacked @ DH_TO_LEG.T


def fk(angles: ArrayLike, geometry: LegGeometry, *, point: Target = "tarsus") -> FloatArray:
    """Forward kinematics (eq. 4.4–4.6): the tarsus joint or the wheel contact, (..., 3)."""
    if point not in ("tarsus", "contact"):
        raise UsageError(f"FK point {point!r}; allowed: 'tarsus' or 'contact'")
    chain = fk_chain(angles, geometry)
    return chain[..., CHAIN_POINTS.index(point), :]


def fk_point(
    angles: tuple[float, ...] | list[float], geometry: LegGeometry
) -> tuple[float, float, float]:
    """The wheel contact in the leg frame from five joint angles: :func:`fk` of one pose
    (``point="contact"``) in plain Python, the case a leg controller asks every cycle.

    The chain written out: femur, tibia and tarsus in the leg plane (outward r, down s),
    the trochanter turning that plane about the leg's long axis, the coxa turning it about
    the vertical (eq. 4.4–4.6). The same results as :func:`fk` (tested equal).
    """
    c, t1, f, tb, ts = angles
    a2, a3 = geometry.femur, geometry.tibia
    a4 = geometry.contact_offset
    phi = f
    r = geometry.trochanter_offset + a2 * math.cos(phi)
    s = -a2 * math.sin(phi)
    phi += tb
    r += a3 * math.cos(phi)
    s -= a3 * math.sin(phi)
    phi += ts
    r += a4 * math.cos(phi)
    s -= a4 * math.sin(phi)
    zeta = s * math.sin(t1)
    y = s * math.cos(t1)
    return r * math.cos(c) - zeta * math.sin(c), y, r * math.sin(c) + zeta * math.cos(c)
