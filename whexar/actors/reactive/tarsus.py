"""The tarsus reflex: the last segment parallel to gravity, from the present angles (4.2.2).

Theory of operation
-------------------
The thesis's tarsus reflex turned the tarsus to θ4 = −π/2 − θ2 − θ3 (eq. 4.19)
from the femur's and tibia's present positions, so that the leg's last segment
hangs parallel to gravity whatever the others do. It turned out too slow as a
reflex — the tarsus followed the other joints a cycle or more late — and the
thesis moved the rule into the inverse kinematics (6.3), as whexar's IK does
(:func:`whexar.kinematics.leg.ik_point`). The reflex form stays available, off
by default: on each servo reading it overrides each leg's tarsus with eq. 4.19
of the present femur and tibia angles (the leg holds an override for
``locomotion.reflex_hold_s``), for experiments with it — a leg whose IK does
not hold the tarsus, or a comparison with the thesis's first design. It acts
only where the present tarsus is more than ``deadband_rad`` from the rule, so a
leg whose IK already holds it is left alone.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from pydantic import Field

from whexar.actors.messages import ServoStates
from whexar.actors.reactive.reflex import Command, Reflex, ReflexParams
from whexar.config import RobotConfig
from whexar.robot import N_LEGS
from whexar.runtime.messages import Message

_FEMUR, _TIBIA, _TARSUS = 2, 3, 4


def parallel_to_gravity(femur: float, tibia: float) -> float:
    """Eq. 4.19: the tarsus angle that keeps the last segment parallel to gravity."""
    return -math.pi / 2 - femur - tibia


class TarsusParams(ReflexParams):
    """When the tarsus reflex acts."""

    deadband_rad: float = Field(math.radians(2.0), gt=0.0, le=0.5)
    """A tarsus within this of eq. 4.19 is left alone: 2°, 23 ticks of the MX's 0.088°
    resolution, so a leg whose IK holds the rule (Table 6.5 to 0.01°) is not touched."""


class Tarsus(Reflex):
    """Overrides each leg's tarsus with eq. 4.19 of its present angles (module docstring)."""

    inputs = ("servo_state",)
    priority = 5
    Params = TarsusParams
    params: TarsusParams

    def __init__(self, params: ReflexParams, *, name: str, cfg: RobotConfig) -> None:
        super().__init__(params, name=name, cfg=cfg)
        self.present: list[list[float | None]] = [[None] * 5 for _ in range(N_LEGS)]

    def react(self, t: float, msg: Message) -> Iterable[Command]:
        if not isinstance(msg, ServoStates):
            return ()
        for j in msg.joints:
            if j.joint <= _TARSUS and j.position_rad is not None:
                self.present[j.leg][j.joint] = j.position_rad
        out: list[Command] = []
        acting = []
        for leg, q in enumerate(self.present):
            femur, tibia, tarsus = q[_FEMUR], q[_TIBIA], q[_TARSUS]
            if femur is None or tibia is None or tarsus is None:
                continue
            goal = parallel_to_gravity(femur, tibia)
            if abs(goal - tarsus) > self.params.deadband_rad:
                acting.append(leg)
                out.append(self.override(t, leg, {_TARSUS: goal}))
        self.active = bool(acting)
        self.reason = f"tarsus of legs {acting} off gravity" if acting else ""
        return out
