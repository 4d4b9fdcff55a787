"""A leg's overrides: which reflex holds which of its joints, and the blend back.

Theory of operation
-------------------
:class:`JointGoals` marked ``reflex`` on a leg's override input take its
positioning joints (coxa…tarsus) over: each goal holds its joint for
``hold_s`` from the goal's ``t``, unless an override of higher ``priority``
holds it (goals of one cycle, or one still held: the priority decides, then
the source's name, never the order of arrival). Once no override has held the
joint for ``hold_s``, the leg blends from the override's angle back to its own
over ``blend_s`` (minimum jerk): no jump. An override keeps control by coming
again; it never has to hand control back. A plain class: the leg controller
asks it each cycle.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from whexar.actors.messages import JointGoals
from whexar.kinematics.trajectory import min_jerk
from whexar.robot import POSITIONING_JOINTS

_POSITIONING = len(POSITIONING_JOINTS)
"""Joints an override may hold: coxa, trochanter, femur, tibia, tarsus."""


class Overrides:
    """The overrides of leg ``leg`` (module docstring)."""

    def __init__(self, leg: int, hold_s: float, blend_s: float) -> None:
        self.leg = leg
        self.hold_s = hold_s
        self.blend_s = blend_s
        self.held: dict[int, tuple[float, float, tuple[int, str]]] = {}
        """joint → (angle, time of the override goal, its (priority, source))."""
        self.blends: dict[int, tuple[float, float]] = {}
        """joint → (override angle at release, release time)."""

    def __bool__(self) -> bool:
        return bool(self.held or self.blends)

    def take(self, t: float, overrides: Iterable[JointGoals]) -> None:
        """Take the override goals that arrived by ``t``."""
        # Per joint, the highest priority wins — among this cycle's goals and over one
        # still held — then the source's name: never the order they arrived in.
        hold = self.hold_s
        for msg in overrides:
            if not msg.reflex:
                continue
            rank = (msg.priority, msg.source)
            for g in msg.goals:
                angle = g.position_rad
                mine = g.leg == self.leg and g.joint < _POSITIONING
                if not (mine and angle is not None and math.isfinite(angle)):
                    continue
                held = self.held.get(g.joint)
                if (
                    held is not None
                    and t - held[1] <= hold
                    and (held[2] > rank or (held[2] == rank and held[1] > msg.t))
                ):
                    continue
                self.held[g.joint] = (angle, msg.t, rank)
                self.blends.pop(g.joint, None)

    def apply(self, t: float, angles: list[float]) -> tuple[list[float], bool]:
        """``angles`` with the override-held joints, and the blend back from them; True
        while an override holds a joint."""
        hold, blend = self.hold_s, self.blend_s
        held = False
        out = list(angles)
        for joint, (angle, since, _) in list(self.held.items()):
            if t - since <= hold:
                out[joint] = angle
                held = True
            else:
                del self.held[joint]
                self.blends[joint] = (angle, since + hold)
        for joint, (angle, released) in list(self.blends.items()):
            w = (t - released) / blend
            if w >= 1.0:
                del self.blends[joint]
                continue
            out[joint] = angle + (angles[joint] - angle) * min_jerk(w)
        return out, held
