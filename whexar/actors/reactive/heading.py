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
  enough to turn the robot in circles. While the coordinator stands or sits
  and commands no motion — not while it stands up, sits down or re-places
  feet, whose motions turn the body a little — the reflex averages the yaw
  axis's reading, then low-passes it (``bias_tau_s``); it corrects nothing
  until it has learnt for ``learn_s``. A level learnt through the stand-up and
  the start's re-placing was 0.19 dps off on 30°: 6° of unseen turn in 30 s,
  which rolled the body off the slope's line (docs/reflexes.md).
* **The error** is the turn the gyroscope reads less the turn the coordinator
  commands (an operator's turn, on the spot or walking, is followed). It
  starts from zero when the robot is on its legs (stood up, or flipped): the
  heading to hold is the one it set off with, kept through every halt and
  re-placing on the way, and what the body turns meanwhile counts. It is
  corrected while the body translates (walking, riding, the hybrid gait with
  a linear speed). Started afresh at each start, and blind while halted, it
  missed 9–23° of veer on 30° in 200 s: 5° in one re-placing (docs/reflexes.md).
* **The reference** is the commanded turn rate less this reflex's own
  correction (the coordinator's state carries both), so that an operator's
  turn is followed, not fought.

* **On a slope, gravity tells the heading.** However well the level is learnt,
  a gyroscope's heading drifts: 0.16 dps left in the level (the body settling
  as it learnt) is 13° in 80 s, and on 30° the robot veered 9–27° in 200 s
  with the heading believed held, the roll that goes with it (atan(tan 30° ·
  sin α)) leaving the feet of one side hanging. On ground tilted
  ``slope_min_deg`` or more the accelerometer's reading in the plane square to
  the yaw axis points down the slope, so its direction measures the heading
  against the slope's line (low-passed over ``accel_tau_s``: the steps' own
  accelerations are not it). While the slope lasts, the error is pulled
  toward what it says with the time constant ``gravity_tau_s``; the gyroscope
  keeps the fast turns. On the flat the gyroscope alone holds it.

It is active while the error exceeds ``active_deg``; it withdraws its request
when the body stops translating.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Literal

from pydantic import Field

from whexar.actors.messages import ImuSample, LocomotionState
from whexar.actors.reactive.reflex import Command, Reflex, ReflexParams
from whexar.config import RobotConfig
from whexar.runtime.messages import Message

Axis = Literal["x", "y", "z", "-x", "-y", "-z"]
MOVING = frozenset({"walking", "riding", "hybrid"})
OFF_LEGS = frozenset({"standing_up", "sitting_down", "seated", "flipping"})
"""The activities in which the heading to hold is forgotten: the robot is not on its legs."""
STILL = frozenset({"standing", "seated"})
"""The activities in which the body stands still: the gyroscope's level is learnt."""
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
    step_rad_s: float = Field(0.005, gt=0.0, le=0.1)
    """A new request goes out when the correction moves by this much."""
    active_deg: float = Field(3.0, gt=0.0, le=90.0)
    """Heading error above which the reflex says it is active."""
    slope_min_deg: float = Field(8.0, gt=0.0, le=60.0)
    """Ground tilted this much or more gives the heading against the slope's line: on the
    flat, walking, the low-passed reading tilts 1.1° at most (the spread's seeds 0 and 1,
    60 s; docs/reflexes.md)."""
    accel_tau_s: float = Field(1.0, gt=0.0, le=30.0)
    """Time constant of the accelerometer's low-pass: ``locomotion.tilt_filter_s``, a
    slope is steady, the steps' accelerations are not."""
    gravity_tau_s: float = Field(3.0, gt=0.0, le=120.0)
    """How fast the slope's heading pulls the gyroscope's error, s: slower than a
    correction's turn (1 / ``gain_per_s``), faster than a level's drift."""


class HeadingHold(Reflex):
    """Holds the heading a translating robot set off with (module docstring)."""

    inputs = ("imu", "locomotion")
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
        """The coordinator stands or sits, commanding no motion: the level is learnt."""
        self.on_legs = False
        """The robot stands on its legs (not standing up, sitting or flipping)."""
        self.reference_rad_s = 0.0
        """The operator's commanded turn rate (the coordinator's, less this correction)."""
        self.sent = 0.0
        """The correction last asked for, rad/s."""
        self.last_t: float | None = None
        self.down = (0.0, 0.0, 1.0)
        """The accelerometer's reading low-passed, g (in the IMU's axes)."""
        self.turned = 0.0
        """∫ the commanded turn since the heading to hold was set, rad."""
        self.lagged = 0.0
        """The heading the gyroscope has (the error and the commanded turns) low-passed as
        the reading is: what the slope's lagged heading is compared with, so that neither
        a veer nor an operator's turn is taken for drift."""
        self.toward: float | None = None
        """The slope's line's direction the held heading has, in the plane square to the
        yaw axis (rad; None on the flat: the gyroscope alone)."""

    def react(self, t: float, msg: Message) -> Iterable[Command]:
        if isinstance(msg, LocomotionState):
            return self._state(t, msg)
        if isinstance(msg, ImuSample):
            return self._sample(t, msg)
        return ()

    def _state(self, t: float, s: LocomotionState) -> Iterable[Command]:
        vx, vy, w = s.twist
        moving = s.activity in MOVING and math.hypot(vx, vy) > STILL_M_S
        # The coordinator turns a translating body only by the correction: else its turn
        # is the operator's alone.
        self.reference_rad_s = w - self.sent if moving else w
        self.still = s.activity in STILL and not (vx or vy or w)
        self.on_legs = s.activity not in OFF_LEGS
        if not self.on_legs:
            self.error_rad = self.integral = 0.0  # the heading to hold: the one it sets off with
        if moving == self.translating:
            return ()
        self.translating = moving
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
        if self.still and dt > 0.0:  # standing still: learn the level
            self.learnt_s += dt
            # The mean of what it read, then a low-pass: not the first reading's noise.
            k = min(1.0, dt / min(p.bias_tau_s, self.learnt_s))
            self.bias_dps += (rate_dps - self.bias_dps) * k
        self._gravity(m.accel_g, dt)
        if not self.on_legs or self.learnt_s < p.learn_s:
            self.turned = 0.0
            self.lagged = self.error_rad
            self.toward = None
            return ()
        rate = math.radians(rate_dps - self.bias_dps)
        self.error_rad += (rate - self.reference_rad_s) * dt
        self._slope(dt)
        if not self.translating:
            return ()  # halted: not turned by a correction, nor its integral wound up
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

    def _gravity(self, accel_g: tuple[float, float, float], dt: float) -> None:
        k = 1.0 if dt <= 0.0 else min(1.0, dt / self.params.accel_tau_s)
        d = self.down
        self.down = (
            d[0] + (accel_g[0] - d[0]) * k,
            d[1] + (accel_g[1] - d[1]) * k,
            d[2] + (accel_g[2] - d[2]) * k,
        )

    def _slope(self, dt: float) -> None:
        """Pull the error toward the heading the slope's line gives (module docstring)."""
        # The plane square to the yaw axis k: axes (k+1, k+2), a right-handed pair. A turn
        # of the body by +Δ about the axis turns what it sees of the slope's line by −Δ.
        k = self.axis
        a, b, up = self.down[(k + 1) % 3], self.down[(k + 2) % 3], self.down[k]
        tilt = math.atan2(math.hypot(a, b), self.sign * up)
        self.turned += self.reference_rad_s * dt
        k_lag = min(1.0, dt / self.params.accel_tau_s) if dt > 0.0 else 0.0
        self.lagged += (self.error_rad + self.turned - self.lagged) * k_lag
        if tilt < math.radians(self.params.slope_min_deg):
            self.toward = None  # the flat: nothing to go by
            return
        seen = self.sign * math.atan2(b, a)
        if self.toward is None:
            self.toward = seen + self.lagged  # from here on, as the gyroscope has it
        off = math.remainder(self.toward - seen - self.lagged, math.tau)  # turns past ±180°
        k_fix = dt / self.params.gravity_tau_s if dt > 0.0 else 0.0
        self.error_rad += off * min(1.0, k_fix)
