"""What the operator wants: motion commands checked and merged into the wanted state.

A :class:`MotionCommand` changes the fields it names and keeps the rest.
:func:`take_command` checks each against what the robot can do: a value
beyond a limit is clamped (:class:`CommandClamped`), a command that cannot be
carried out at all — not a number, an unknown gait, mode or stance, riding
upside down, a turn inside the body — is refused whole
(:class:`CommandRefused`) and changes nothing. Plain functions: the time and
the source of the events are arguments.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final

from whexar.actors.messages import CommandClamped, CommandRefused, MotionCommand
from whexar.config import RobotConfig
from whexar.kinematics.gait import AUTO_GAIT, GAITS
from whexar.runtime.messages import Event

MODES: Final = ("walk", "ride", "hybrid")
POSE_LIMIT_RAD: Final = math.radians(20.0)
"""Body roll and pitch a command may ask for over the feet."""
_NUMBERS: Final = (
    "vx_m_s",
    "vy_m_s",
    "yaw_rate_rad_s",
    "turn_radius_m",
    "step_height_m",
    "step_length_m",
    "body_height_m",
    "roll_rad",
    "pitch_rad",
)


@dataclass
class Wanted:
    """The state the operator asked for; the coordinator moves toward it."""

    vx: float = 0.0
    vy: float = 0.0
    yaw: float = 0.0
    radius: float | None = None
    gait: str = "tripod"
    mode: str = "walk"
    stance: str = "default"
    step_height: float = 0.06
    step_length: float = 0.1
    body_height: float | None = None
    roll: float = 0.0
    pitch: float = 0.0
    upside_down: bool = False
    stop: bool = False

    @classmethod
    def of(cls, cfg: RobotConfig) -> Wanted:
        """The configuration's defaults: its gait, stance, step height and length."""
        loco = cfg.locomotion
        return cls(
            gait=loco.gait,
            stance=loco.stance,
            step_height=loco.step_height_mm / 1000,
            step_length=loco.step_length_mm / 1000,
        )

    def twist(self) -> tuple[float, float, float]:
        """The wanted body twist in the upright frame, the turn radius resolved."""
        if self.radius is not None:
            return self.vx, 0.0, self.vx / self.radius
        return self.vx, self.vy, self.yaw


def refused(cmd: MotionCommand, reason: str, *, t: float, source: str) -> CommandRefused:
    """The event that drops ``cmd`` whole, naming what it asked for."""
    fields = {
        k: v
        for k in cmd.__dataclass_fields__
        if k not in ("t", "source") and (v := getattr(cmd, k)) not in (None, False)
    }
    return CommandRefused(t=t, source=source, command=repr(fields), reason=reason)


def take_command(
    want: Wanted, cmd: MotionCommand, cfg: RobotConfig, *, t: float, source: str
) -> list[Event]:
    """Check ``cmd`` and merge it into ``want``, or refuse it whole; the events it gives."""
    loco = cfg.locomotion
    events: list[Event] = []

    def refuse(reason: str) -> list[Event]:
        return [refused(cmd, reason, t=t, source=source)]

    def limit(field: str, value: float, lo: float, hi: float, why: str) -> float:
        applied = min(max(value, lo), hi)
        if applied != value:
            events.append(
                CommandClamped(
                    t=t, source=source, field=field, requested=value, applied=applied, reason=why
                )
            )
        return applied

    for key in _NUMBERS:
        value = getattr(cmd, key)
        if value is not None and not (isinstance(value, int | float) and math.isfinite(value)):
            return refuse(f"{key} = {value!r}: not a finite number")
    if cmd.gait is not None and cmd.gait not in GAITS and cmd.gait != AUTO_GAIT:
        return refuse(f"unknown gait {cmd.gait!r}; allowed: {', '.join(GAITS)}, {AUTO_GAIT}")
    if cmd.mode is not None and cmd.mode not in MODES:
        return refuse(f"unknown mode {cmd.mode!r}; allowed: {', '.join(MODES)}")
    if cmd.stance is not None and cmd.stance not in cfg.stances:
        return refuse(f"unknown stance {cmd.stance!r}; allowed: {', '.join(sorted(cfg.stances))}")
    upside = want.upside_down if cmd.upside_down is None else cmd.upside_down
    mode = cmd.mode or want.mode
    if upside and mode != "walk":
        return refuse("upside down the robot walks: its wheels face the sky (6.8.1)")
    radius = cmd.turn_radius_m
    if radius is not None:
        inner = loco.min_turn_radius_mm / 1000
        if abs(radius) < inner:
            return refuse(
                f"turn_radius_m = {radius:g}: inside the body; allowed: |R| ≥ {inner:g} m "
                "(spin in place with yaw_rate_rad_s instead)"
            )
    w = want
    if cmd.stop:
        w.vx = w.vy = w.yaw = 0.0
        w.radius = None
        w.stop = True
    if cmd.vx_m_s is not None:
        w.vx = cmd.vx_m_s
    if cmd.vy_m_s is not None:
        w.vy = cmd.vy_m_s
    if cmd.yaw_rate_rad_s is not None:
        w.yaw = cmd.yaw_rate_rad_s
        w.radius = None
    if radius is not None:
        w.radius = radius
    if cmd.vx_m_s is not None or cmd.vy_m_s is not None or cmd.yaw_rate_rad_s is not None:
        w.stop = False
    if cmd.gait is not None:
        w.gait = cmd.gait
    w.mode = mode
    w.upside_down = upside
    if cmd.stance is not None:
        w.stance = cmd.stance
        w.body_height = None
    if cmd.step_height_m is not None:
        w.step_height = limit(
            "step_height_m",
            cmd.step_height_m,
            0.0,
            loco.max_step_height_mm / 1000,
            "0 … locomotion.max_step_height_mm",
        )
    if cmd.step_length_m is not None:
        w.step_length = limit(
            "step_length_m",
            cmd.step_length_m,
            0.01,
            loco.max_step_length_mm / 1000,
            "0.01 m … locomotion.max_step_length_mm (the workspace)",
        )
    if cmd.body_height_m is not None:
        low = loco.sit_height_mm / 1000
        high = max(s.height_mm for s in cfg.stances.values()) / 1000
        w.body_height = limit(
            "body_height_m",
            cmd.body_height_m,
            low,
            high,
            "the seated height … the highest stance",
        )
    if cmd.roll_rad is not None:
        w.roll = limit(
            "roll_rad", cmd.roll_rad, -POSE_LIMIT_RAD, POSE_LIMIT_RAD, "±20° of body roll"
        )
    if cmd.pitch_rad is not None:
        w.pitch = limit(
            "pitch_rad", cmd.pitch_rad, -POSE_LIMIT_RAD, POSE_LIMIT_RAD, "±20° of body pitch"
        )
    return events
