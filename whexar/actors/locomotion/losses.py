"""Servos the bus lost, as the coordinator learns of them (beyond the thesis).

Theory of operation
-------------------
The bus reports a lost servo by what it leaves out: a servo whose reads fail
``bus.degrade_after`` cycles in a row is left out of the cycle
(:class:`~whexar.actors.messages.ServoDegraded` says why) and its joint is missing
from every :class:`~whexar.actors.messages.ServoStates` from then on, until it
answers again. :class:`LostJoints` watches each joint's reads: a joint read before
and then not for ``lost_after_s`` — or three of its own read periods, for a joint
the read plan reads rarely — is *lost*; read again, it is *back*. A joint read once
only (at start-up) is never judged: its period is unknown.

What the coordinator does about each (:meth:`LocomotionPlanner.joint_lost`):

* **coxa**: the leg cannot move its foot along the walk any more. It *rides its
  wheel* while the others walk: it never lifts, holds its foot where it is under
  the body, steers its wheel along the ground's velocity at the foot and drives it
  at that speed (eq. 5.17–5.18), so it keeps carrying its share of the body instead
  of being dragged (a lost coxa used to drag its tripod group and turn the robot);
* **trochanter**: the trochanters stop following the pitch and hold the angle they
  had;
* **wheel direction or drive**: riding and the hybrid gait are refused, the robot
  walks; a leg riding for a lost coxa is then dragged;
* **tarsus**: nothing changes (it holds its last goal, the foot's tip a few degrees
  off);
* **femur, tibia**: the bus stops the robot (:class:`BusLost`): the leg cannot carry
  the body.
"""

from __future__ import annotations

import math
from typing import Final

from whexar.actors.messages import ServoStates

PERIODS: Final = 3.0
"""A joint unread for this many of its own read periods (and ``lost_after_s``) is lost."""

Key = tuple[int, int]
"""(leg, joint)."""


class LostJoints:
    """Which joints the bus stopped reading (module docstring)."""

    def __init__(self, lost_after_s: float) -> None:
        self.after_s = lost_after_s
        self.read_t: dict[Key, float] = {}
        self.period: dict[Key, float] = {}
        """The interval between a joint's last two reads, s."""
        self.lost: set[Key] = set()
        self._next_check = -math.inf

    def take(self, states: ServoStates) -> tuple[list[Key], list[Key]]:
        """The joints lost and the ones back with this cycle's reads."""
        t = states.t
        read_t, period, lost = self.read_t, self.period, self.lost
        back: list[Key] = []
        for j in states.joints:
            if j.position_rad is None and j.velocity_rad_s is None:
                continue
            key = (j.leg, j.joint)
            last = read_t.get(key)
            if last is not None and t > last:
                period[key] = t - last
            read_t[key] = t
            if key in lost:
                lost.discard(key)
                back.append(key)
        if t < self._next_check and not back:
            return [], back
        # A few times per lost_after_s is soon enough, and spares 42 lookups a cycle.
        self._next_check = t + 0.25 * self.after_s
        gone = [
            key
            for key, last in read_t.items()
            if key not in lost
            and key in period
            and t - last > max(self.after_s, PERIODS * period[key])
        ]
        lost.update(gone)
        return sorted(gone), back
