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

What the coordinator does about each (:meth:`WalkOnLosses.joint_lost`):

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

from whexar.actors.locomotion.core import SETTLE_S
from whexar.actors.locomotion.engines import Engines
from whexar.actors.messages import CommandRefused, JointBack, JointLost, ServoStates
from whexar.config import RobotConfig
from whexar.robot import JOINT_NAMES, LEG_NAMES

PERIODS: Final = 3.0
"""A joint unread for this many of its own read periods (and ``lost_after_s``) is lost."""

Key = tuple[int, int]
"""(leg, joint)."""
_COXA: Final = JOINT_NAMES.index("coxa")
_TROCHANTER: Final = JOINT_NAMES.index("trochanter")
_WHEEL_JOINTS: Final = frozenset({JOINT_NAMES.index("direction"), JOINT_NAMES.index("wheel")})


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


class WalkOnLosses(Engines):
    """The coordinator's answer to a lost joint (module docstring), over its state."""

    def __init__(self, cfg: RobotConfig, *, name: str) -> None:
        super().__init__(cfg, name=name)
        self.losses = LostJoints(self.loco.lost_after_s)
        self.no_wheel: set[int] = set()
        """Legs whose wheel direction or drive is lost: the robot walks (:meth:`_recount`)."""
        self.trochanter_held: float | None = None
        """The angle the trochanters hold while one is lost."""

    def _recount(self) -> None:
        """What the lost joints leave: the legs without a wheel, and the riders — a lost
        coxa's leg whose wheel is there (``ride_lost_coxa``)."""
        lost = self.losses.lost
        self.no_wheel = {leg for leg, j in lost if j in _WHEEL_JOINTS}
        coxa_lost = {leg for leg, j in lost if j == _COXA}
        self.riders = coxa_lost - self.no_wheel if self.loco.ride_lost_coxa else set()
        self.riding &= self.riders
        if not any(j == _TROCHANTER for _, j in lost):
            self.trochanter_held = None

    def joint_lost(self, leg: int, joint: int) -> None:
        """The bus stopped reading ``joint`` of ``leg``: walk on without it where the robot
        can (:mod:`.losses`), and say what changes (:class:`JointLost`)."""
        if joint == _TROCHANTER and self.trochanter_held is None:
            self.trochanter_held = self.trochanter_rad
        self._recount()
        if joint == _COXA:
            if leg in self.riders:
                action = "the leg rides its wheel while the others walk"
            else:
                why = "its wheel is lost too" if leg in self.no_wheel else "ride_lost_coxa off"
                action = f"none ({why}): the leg is dragged"
        elif joint == _TROCHANTER:
            action = f"the trochanters hold {math.degrees(self.trochanter_held or 0.0):.1f}°"
        elif joint in _WHEEL_JOINTS:
            action = "riding refused: the robot walks"
            if (leg, _COXA) in self.losses.lost:
                action += "; the leg, its coxa lost, is dragged"
            if self.want.mode != "walk":
                self._walk_without_wheels()
        elif JOINT_NAMES[joint] == "tarsus":
            action = "none: the tarsus holds where it stopped"
        else:
            action = "none: the bus stops the robot, the leg cannot carry the body"
        self.say(JointLost(t=self.t, source=self.name, leg=leg, joint=joint, action=action))

    def joint_back(self, leg: int, joint: int) -> None:
        """``joint`` of ``leg`` is read again: undo what its loss changed."""
        self._recount()
        self.say(JointBack(t=self.t, source=self.name, leg=leg, joint=joint))

    def _walk_without_wheels(self) -> None:
        legs = ", ".join(LEG_NAMES[i] for i in sorted(self.no_wheel))
        self.say(
            CommandRefused(
                t=self.t,
                source=self.name,
                command=f"mode {self.want.mode}",
                reason=f"the wheel of {legs} is lost: the robot walks",
            )
        )
        self.want.mode = "walk"

    def _ride_riders(self) -> None:
        """Tell each rider not told yet to ride its wheel, its foot where it is."""
        for leg in sorted(self.riders - self.riding):
            foot = self.feet[leg]
            if foot is None or self.t < self.swing_until[leg]:
                continue
            self.send_step(leg, "ride", SETTLE_S, foot)
            self.riding.add(leg)
