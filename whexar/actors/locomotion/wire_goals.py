"""The goals a leg has said, and which of this cycle's are new.

The bus keeps a joint's goal until a new one comes, and sends a servo its goal again
on its own before the Bus Watchdog would expire: an unchanged goal need not travel. A
position within half a Goal Position tick of the last one said is unchanged; a wheel's
velocity changes when it differs at all. Plain Python: the leg's policy
(:mod:`whexar.actors.locomotion.leg_controller`) asks it each cycle, and for the
override goals that arrive between two cycles.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Final

from whexar.actors.messages import JointGoal, JointGoals
from whexar.robot import N_JOINTS

HALF_TICK_RAD: Final = math.pi / 4096
"""Half a Goal Position tick (0.088°): goals closer than this reach the wire unchanged."""
WHEEL: Final = 6
"""The wheel drive joint: a velocity goal."""


class WireGoals:
    """One leg's goals last said (module docstring); ``name`` is their ``source``."""

    __slots__ = ("leg", "name", "sent")

    def __init__(self, name: str, leg: int) -> None:
        self.name = name
        self.leg = leg
        self.sent: list[float] = [math.inf] * N_JOINTS
        """The goals last said, per joint (rad, or rad/s for the wheel); inf: none yet."""

    def changed(
        self, t: float, positions: Iterable[tuple[int, float]], wheel_rad_s: float | None = None
    ) -> JointGoals | None:
        """The goals among ``positions`` ((joint, rad) pairs) and the wheel's velocity that
        differ from the ones last said, said now (None: nothing new)."""
        last, name, leg = self.sent, self.name, self.leg
        goals = []
        for j, angle in positions:
            if abs(angle - last[j]) >= HALF_TICK_RAD:
                last[j] = angle
                goals.append(JointGoal(t=t, source=name, leg=leg, joint=j, position_rad=angle))
        if wheel_rad_s is not None and wheel_rad_s != last[WHEEL]:
            last[WHEEL] = wheel_rad_s
            goals.append(
                JointGoal(t=t, source=name, leg=leg, joint=WHEEL, velocity_rad_s=wheel_rad_s)
            )
        return JointGoals(t=t, source=name, goals=tuple(goals)) if goals else None
