"""The coordinator's steady engines: the gait, riding, the hybrid gait (3.2.1, 5.4, 6.6).

The gait engine follows the phase table of the gait
(:mod:`whexar.kinematics.gait`): the cycle phase advances by dt/T, and a leg
whose own phase enters the swing lifts off, for (1 − β)·T, toward its
anterior extreme point AEP = n + ½·β·T·vᵢ, with n its neutral point and vᵢ
the velocity of the ground under it, v + ω ẑ × n. A stance foot is carried
by the body's twist, so the support feet agree at every instant, also while
the velocity ramps. The cycle time follows the speed, T = L / (β·max |vᵢ|),
within ``min_swing_s``/(1 − β) and ``max_cycle_s``; a faster command is
clamped to L = ``max_step_length_mm``. Before a lift-off, the static
stability margin of the feet that stay down is computed (CoG over the body
centre); below ``min_stability_margin_mm`` the leg waits with every foot down
and the body slows (:class:`SwingDelayed`). A gait starts with its stance
feet where its phase table has them.

Riding steers each wheel along v + ω × r (eq. 5.8–5.18), aligned before the
wheels turn; a change of the wheels' headings goes through zero speed. The
hybrid gait steps the legs at a share of the speed while the wheels drive
the rest, each wheel stopping just before its leg lifts.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Final

from whexar.actors.locomotion.core import GAIT_START, STILL
from whexar.actors.locomotion.scripts import Scripts
from whexar.actors.messages import CommandClamped, SwingDelayed, Vec3
from whexar.kinematics.gait import Gait
from whexar.robot import N_LEGS

WHEEL_LEAD_S: Final = 0.1
"""Hybrid gait: a leg's wheel stops this long before the leg lifts."""


def ramp(value: float, target: float, step: float) -> float:
    """``value`` moved toward ``target`` by at most ``step``."""
    if target > value + step:
        return value + step
    if target < value - step:
        return value - step
    return target


class Engines(Scripts):
    """The steady engines and the limits of what they may do (module docstring)."""

    # ----------------------------------------------------------------- limits

    def _gait_limits(self, gait: Gait) -> tuple[float, float]:
        """(shortest cycle, fastest foot speed over the ground) of ``gait``."""
        beta = gait.duty_factor
        t_min = self.loco.min_swing_s / (1.0 - beta)
        return t_min, self.max_step() / (beta * t_min)

    def _foot_speeds(self, twist: tuple[float, float, float]) -> list[float]:
        vx, vy, w = twist
        return [math.hypot(vx - w * n[1], vy + w * n[0]) for n in self.neutral_points]

    def _limit_walk(self, twist: tuple[float, float, float]) -> tuple[float, float, float]:
        _, v_max = self._gait_limits(self.gait)
        return self._scaled(
            twist,
            v_max,
            lambda: (
                f"the {self.gait.name} gait's fastest foot: max_step_length_mm in the "
                "shortest cycle (min_swing_s)"
            ),
        )

    def _limit_ride(self, twist: tuple[float, float, float]) -> tuple[float, float, float]:
        # The fastest wheel: the configured top speed, or what the wheel servo's Velocity
        # Limit (44) turns the wheel at, whichever is lower; beyond it the bus would clamp.
        wheel_max = self.wheel_rate_max * self.geometry.wheel_radius
        v_max = min(self.loco.ride_max_speed_m_s, wheel_max)
        return self._scaled(
            twist,
            v_max,
            lambda: (
                "locomotion.ride_max_speed_m_s (6.5.1)"
                if v_max == self.loco.ride_max_speed_m_s
                else "the wheel servo's Velocity Limit"
            ),
        )

    def _scaled(
        self, twist: tuple[float, float, float], v_max: float, why: Callable[[], str]
    ) -> tuple[float, float, float]:
        """``twist`` scaled down so that no foot (or wheel) moves faster than ``v_max`` over
        the ground; said once per command (:class:`CommandClamped`), with the reason ``why``
        gives (made only then)."""
        fastest = max(self._foot_speeds(twist), default=0.0)
        if fastest <= v_max:
            return twist
        if not self.clamp_said:
            self.clamp_said = True
            self.say(
                CommandClamped(
                    t=self.t,
                    source=self.name,
                    field="speed",
                    requested=fastest,
                    applied=v_max,
                    reason=why(),
                )
            )
        k = v_max / fastest
        return twist[0] * k, twist[1] * k, twist[2] * k

    def _ramp_twist(
        self, current: tuple[float, float, float], target: tuple[float, float, float], dt: float
    ) -> tuple[float, float, float]:
        a = self.loco.max_accel_m_s2 * dt
        ay = math.radians(self.loco.max_yaw_accel_deg_s2) * dt
        return (
            ramp(current[0], target[0], a),
            ramp(current[1], target[1], a),
            ramp(current[2], target[2], ay),
        )

    # ----------------------------------------------------------------- engines

    def _gait_tick(self, dt: float, hybrid: bool) -> None:
        loco = self.loco
        beta = self.gait.duty_factor
        target = (0.0, 0.0, 0.0) if self.winding_down or self.delayed else self.asked_twist()
        if hybrid:
            share = loco.hybrid_wheel_share
            legs_target = (
                target[0] * (1 - share),
                target[1] * (1 - share),
                target[2] * (1 - share),
            )
            wheels_target = (target[0] * share, target[1] * share, target[2] * share)
        else:
            legs_target, wheels_target = target, (0.0, 0.0, 0.0)
        legs_target = self._limit_walk(legs_target)
        self.leg_twist = self._ramp_twist(self.leg_twist, legs_target, dt)
        if hybrid:
            wheels_target = self._limit_ride(wheels_target)
            self.wheel_twist = self._ramp_twist(self.wheel_twist, wheels_target, dt)
        # The cycle follows the wanted speed, not the ramp: a swing planned now lasts
        # (1 − β)·T while the phase advances at the same T (steps grow with the ramp).
        fastest = max(self._foot_speeds(legs_target))
        t_min, _ = self._gait_limits(self.gait)
        if fastest > STILL:
            step = min(self.want.step_length, self.max_step())
            self.cycle_s = min(max(step / (beta * fastest), t_min), loco.max_cycle_s)
        moving = fastest > STILL or any(abs(v) > STILL for v in self.leg_twist)
        # A swing ending within this cycle counts as down: the tripod's groups hand over
        # at one phase, and the bus cycle is the resolution of "at once".
        landing = self.t + dt
        swinging = [landing < self.swing_until[i] for i in range(N_LEGS)]
        if not moving or self.winding_down:
            if not any(swinging):
                self.phase_running = False
                self.delayed = False  # at rest: the next start places the feet anew
            self._wheels_hybrid(hybrid, swinging)
            return
        starting = not self.phase_running
        if starting and self._prepare_start(legs_target):
            return  # feet first: a script places them where the gait's phase wants them
        self.phase_running = True
        new_phase = self.phase + dt / self.cycle_s
        swing_part = self.gait.swing_fraction
        lifts: list[int] = []
        durations: dict[int, float] = {}
        riders = self.riders
        for i in range(N_LEGS):
            if swinging[i] or i in riders:
                continue
            # A leg lifts when its own phase wraps past 0, the start of its swing (gait.py);
            # at a start, a leg the table has in mid-swing lifts for what is left of it.
            offset = self.gait.offsets[i]
            psi = (new_phase - offset) % 1.0
            if psi < (self.phase - offset) % 1.0 or (starting and psi < swing_part - 1e-9):
                lifts.append(i)
                durations[i] = (swing_part - psi) * self.cycle_s
        if lifts:
            down = [i for i in range(N_LEGS) if not swinging[i] and i not in lifts]
            margin = self.margin(down)
            minimum = loco.min_stability_margin_mm / 1000
            if margin < minimum:
                if not self.delayed:
                    self.say(
                        SwingDelayed(
                            t=self.t,
                            source=self.name,
                            legs=tuple(lifts),
                            margin_m=margin,
                            minimum_m=minimum,
                        )
                    )
                self.delayed = True
                return
            self.delayed = False
            # The anterior extreme point for the wanted twist, not the ramp's: a swing that
            # lifts while the body speeds up lands where the coming stance needs it.
            vx, vy, w = legs_target
            half = 0.5 * beta * self.cycle_s
            for i in lifts:
                n = self.neutral_points[i]
                target = (n[0] + half * (vx - w * n[1]), n[1] + half * (vy + w * n[0]), n[2])
                swing_s = max(durations[i], self.loco.min_swing_s / 2)
                self.swing_until[i] = self.t + swing_s
                swinging[i] = True
                self.send_step(i, "swing", swing_s, target, self.asked_step_height())
        self.delayed = False
        self.phase = new_phase % 1.0
        self._wheels_hybrid(hybrid, swinging)

    def _start_phase(self) -> float:
        """The cycle phase a gait starts from: just before one of its lift-offs, the one
        that leaves the legs the table has in mid-swing the most of their swing."""
        gait, part = self.gait, self.gait.swing_fraction
        best, best_left = GAIT_START, -1.0
        for start in sorted(set(gait.offsets)):
            left = 1.0
            for offset in gait.offsets:
                psi = (start - offset) % 1.0
                if 1e-9 < psi < part - 1e-9:
                    left = min(left, (part - psi) / part)
            if left > best_left + 1e-9:
                best, best_left = (start - 1e-9) % 1.0, left
        return best

    def _prepare_start(self, twist: tuple[float, float, float]) -> bool:
        """Before a gait starts: put each foot the table has on the ground where its phase
        says it is, so that it reaches its posterior extreme point when it lifts (its
        stance is centred on its neutral point), once every touchdown still awaited is
        judged (a gait's first swings would judge them in the air). Returns True when a
        script does it."""
        self.phase = self._start_phase()
        beta, period = self.gait.duty_factor, self.cycle_s
        part = self.gait.swing_fraction
        vx, vy, w = twist
        targets: list[Vec3] = []
        for i, n in enumerate(self.neutral_points):
            psi = (self.phase + 1e-9 - self.gait.offsets[i]) % 1.0
            if psi < part - 1e-9:
                targets.append(self.feet[i] or n)  # it lifts at once: it goes from anywhere
                continue
            k = period * (1.0 - beta / 2 - psi)
            targets.append((n[0] + k * (vx - w * n[1]), n[1] + k * (vy + w * n[0]), n[2]))
        legs = list(range(N_LEGS))
        if not self.awaiting(legs) and not any(self.away(i, targets[i]) for i in legs):
            return False
        self.leg_twist = (0.0, 0.0, 0.0)
        self.script = self.placed_for_start(targets)
        return True

    def _wheels_hybrid(self, hybrid: bool, swinging: list[bool]) -> None:
        if not hybrid:
            self.steer = False
            self._wheels_riders()
            return
        headings, wheel_speeds = self.wheels(self.contacts(), *self.wheel_twist)
        speeds = []
        for i in range(N_LEGS):
            psi = (self.phase - self.gait.offsets[i]) % 1.0
            soon = (1.0 - psi) * self.cycle_s < WHEEL_LEAD_S
            speeds.append(0.0 if swinging[i] or soon else wheel_speeds[i])
        self.steer = True
        self.speeds = tuple(speeds)
        if any(abs(v) > STILL for v in self.wheel_twist):
            self.headings = headings

    def _wheels_riders(self) -> None:
        """Walking: the riders' wheels (a lost coxa, :mod:`.losses`) roll their feet over
        the ground at the body's twist (eq. 5.17–5.18); every other wheel is held."""
        if not self.riders:
            self.speeds = (0.0,) * N_LEGS
            return
        headings, speeds = self.wheels(self.contacts(), *self.leg_twist)
        moving = any(abs(v) > STILL for v in self.leg_twist)
        self.speeds = tuple(v if i in self.riders else 0.0 for i, v in enumerate(speeds))
        if moving:  # standing still, a wheel keeps its heading
            self.headings = tuple(
                h if i in self.riders else old
                for i, (h, old) in enumerate(zip(headings, self.headings, strict=True))
            )

    def _ride_tick(self, dt: float) -> None:
        target = (0.0, 0.0, 0.0) if self.winding_down else self._limit_ride(self.asked_twist())
        contacts = self.contacts()
        if any(abs(v) > STILL for v in target):
            headings, _ = self.wheels(contacts, *target)
            tol = math.radians(self.loco.align_tolerance_deg)
            if max(abs(a - b) for a, b in zip(headings, self.headings, strict=True)) > tol:
                # New headings: through zero speed, then align, then on (5.4, 6.5.2).
                if all(abs(v) <= STILL for v in self.wheel_twist):
                    self.script = self.align(headings)
                    return
                target = (0.0, 0.0, 0.0)
            elif any(abs(v) > STILL for v in self.wheel_twist):
                # Within the tolerance (a wheel moved as its leg sagged): steer while rolling.
                self.headings = headings
        self.wheel_twist = self._ramp_twist(self.wheel_twist, target, dt)
        if any(abs(v) > STILL for v in self.wheel_twist):
            _, self.speeds = self.wheels(contacts, *self.wheel_twist)
        else:
            self.speeds = (0.0,) * N_LEGS
