"""Heading hold: the IMU's yaw rate corrects the commanded turn (beyond the thesis).

Theory of operation
-------------------
A weak or lost coxa turns a walking robot: with the middle right coxa silent,
the tripod walk veered 23° in 8 s (docs/servo-failures.md) and nothing
noticed. This reflex integrates the body's measured yaw rate against the turn
rate the operator commands into a heading error, and asks the coordinator for
a turn-rate correction against it (:class:`~whexar.actors.messages.ReflexRequest`,
``yaw_rate_rad_s``): proportional to the error and to its integral (a steady
pull is held with no error left), bounded, the integral held while at the bound.

* **The gyroscope's zero-rate level** is learnt while the robot stands still:
  an uncalibrated LSM9DS1 reads up to ±30 dps at rest (data sheet, Table 3),
  enough to turn the robot in circles. Still means the coordinator stands or
  sits and commands no motion — not while it stands up, sits down or re-places
  feet — and the body's pose and the trochanters have not moved for
  ``settle_s`` (the obstacle reflex's sweep sways the body over its feet).
  The reflex averages the yaw axis's reading then, then low-passes it
  (``bias_tau_s``); it corrects nothing until it has learnt for ``learn_s``.
  Learnt through the obstacle's sweep, the level was 0.47 dps off: the default
  course veered 37° in 75 s with the heading believed held (docs/reflexes.md).
* **The error** integrates only while the body translates (walking, riding,
  the hybrid gait with a linear speed): turning on the spot is the operator's.
  It starts from zero at each start: the heading to hold is the one the robot
  had when it set off. (Kept through halts, with what the body turned
  meanwhile counted, the corrections after each halt cost the sill, the box
  and the trench a seed each in the reflex campaign: docs/reflexes.md.)
* **The reference** is the commanded turn rate less this reflex's own
  correction (the coordinator's state carries both), so that an operator's
  turn is followed, not fought.

It is active while the error exceeds ``active_deg``; it withdraws its request
when the body stops translating.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Literal

from pydantic import Field

from whexar.actors.messages import BodyMotion, ImuSample, LocomotionState
from whexar.actors.reactive.reflex import Command, Reflex, ReflexParams
from whexar.config import RobotConfig
from whexar.runtime.messages import Message

Axis = Literal["x", "y", "z", "-x", "-y", "-z"]
MOVING = frozenset({"walking", "riding", "hybrid"})
STILL = frozenset({"standing", "seated"})
"""The activities in which the body may stand still: the gyroscope's level is learnt."""
MOVED_M = 1e-3
MOVED_RAD = math.radians(0.25)
"""A jump of the body's pose or trochanter angle from one of the coordinator's cycles to
the next above these is a motion (m, rad): the obstacle reflex's sweep steps 2° at once.
Standing on 30°, the trochanter follows the filtered pitch by 0.02° a cycle (2°/s while
it settles): no motion, else the level would never be learnt there."""
STILL_M_S = 1e-3
"""A commanded linear speed below this is no translation."""


class HeadingParams(ReflexParams):
    """Heading hold's gains and limits (chosen on the lost-coxa walk, docs/reflexes.md)."""

    gain_per_s: float = Field(1.5, gt=0.0, le=20.0)
    """Turn-rate correction per radian of heading error, rad/s per rad."""
    integral_per_s2: float = Field(0.5, ge=0.0, le=20.0)
    """Correction per radian-second of the error's integral: a steady pull (a lost coxa)
    is held with no error left."""
    max_rad_s: float = Field(0.25, gt=0.0, le=1.0)
    """Largest correction, rad/s (the tripod walk's turns reach about 0.5 rad/s)."""
    yaw_axis: Axis = "z"
    """The IMU axis that reads the body's yaw rate, counter-clockwise positive (the
    LSM9DS1 mounted level, z up: ``z``)."""
    bias_tau_s: float = Field(2.0, gt=0.0, le=60.0)
    """Time constant of the zero-rate level's low-pass while standing still."""
    learn_s: float = Field(0.5, ge=0.0, le=60.0)
    """Standing still this long before the first correction (the level learnt)."""
    settle_s: float = Field(0.5, ge=0.0, le=10.0)
    """The body's pose and trochanters unchanged this long before the level is learnt, s:
    the servos reach a goal within a few control cycles, the body's sway dies with them."""
    step_rad_s: float = Field(0.005, gt=0.0, le=0.1)
    """A new request goes out when the correction moves by this much."""
    active_deg: float = Field(3.0, gt=0.0, le=90.0)
    """Heading error above which the reflex says it is active."""


class HeadingHold(Reflex):
    """Holds the heading a translating robot set off with (module docstring)."""

    inputs = ("imu", "locomotion", "motion")
    priority = 10
    Params = HeadingParams
    params: HeadingParams

    def __init__(self, params: ReflexParams, *, name: str, cfg: RobotConfig) -> None:
        super().__init__(params, name=name, cfg=cfg)
        p = self.params
        self.sign = -1.0 if p.yaw_axis.startswith("-") else 1.0
        self.axis = "xyz".index(p.yaw_axis[-1])
        self.bias_dps = 0.0
        self.learnt_s = 0.0
        self.error_rad = 0.0
        self.integral = 0.0
        """∫ error dt while translating, rad·s (held back while the correction is at its
        bound: no wind-up)."""
        self.translating = False
        self.still = False
        """The coordinator stands or sits, commanding no motion."""
        self.posed: tuple[float, ...] | None = None
        """The body's pose and trochanter angle in the coordinator's last cycle."""
        self.moved_t = -math.inf
        """When they last jumped, s."""
        self.reference_rad_s = 0.0
        """The operator's commanded turn rate (the coordinator's, less this correction)."""
        self.sent = 0.0
        """The correction last asked for, rad/s."""
        self.last_t: float | None = None

    def react(self, t: float, msg: Message) -> Iterable[Command]:
        if isinstance(msg, LocomotionState):
            return self._state(t, msg)
        if isinstance(msg, ImuSample):
            return self._sample(t, msg)
        if isinstance(msg, BodyMotion):
            posed = (*msg.pose, msg.trochanter_rad)
            last = self.posed
            if last is None or any(
                abs(a - b) > (MOVED_M if k < 3 else MOVED_RAD)
                for k, (a, b) in enumerate(zip(posed, last, strict=True))
            ):
                self.moved_t = t
            self.posed = posed
        return ()

    def _state(self, t: float, s: LocomotionState) -> Iterable[Command]:
        vx, vy, w = s.twist
        moving = s.activity in MOVING and math.hypot(vx, vy) > STILL_M_S
        self.reference_rad_s = w - self.sent
        self.still = s.activity in STILL and not (vx or vy or w)
        if moving == self.translating:
            return ()
        self.translating = moving
        self.error_rad = self.integral = 0.0  # the heading to hold: the one it sets off with
        if moving or self.sent == 0.0:
            return ()
        self.sent = 0.0
        self.active = False
        return (self.request(t, yaw_rate_rad_s=0.0, reason="stopped"),)

    def _sample(self, t: float, m: ImuSample) -> Iterable[Command]:
        dt = 0.0 if self.last_t is None else max(0.0, t - self.last_t)
        self.last_t = t
        rate_dps = self.sign * m.gyro_dps[self.axis]
        p = self.params
        if not self.translating:
            if self.still and t - self.moved_t >= p.settle_s and dt > 0.0:  # learn the level
                self.learnt_s += dt
                # The mean of what it read, then a low-pass: not the first reading's noise.
                k = min(1.0, dt / min(p.bias_tau_s, self.learnt_s))
                self.bias_dps += (rate_dps - self.bias_dps) * k
            return ()
        if self.learnt_s < p.learn_s:
            return ()
        rate = math.radians(rate_dps - self.bias_dps)
        self.error_rad += (rate - self.reference_rad_s) * dt
        integral = self.integral + self.error_rad * dt
        free = -(p.gain_per_s * self.error_rad + p.integral_per_s2 * integral)
        want = max(-p.max_rad_s, min(p.max_rad_s, free))
        if want == free:
            self.integral = integral
        error_deg = math.degrees(self.error_rad)
        self.active = abs(error_deg) > p.active_deg
        self.reason = f"heading off by {error_deg:+.1f}°"
        if abs(want - self.sent) < p.step_rad_s:
            return ()
        self.sent = want
        return (self.request(t, yaw_rate_rad_s=want, reason=self.reason),)
