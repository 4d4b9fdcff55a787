"""A sweep's points sorted into clear ground, a slope or an obstacle: the obstacle
reflex's picture of the ground ahead (:mod:`whexar.actors.reactive.obstacle`, whose
docstring says how the points are taken; docs/reflexes.md, "obstacle").

Plain functions over plain data: a point is ``(x, z)``, along the rays and up from the
ground under the feet.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

Kind = Literal["clear", "slope", "obstacle"]


@dataclass(frozen=True)
class Profile:
    """What a sweep saw (:func:`profile`): ``kind``; for an obstacle its ``front`` (m
    along the ray), ``height`` and ``depth`` (m), whether a ray passed over its top
    (``top_seen``: else the height is a lower bound) and beyond its back (``back_seen``:
    else the depth is); for a slope its ``face_deg``; whether a ray saw the rise's face
    (``face_seen``: ground before it, or its own points rising straight up; else its face
    ran from the front feet's ground)."""

    kind: Kind
    front: float = math.inf
    height: float = 0.0
    depth: float = 0.0
    top_seen: bool = False
    back_seen: bool = False
    face_deg: float = 90.0
    face_seen: bool = True


def ray_point(distance: float, down_rad: float, height: float) -> tuple[float, float]:
    """The point a ray from ``height`` m, pitched down by ``down_rad``, meets at
    ``distance`` m: (along, up) from the ground under the sensor; ``math.inf`` along for
    nothing in range."""
    if not math.isfinite(distance):
        return (math.inf, -math.inf)
    return (distance * math.cos(down_rad), height - distance * math.sin(down_rad))


def profile(
    points: Sequence[tuple[float, float]],
    *,
    min_height: float,
    tolerance: float,
    max_face_deg: float,
    origin: float = math.inf,
    ground: float = math.inf,
) -> Profile:
    """Sort a sweep's points (:func:`ray_point`; ``x`` infinite: the ray met nothing)
    into clear ground, a slope or an obstacle (module docstring). An obstacle's height is
    the median of its top's points: the sensor's noise spreads them over ``tolerance``.
    Given the rays' ``origin`` height, its back edge is placed between the last point on
    its top and the next ray's crossing of the top's height (a sweep's steps are coarse
    where the rays graze the top). Where no ray met the ground before the rise (the
    robot stands at its foot), its face runs from ``ground``, m along the rays: where
    the front feet stand, the last ground known."""
    risen = [p for p in points if math.isfinite(p[0]) and p[1] >= min_height]
    if not risen:
        return Profile("clear")
    top = max(z for _, z in risen)
    front = min(x for x, _ in risen)
    tops = [p for p in risen if p[1] >= top - tolerance]
    first = min(tops)
    lowest = min(risen, key=lambda p: (p[1], p[0]))
    face_seen = True
    if lowest[0] >= first[0] or lowest == first:
        before = [p for p in points if p[0] < front and p[1] < min_height]
        # No ground seen before it: its points rising straight up are its face (a wall's),
        # else it rises from the front feet's ground at the furthest.
        under = [p for p in risen if p[0] <= first[0] + 1e-3 and p[1] < first[1] - tolerance]
        if before:
            lowest = max(before)
        elif under:
            lowest = min(under, key=lambda p: p[1])
        else:
            lowest = (min(ground, first[0]), 0.0)
            face_seen = not math.isfinite(ground)
    run = first[0] - lowest[0]
    face = 90.0 if run <= 1e-3 else math.degrees(math.atan2(first[1] - lowest[1], run))
    if face < max_face_deg:
        return Profile("slope", front=front, height=top, face_deg=face, face_seen=face_seen)
    height = float(np.median([z for _, z in tops]))
    back = max(x for x, _ in tops)
    beyond = [p for p in points if p[0] > first[0] + tolerance and p[1] < top - tolerance]
    passed = [p for p in beyond if p[0] > back and math.isfinite(p[0])]
    if passed and origin > height:
        # The back edge lies between the last point on the top and where the first ray
        # that passed it crossed the top's height: the middle of the two.
        crossing = min(x * (origin - height) / (origin - z) for x, z in passed)
        back = (back + max(back, crossing)) / 2
    return Profile(
        "obstacle",
        front=front,
        height=height,
        depth=back - front,
        top_seen=bool(beyond),
        back_seen=bool(passed),
        face_deg=face,
        face_seen=face_seen,
    )


__all__ = ["Kind", "Profile", "profile", "ray_point"]
