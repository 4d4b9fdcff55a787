"""A stance that settles: the standing legs stop pushing each other through the ground.

Position-held legs standing on the flat draw more current than walking ones (the slopes
note: 11 A against 8): the stand-up drags the wheels, which friction then holds where
they landed, centimetres from their commanded points, and every leg pushes towards its
own point against the others. The thesis's controller balanced the legs' loads from the
force sensors and femur currents (4.2.5); here the coordinator does it from where the
feet are: each standing foot's goal is moved toward the foot measured by the servos
(its joints' forward kinematics), by each leg's error less the legs' mean error. The
mean is the load the legs carry together (the body's weight along a slope): it stays,
and only the forces the legs exchange relax. Vertically nothing changes: the height
holds.

Plain Python: the planner calls :func:`settled` every :data:`SETTLE_PERIOD_S` while it
stands.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Final

from whexar.actors.messages import Vec3

__all__ = ["SETTLE_MIN_M", "SETTLE_PERIOD_S", "settled"]

SETTLE_PERIOD_S: Final = 0.2
"""How often the standing feet's goals are moved (each move lasts this long)."""
SETTLE_MIN_M: Final = 0.002
"""A foot whose error, less the mean, is within this is left where it is."""


def settled(
    goals: Sequence[Vec3 | None],
    placed: Sequence[Vec3 | None],
    measured: Sequence[Vec3 | None],
    neutral: Sequence[Vec3],
    *,
    fraction: float,
    limit_m: float,
) -> dict[int, Vec3]:
    """The legs whose goal moves, and where to (upright frame).

    A leg's error is where its foot is ``measured`` less where the leg ``placed`` it (its
    goal as the trochanter carries it); its goal moves by ``fraction`` of that error, less
    the legs' mean error, in x and y, and never further than ``limit_m`` from its
    ``neutral`` point. Legs with no goal or no measurement take no part."""
    legs = [
        i
        for i in range(len(goals))
        if goals[i] is not None and placed[i] is not None and measured[i] is not None
    ]
    if len(legs) < 2:
        return {}
    errors: dict[int, tuple[float, float]] = {}
    for i in legs:
        m, p = measured[i], placed[i]
        assert m is not None
        assert p is not None
        errors[i] = (m[0] - p[0], m[1] - p[1])
    mx = sum(e[0] for e in errors.values()) / len(legs)
    my = sum(e[1] for e in errors.values()) / len(legs)
    out: dict[int, Vec3] = {}
    for i in legs:
        ex, ey = errors[i][0] - mx, errors[i][1] - my
        if math.hypot(ex, ey) <= SETTLE_MIN_M:
            continue
        g, n = goals[i], neutral[i]
        assert g is not None
        x, y = g[0] + fraction * ex, g[1] + fraction * ey
        dx, dy = x - n[0], y - n[1]
        far = math.hypot(dx, dy)
        # A goal the planner put further out (a gait's start places feet up to half a
        # stride from neutral) is not pulled in: only the settle's own moves are bounded.
        limit = max(limit_m, math.hypot(g[0] - n[0], g[1] - n[1]))
        if far > limit:
            x, y = n[0] + dx * limit / far, n[1] + dy * limit / far
        out[i] = (x, y, g[2])
    return out
