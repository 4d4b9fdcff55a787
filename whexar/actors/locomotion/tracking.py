"""Where a leg's joints put its foot: the servos' tracking at the foot.

The leg sends goals and reads its joints back each cycle. Forward kinematics of
both, in the upright frame (:mod:`.frames`), say where the joints hold the foot
and where the goals put it: their distance is the foot's tracking error
(``LegState.foot_error_m``, the stepping reflex's input). Two rules of the
leg's adaptive swing read them:

* how high the joints have lifted the foot in a swing (:class:`Lift`);
* a swing stopped early by ground stands where the joints hold the foot across
  the ground, not where its goal had gone on to (:func:`stand_where_stopped`):
  against an edge or a face the goal runs on past the foot by the servos' lag,
  and held there the leg pushes the body away from what stopped it with the
  servos' stiffness. Only after the joints lifted the foot :data:`LIFTED` of
  its step (docs/reflexes.md, "A foot stopped on an edge").

Plain functions over plain data: no time is read, nothing is sent.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final

from whexar.actors.locomotion.frames import LegFrame
from whexar.actors.messages import Vec3
from whexar.kinematics.geometry import LegGeometry
from whexar.kinematics.leg import fk_point
from whexar.robot import POSITIONING_JOINTS

_POSITIONING: Final = len(POSITIONING_JOINTS)
READ_FRESH_S: Final = 0.1
"""A joint read longer ago (a servo lost) leaves the foot's error unknown: ten cycles."""
_READ_JOINTS: Final = (0, 2, 3, 4)
"""The joints the foot's error reads (the default plan leaves the trochanter out)."""
LIFTED: Final = 0.5
"""A swing stopped early stands where its foot stopped only if the joints had lifted the
foot this fraction of its step: one that came down on an edge had risen over it, one that
never left its ground (a loaded leg on a steep slope) had not (docs/reflexes.md, "A foot
stopped on an edge")."""

BLOCK_LIFT_M: Final = 0.01
"""A swing is blocked on its way up only once the joints have lifted its foot this high, m:
on 30° a loaded leg's contact comes and goes as its load moves off at lift-off, its foot
risen 0–8 mm, and a 6 cm sill stopped the front feet at 1.5–4.4 cm (docs/reflexes.md,
"elevator")."""


@dataclass(frozen=True)
class Tracked:
    """Where the joints read put the foot (``measured``) and where the goals sent put it
    (``sent``: None while a joint read is stale or no goal was sent), upright frame."""

    measured: Vec3
    sent: Vec3 | None

    @property
    def error(self) -> float | None:
        """The foot's tracking error, m (None: not known)."""
        return None if self.sent is None else math.dist(self.measured, self.sent)


def tracked(
    read: Sequence[float | None],
    read_t: Sequence[float],
    sent: Sequence[float],
    t: float,
    troch: float,
    geometry: LegGeometry,
    frame: LegFrame,
) -> Tracked | None:
    """The foot's :class:`Tracked` points at ``t`` from the joints ``read`` (None: never
    read) at ``read_t`` and the goals ``sent``, per joint in the leg's order; ``troch``
    stands for a trochanter the plan does not read. None before the joints are read."""
    coxa, trochanter, femur, tibia, tarsus = read[:_POSITIONING]
    if trochanter is None:
        trochanter = troch  # a plan that does not read it (the default) leaves its goal
    if coxa is None or femur is None or tibia is None or tarsus is None:
        return None
    q = fk_point((coxa, trochanter, femur, tibia, tarsus), geometry)
    goals = list(sent[:_POSITIONING])
    fresh = all(t - read_t[j] <= READ_FRESH_S for j in _READ_JOINTS)
    g = fk_point(goals, geometry) if fresh and all(map(math.isfinite, goals)) else None
    if frame.upside_down:
        q = (q[0], -q[1], q[2])
        g = None if g is None else (g[0], -g[1], g[2])
    return Tracked(frame.from_leg(q), None if g is None else frame.from_leg(g))


class Lift:
    """How high the joints have lifted the foot in a swing: the highest point they put it,
    over the first (their own frame throughout)."""

    def __init__(self) -> None:
        self.lifted = 0.0
        self.start: float | None = None

    def reset(self) -> None:
        """A new step begins."""
        self.lifted, self.start = 0.0, None

    def see(self, seen: Tracked | None) -> None:
        """Take this cycle's points into account."""
        if seen is None:
            return
        z = seen.measured[2]
        if self.start is None:
            self.start = z
        self.lifted = max(self.lifted, z - self.start)

    def raised(self) -> bool:
        """Whether the joints have lifted the foot :data:`BLOCK_LIFT_M` off its ground (not
        known, joints unread: taken as lifted, as the goals say)."""
        return self.start is None or self.lifted >= BLOCK_LIFT_M

    def enough(self, height: float) -> bool:
        """Whether the foot rose :data:`LIFTED` of a step ``height`` high."""
        return self.lifted >= LIFTED * height


def stand_where_stopped(foot: list[float], before: Vec3, seen: Tracked | None) -> None:
    """Move ``foot`` (in place) across the ground to where the joints hold it: ``before``,
    the point the goals on the wire were solved for, moved by the servos' tracking error.
    The error, not the joints' point itself: the plan's points and the joints' forward
    kinematics part where the trochanter turns (its arc, docs/slopes.md). Up and down the
    goal stays: pressing onto the ground is what loads a stance foot."""
    if seen is None or seen.sent is None:
        return
    for k in (0, 1):
        foot[k] = before[k] + seen.measured[k] - seen.sent[k]


__all__ = [
    "BLOCK_LIFT_M",
    "LIFTED",
    "READ_FRESH_S",
    "Lift",
    "Tracked",
    "stand_where_stopped",
    "tracked",
]
