"""The trochanter reflex: past a body tilt, the legs parallel to gravity (4.2.2, 6.7.6).

Theory of operation
-------------------
The thesis's trochanter reflex turned the trochanters when the IMU's tilt
exceeded a threshold, so that the legs stood parallel to gravity again
(θ1 = body pitch, eq. 4.18); on a tilting board it walked 32°, rode 40° and
stood on 50° (6.7.6). whexar's coordinator follows the pitch continuously by
default (``locomotion.trochanter_follows_pitch``, with the feet carried on
their arcs as the thesis's IK does, :func:`whexar.kinematics.leg.trochanter_arc`):
the threshold at zero. The reflex form is the thesis's, for a robot configured
without that rule (``trochanter_follows_pitch = false``) or a comparison with
the thesis: it low-passes the measured pitch (``filter_s``: a slope is steady,
the accelerations of each step are not), becomes active when it exceeds
``on_deg`` and asks the coordinator to hold the trochanters at it
(:class:`~whexar.actors.messages.ReflexRequest`, ``trochanter_rad``), follows it
by ``step_deg`` while active, and withdraws below ``off_deg`` (the hysteresis
keeps it from flapping on a slope at the threshold). The coordinator bounds the
angle by ``locomotion.max_trochanter_deg``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from pydantic import Field, ValidationInfo, field_validator

from whexar.actors.messages import BodyTilt
from whexar.actors.reactive.reflex import Command, Reflex, ReflexParams
from whexar.config import RobotConfig
from whexar.runtime.messages import Message


class TrochanterParams(ReflexParams):
    """When the trochanter reflex acts (the thesis gives no threshold: chosen on the
    simulated walks, docs/reflexes.md)."""

    on_deg: float = Field(5.0, gt=0.0, le=45.0)
    """The filtered pitch beyond which the legs turn: above the flat walk's filtered
    pitch (within ±1°), below the 10° slope the thesis's controller already noticed."""
    off_deg: float = Field(3.0, ge=0.0, le=45.0)
    """Below this the reflex withdraws: the hysteresis under ``on_deg``."""
    filter_s: float = Field(1.0, gt=0.0, le=10.0)
    """Time constant of the pitch's low-pass (``locomotion.tilt_filter_s``'s default)."""
    step_deg: float = Field(0.5, gt=0.0, le=10.0)
    """While active, a new request when the pitch moved by this much."""

    @field_validator("off_deg")
    @classmethod
    def _below(cls, off: float, info: ValidationInfo) -> float:
        on = info.data.get("on_deg")
        if on is not None and off >= on:
            raise ValueError(f"below on_deg ({on})")
        return off


class Trochanter(Reflex):
    """Turns the trochanters to the body's pitch past a tilt (module docstring)."""

    inputs = ("tilt",)
    priority = 20
    Params = TrochanterParams
    params: TrochanterParams

    def __init__(self, params: ReflexParams, *, name: str, cfg: RobotConfig) -> None:
        super().__init__(params, name=name, cfg=cfg)
        self.pitch = 0.0
        """The low-passed pitch, rad."""
        self.last_t: float | None = None
        self.sent: float | None = None
        """The trochanter angle last asked for; None: none asked."""

    def react(self, t: float, msg: Message) -> Iterable[Command]:
        if not isinstance(msg, BodyTilt):
            return ()
        p = self.params
        if self.last_t is None:
            self.pitch = msg.pitch_rad
        else:
            k = min(1.0, max(0.0, t - self.last_t) / p.filter_s)
            self.pitch += (msg.pitch_rad - self.pitch) * k
        self.last_t = t
        tilt = abs(math.degrees(self.pitch))
        if not self.active and tilt > p.on_deg:
            self.active = True
        elif self.active and tilt < p.off_deg:
            self.active = False
            self.reason = ""
            self.sent = None
            return (self.request(t, trochanter_rad=0.0, reason="level again"),)
        if not self.active:
            return ()
        self.reason = f"body pitched {math.degrees(self.pitch):+.1f}°"
        if self.sent is not None and abs(self.pitch - self.sent) < math.radians(p.step_deg):
            return ()
        self.sent = self.pitch
        return (self.request(t, trochanter_rad=self.pitch, reason=self.reason),)
