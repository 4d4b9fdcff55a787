"""Static stability margin of a support polygon (Žák 2023, 3.2.2, eq. 3.1–3.6).

The robot is statically stable while its centre of gravity (CoG), projected on the ground
plane, lies inside the support polygon spanned by the feet in contact; the static stability
margin (SSM) is the shortest distance from the CoG to the polygon's edges (3.2.2, Fig. 3.4).
Margins here are signed: positive inside, zero on an edge (critically stable, Fig. 3.4c) and
negative outside (statically unstable, Fig. 3.4b). Coordinates are horizontal (x, y) in any
frame shared by the supports and the CoG; a z column is ignored.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import TYPE_CHECKING, Final

import numpy as np

from whexar._typing import ArrayLike, FloatArray
from whexar.errors import UsageError
from whexar.robot import N_LEGS

if TYPE_CHECKING:
    from whexar.kinematics.gait import Gait
    from whexar.kinematics.trajectory import FootTrajectory

MIN_SUPPORTS: Final = 3
"""Fewest supports that can enclose an area (3.2.2: a tripod stance is the minimum)."""


def _planar(name: str, value: ArrayLike, rows: tuple[int, int] | None) -> FloatArray:
    points = np.asarray(value, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise UsageError(f"{name} has shape {points.shape}: expected (k, 2) or (k, 3) points in m")
    if rows is not None and not rows[0] <= points.shape[0] <= rows[1]:
        raise UsageError(
            f"{name} has {points.shape[0]} points: a support polygon needs "
            f"{rows[0]}–{rows[1]} feet on the ground"
        )
    if not np.all(np.isfinite(points)):
        bad = np.argwhere(~np.isfinite(points))[0]
        raise UsageError(f"{name}[{bad[0]}, {bad[1]}] = {points[tuple(bad)]!r}: must be finite")
    return points[:, :2]


def _point(name: str, value: ArrayLike) -> FloatArray:
    point = np.asarray(value, dtype=np.float64)
    if point.shape not in ((2,), (3,)):
        raise UsageError(f"{name} has shape {point.shape}: expected (x, y) or (x, y, z) in m")
    if not np.all(np.isfinite(point)):
        raise UsageError(f"{name} = {point.tolist()!r}: coordinates must be finite")
    return point[:2]


def triangle_margin(
    p1: ArrayLike, p2: ArrayLike, p3: ArrayLike, cog: ArrayLike = (0.0, 0.0)
) -> float:
    """Stability margin of a tripod stance, literally eq. 3.1–3.6 of Žák 2023 (3.2.2, Fig. 3.5).

    For each edge (p_a, p_b) the signed area S_k of the triangle (p_a, p_b, CoG) (eq. 3.2–3.3)
    and the edge length L_k (eq. 3.4) give the altitude H_k = 2·S_k/L_k (eq. 3.5); the margin
    is H = min(H₁, H₂, H₃) (eq. 3.6). Areas are oriented by the support triangle so that H is
    positive inside. Outside, eq. 3.6 gives minus the distance to the nearest violated edge
    *line*, which near a corner is shorter than the true distance that
    :func:`static_stability_margin` reports. A degenerate triangle (collinear or coincident
    feet, S = 0) has no inside; it falls back to :func:`static_stability_margin` (≤ 0).
    """
    a, b, c = (_point(name, p) for name, p in (("p1", p1), ("p2", p2), ("p3", p3)))
    g = _point("cog", cog)

    def area(p: FloatArray, q: FloatArray, r: FloatArray) -> float:
        # eq. 3.2: S(p, q, r) = ½[(x_q − x_p)(y_r − y_p) − (x_r − x_p)(y_q − y_p)]
        return 0.5 * float((q[0] - p[0]) * (r[1] - p[1]) - (r[0] - p[0]) * (q[1] - p[1]))

    whole = area(a, b, c)
    if whole == 0.0:
        return static_stability_margin(np.stack([a, b, c]), g)
    orientation = 1.0 if whole > 0.0 else -1.0
    heights = [
        2.0 * orientation * area(p, q, g) / float(np.hypot(p[0] - q[0], p[1] - q[1]))  # eq. 3.3–3.5
        for p, q in ((a, b), (b, c), (c, a))
    ]
    return min(heights)  # eq. 3.6


def _convex_hull(points: FloatArray) -> FloatArray:
    """:func:`convex_hull` of an (k, 2) array, as an array."""
    return np.array(convex_hull((float(x), float(y)) for x, y in points), dtype=np.float64)


def _segment_distances(starts: FloatArray, ends: FloatArray, cogs: FloatArray) -> FloatArray:
    """Distances (n, e) from each CoG to each segment starts[e]→ends[e]."""
    edge = ends - starts  # (e, 2)
    rel = cogs[:, None, :] - starts[None, :, :]  # (n, e, 2)
    length2 = np.einsum("ej,ej->e", edge, edge)
    safe = np.where(length2 > 0.0, length2, 1.0)  # a zero-length segment is its start point
    t = np.clip(np.einsum("nej,ej->ne", rel, edge) / safe, 0.0, 1.0)
    nearest = starts[None, :, :] + t[..., None] * edge[None, :, :]
    result: FloatArray = np.hypot(*np.moveaxis(cogs[:, None, :] - nearest, -1, 0))
    return result


def static_stability_margins(support_points: ArrayLike, cogs: ArrayLike) -> FloatArray:
    """Signed static stability margins (m) of one support polygon for many CoG positions.

    ``support_points`` (k, 2) or (k, 3), 3 ≤ k ≤ 6; ``cogs`` (n, 2) or (n, 3). Returns (n,):
    the distance from each CoG to the boundary of the support polygon, the convex hull of the
    supports (Žák 2023, 3.2.2, Fig. 3.4), positive inside, negative outside, zero on an edge.
    Collinear or coincident supports enclose no area: their margin is minus the distance to the
    segment (or point) they span, so it is 0 at best.
    """
    supports = _planar("support_points", support_points, (MIN_SUPPORTS, N_LEGS))
    points = _planar("cogs", cogs, None)
    hull = _convex_hull(supports)
    if len(hull) < 3:
        return -_segment_distances(hull[:1], hull[-1:], points)[:, 0]
    ends = np.roll(hull, -1, axis=0)
    distance = _segment_distances(hull, ends, points).min(axis=1)
    edge = ends - hull
    rel = points[:, None, :] - hull[None, :, :]
    # z of edge × (cog − start): ≥ 0 for every edge of a counter-clockwise hull ⇔ inside
    inward = edge[None, :, 0] * rel[..., 1] - edge[None, :, 1] * rel[..., 0]
    inside = np.all(inward >= 0.0, axis=1)
    result: FloatArray = np.where(inside, distance, -distance)
    return result


def static_stability_margin(support_points: ArrayLike, cog: ArrayLike = (0.0, 0.0)) -> float:
    """Signed static stability margin (m) of the CoG over the support polygon (Žák 2023, 3.2.2).

    ``support_points`` are the 3–6 feet on the ground, (k, 2) or (k, 3) in any horizontal frame
    shared with ``cog`` (z ignored); their order does not matter. The margin is the shortest
    distance from the CoG to the edges of their convex hull: positive inside, 0 on an edge,
    negative outside. For a tripod with the CoG inside it equals min(H₁, H₂, H₃) of eq. 3.1–3.6
    (:func:`triangle_margin`). Collinear supports give minus the distance to their segment.
    """
    point = _point("cog", cog)
    return float(static_stability_margins(support_points, point[None, :])[0])


def support_margin(points: list[tuple[float, float]], cog: tuple[float, float]) -> float:
    """:func:`static_stability_margin` in plain Python, for at most six points: the case a
    coordinator asks every cycle, where numpy's call overhead is most of the cost (tested
    equal). Fewer than three supports: −∞; collinear ones: minus the distance to their
    segment, as :func:`static_stability_margins` gives."""
    if len(points) < 3:
        return -math.inf
    hull = convex_hull(points)
    cx, cy = cog
    if len(hull) < 3:  # collinear or coincident: minus the distance to their segment
        (ax, ay), (bx, by) = hull[0], hull[-1]
        ex, ey = bx - ax, by - ay
        length2 = ex * ex + ey * ey
        u = 0.0 if length2 == 0 else ((cx - ax) * ex + (cy - ay) * ey) / length2
        u = 0.0 if u < 0.0 else 1.0 if u > 1.0 else u
        return -math.hypot(cx - ax - u * ex, cy - ay - u * ey)
    best = math.inf
    inside = True
    # min(max(u, 0), 1) and min(best, d) as comparisons: the same results, no calls.
    for (ax, ay), (bx, by) in zip(hull, hull[1:] + hull[:1], strict=True):
        ex, ey = bx - ax, by - ay
        length2 = ex * ex + ey * ey
        u = 0.0 if length2 == 0 else ((cx - ax) * ex + (cy - ay) * ey) / length2
        u = 0.0 if u < 0.0 else 1.0 if u > 1.0 else u
        d = math.hypot(cx - ax - u * ex, cy - ay - u * ey)
        if d < best:
            best = d
        if ex * (cy - ay) - ey * (cx - ax) < 0.0:
            inside = False
    return best if inside else -best


def gravity_cog(
    cog: tuple[float, float], height: float, roll: float, pitch: float
) -> tuple[float, float]:
    """The CoG projected along gravity onto the support plane (3.2.2), in the plane's frame.

    ``cog`` is the CoG's (x, y) and ``height`` (m) its height above the support plane,
    both in a frame fixed to that plane (x forward, y left, z up), which gravity sees at
    ``roll`` and ``pitch`` (rad; pitch positive nose down, R = R_y(pitch)·R_x(roll) as in
    :class:`~whexar.kinematics.body.BodyPose`). Gravity in that frame is
    g = Rᵀ·(0, 0, −1) = (sin p, −cos p·sin r, −cos p·cos r); the CoG falls along it to the
    plane, h·(tan p / cos r, −tan r) from its foot. On a slope the supports must enclose
    that point, not the one straight below the body: climbing nose up (p < 0) it moves
    downhill, h·tan|p| towards the rear legs. On the flat it is ``cog`` itself.
    """
    if pitch == 0.0 and roll == 0.0:
        return cog
    cos_r = math.cos(roll)
    return cog[0] + height * math.tan(pitch) / cos_r, cog[1] - height * math.tan(roll)


def convex_hull(points: Iterable[tuple[float, float]]) -> list[tuple[float, float]]:
    """Counter-clockwise hull vertices of 2-D points (Andrew's monotone chain), in plain
    Python; collinear points dropped, so points on one line give its two ends."""
    pts = sorted(set(points))
    if len(pts) < 3:
        return pts
    lower: list[tuple[float, float]] = []
    for q in pts:
        while len(lower) >= 2 and _cross(lower[-2], lower[-1], q) <= 0:
            lower.pop()
        lower.append(q)
    upper: list[tuple[float, float]] = []
    for q in reversed(pts):
        while len(upper) >= 2 and _cross(upper[-2], upper[-1], q) <= 0:
            upper.pop()
        upper.append(q)
    return lower[:-1] + upper[:-1]


def _cross(o: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


__all__ = [
    "MIN_SUPPORTS",
    "convex_hull",
    "gravity_cog",
    "static_stability_margin",
    "static_stability_margins",
    "support_margin",
    "triangle_margin",
]


def gait_stability_margin(
    gait: Gait,
    feet: ArrayLike,
    trajectory: FootTrajectory,
    *,
    samples: int = 600,
    cog: ArrayLike = (0.0, 0.0),
) -> tuple[float, float]:
    """Smallest static stability margin over one gait cycle, and the phase where it occurs.

    ``feet`` (6, 2) or (6, 3) are the neutral foot points in the body frame; each
    leg moves along x by its foot trajectory at its own phase, and only the legs
    in stance support the body (3.2.1–3.2.2). The body is taken to move steadily,
    so the CoG stays at ``cog`` in the body frame.
    """
    if not (isinstance(samples, int) and samples > 0):
        raise UsageError(f"samples = {samples!r}: must be a positive whole number")
    neutral = _planar("feet", feet, (N_LEGS, N_LEGS))
    centre = _point("cog", cog)
    phases = np.arange(samples) / samples
    along, _ = trajectory.at(gait.leg_phase(phases))
    swinging = gait.in_swing(phases)
    worst, worst_phase = np.inf, 0.0
    for k in range(samples):
        points = neutral.copy()
        points[:, 0] += along[k]
        margin = static_stability_margin(points[~swinging[k]], centre)
        if margin < worst:
            worst, worst_phase = margin, float(phases[k])
    return float(worst), worst_phase
