"""The leg coordinator: gaits, riding, stances, the leg flip (Žák 2023, 4.2.5, 5.4, 6.3–6.8).

Theory of operation
-------------------
The coordinator wakes on every :class:`ServoStates`, like the legs, and each
control cycle

1. takes the commands that arrived (:class:`MotionCommand`): each field is
   checked against what the robot can do — clamped with a
   :class:`CommandClamped` event, or the whole command refused with a
   :class:`CommandRefused` — and becomes the *wanted* state;
2. ramps the body's velocity toward the wanted one (``max_accel_m_s2``);
3. runs what it is doing: a *script* (stand up, sit down, change stance,
   walk ↔ ride, flip) or a steady engine (the gait, riding, the hybrid gait);
4. publishes :class:`BodyMotion` (twist, pose, trochanter, wheels) for the
   legs, :class:`StepCommand` when a leg starts a swing, a stance or a move,
   and :class:`LocomotionState`.

Everything is planned in the *upright frame* (the body frame of a robot on
its feet, z up from the ground); upside down, the legs mirror it (6.8.1).

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
and the body slows (:class:`SwingDelayed`).

Changes that move feet run as scripts, each step waiting on time or on the
servos: a gait change, a stance change and walk ↔ ride first wind down (no
new lift-offs, the body stops, the swings land), then re-place the feet one
group at a time (each group's lift checked for stability), then resume.
Riding aligns the direction servos before the wheels turn and waits for the
wheels to stop before a leg lifts; a change of the wheels' headings goes
through zero speed. Standing up moves every leg in joint space from the pose
the servos report to the seated pose, then lifts the body to the stance;
sitting down lowers the body; a flip sits, turns the trochanters 180° and
stands up on the other side. On stop and on a safe stop the robot sits down
before the bus turns torque off, when servo states still arrive.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from itertools import chain
from typing import Final

import anyio
import numpy as np

from whexar.actors.messages import (
    BodyMotion,
    BodyTilt,
    CommandClamped,
    CommandRefused,
    LegState,
    LocomotionChanged,
    LocomotionState,
    MotionCommand,
    ServoStates,
    StepCommand,
    SwingDelayed,
    Vec3,
)
from whexar.bus import control_table as ct
from whexar.config import ConfigFile, RobotConfig, load_config
from whexar.errors import KinematicsError
from whexar.kinematics.body import Stance, body_to_leg, leg_to_body, stance_feet
from whexar.kinematics.gait import GAITS, TRIPOD, Gait
from whexar.kinematics.geometry import LegGeometry
from whexar.kinematics.leg import ik
from whexar.kinematics.wheels import wheel_twist
from whexar.robot import LEG_NAMES, N_LEGS
from whexar.runtime.actor import Actor, ActorParams, Input, Output

MODES: Final = ("walk", "ride", "hybrid")
MAX_TROCHANTER: Final = math.radians(45.0)
"""The trochanter follows the pitch up to this; IK needs it strictly inside ±90° (eq. 4.18)."""
GAIT_START: Final = 1.0 - 1e-9
"""Cycle phase a gait starts from: just before 0, so the legs at offset 0 lift first."""
PLACED_M: Final = 0.005
"""A foot within this of its target needs no re-placement."""
SETTLE_S: Final = 0.05
"""Margin after a commanded move before the next step of a script (a few bus cycles)."""
STILL: Final = 1e-6
"""|twist| below this is standing still."""
WHEEL_LEAD_S: Final = 0.1
"""Hybrid gait: a leg's wheel stops this long before the leg lifts."""
CONTACT_GRID_M: Final = 0.005
"""Measured feet are rounded to this grid before the wheels' kinematics use them."""
BUS_SILENT_S: Final = 0.2
"""No servo states for this long: the bus cannot carry out a sit-down any more."""
_WHEELS_KEY: Final = struct.Struct("<21d").pack
"""The key of :meth:`Coordinator._wheels`: a twist and six contact points, as bytes."""
_POSE_RATES: Final = (0.1, 0.1, 0.1, math.radians(20), math.radians(20), math.radians(20))
"""Body pose change per transition (m, rad): x, y, z, roll, pitch, yaw."""

Wait = Callable[[], bool]
Script = Iterator[Wait]


@dataclass
class _Want:
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


def workspace_step(stance: Stance, geometry: LegGeometry, longest: float, height: float) -> float:
    """The longest step, at most ``longest``, every leg of ``stance`` can take in any
    direction with its foot ``height`` up at mid-swing (IK within the joint limits)."""
    feet = stance_feet(stance)  # leg frames: x outward, y down, z forward
    length = longest
    while length > 0.01:
        half = length / 2
        offsets = [(half, 0, 0), (-half, 0, 0), (0, 0, half), (0, 0, -half), (0, -height, 0)]
        points = np.array([f + np.array(o) for f in feet for o in offsets])
        try:
            ik(points, geometry, target="contact")
            return length
        except KinematicsError:
            length -= 0.005
    return 0.01


def support_margin(points: list[tuple[float, float]], cog: tuple[float, float]) -> float:
    """Signed static stability margin (m), as
    :func:`~whexar.kinematics.stability.static_stability_margin` computes it, in plain Python:
    the coordinator asks every cycle, for at most six points, where numpy's call overhead is
    most of the cost. Fewer than three supports: −∞."""
    if len(points) < 3:
        return -math.inf
    pts = sorted(set(points))
    lower: list[tuple[float, float]] = []
    for q in pts:
        while len(lower) >= 2 and _cross(lower[-2], lower[-1], q) <= 0:
            lower.pop()
        lower.append(q)
    upper: list[tuple[float, float]] = []
    for q in reversed(pts):
        while len(upper) >= 2 and _cross(upper[-2], upper[-1], q) <= 0:
            upper.pop()
        upper.append(q)
    hull = lower[:-1] + upper[:-1]  # counter-clockwise
    cx, cy = cog
    best = math.inf
    inside = len(hull) >= 3
    # min(max(u, 0), 1) and min(best, d) as comparisons: the same results, no calls.
    for (ax, ay), (bx, by) in zip(hull, hull[1:] + hull[:1], strict=True):
        ex, ey = bx - ax, by - ay
        length2 = ex * ex + ey * ey
        u = 0.0 if length2 == 0 else ((cx - ax) * ex + (cy - ay) * ey) / length2
        u = 0.0 if u < 0.0 else 1.0 if u > 1.0 else u
        d = math.hypot(cx - ax - u * ex, cy - ay - u * ey)
        if d < best:
            best = d
        if ex * (cy - ay) - ey * (cx - ax) < 0.0:
            inside = False
    return best if inside else -best


def _cross(o: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def _velocity_limit(model: str) -> float:
    """The Velocity Limit (44) a servo of ``model`` starts with, rad/s (e-manual)."""
    return ct.velocity_to_rad_s(ct.model(model).register("velocity_limit").initial or 0)


def _ramp(value: float, target: float, step: float) -> float:
    if target > value + step:
        return value + step
    if target < value - step:
        return value - step
    return target


class Coordinator(Actor):
    """Synchronises the six legs: gaits, riding, stances, transitions (module docstring)."""

    class Params(ActorParams):
        config: ConfigFile | None = None
        """Robot configuration file; absent: the built-in defaults."""

    params: Params
    servo_state = Input(ServoStates)
    commands = Input(MotionCommand, optional=True)
    legs = Input(LegState, optional=True)
    tilt = Input(BodyTilt, optional=True)
    steps = Output(StepCommand)
    motion = Output(BodyMotion)
    state = Output(LocomotionState, optional=True)

    # ----------------------------------------------------------------- set-up

    def _setup(self) -> None:
        p = self.params
        self.cfg: RobotConfig = load_config(p.config) if p.config else RobotConfig()
        loco = self.loco = self.cfg.locomotion
        self.geometry = self.cfg.leg_geometry()
        self.want = _Want(
            gait=loco.gait,
            stance=loco.stance,
            step_height=loco.step_height_mm / 1000,
            step_length=loco.step_length_mm / 1000,
        )
        self.gait: Gait = GAITS[loco.gait]
        self.stance_name = loco.stance
        self.mode = "walk"
        self.upside_down = False
        self.activity = "standing_up"
        self.leg_twist = (0.0, 0.0, 0.0)
        self.wheel_twist = (0.0, 0.0, 0.0)
        self.headings: tuple[float, ...] = (0.0,) * N_LEGS
        self.speeds: tuple[float, ...] = (0.0,) * N_LEGS
        self.steer = False
        self.phase = GAIT_START
        self.cycle_s = loco.max_cycle_s
        self.tilt_pitch = 0.0
        self.tilt_measured = 0.0
        self.dt = 0.0
        self.swing_until = [-math.inf] * N_LEGS
        self.feet: list[Vec3 | None] = [None] * N_LEGS
        self.measured_feet: list[Vec3 | None] = [None] * N_LEGS
        """Where each leg's foot is: its present angles' forward kinematics (:meth:`_contacts`)."""
        self.wheel_measured: list[float | None] = [None] * N_LEGS
        self.direction_measured: list[float | None] = [None] * N_LEGS
        self.coxa_measured: list[float | None] = [None] * N_LEGS
        self.t = 0.0
        self.last_t: float | None = None
        self.last_states_t = -math.inf
        self.cycle = 0
        self.height = self._stance(self.stance_name).height
        self.script: Script | None = None
        self.stopping = False
        """A safe stop is under way: the robot sits down and takes no more commands."""
        self.wait: Wait | None = None
        self.winding_down = False
        self.delayed = False
        self.margin = math.inf
        self.neutral_points: list[Vec3] = self.neutral(self._stance(self.stance_name))
        self.pose_now: tuple[float, ...] = (0.0,) * 6
        self._pending_moves: list[tuple[int, Vec3, float]] = []
        self._pending_duration = 0.0
        self._clamp_said = False
        self.phase_running = False
        self._workspace: dict[tuple[str, bool], float] = {}
        joints = self.cfg.joints
        self.wheel_rate_max = _velocity_limit(joints.by_name("wheel").model)
        self.direction_rate_max = _velocity_limit(joints.by_name("direction").model)
        self._wheels_key = b""
        self._wheels_said: tuple[tuple[float, ...], tuple[float, ...]] = ((), ())
        # Looked up once, not every cycle: a port attribute is a descriptor and a mapping
        # lookup. An optional input or output the wiring left unconnected is None here.
        self.commands_in = self.commands if self.commands.connected else None
        self.legs_in = self.legs if self.legs.connected else None
        self.tilt_in = self.tilt if self.tilt.connected else None
        self.steps_out = self.steps
        self.motion_out = self.motion
        self.state_out = self.state if self.state.connected else None

    def _stance(self, name: str) -> Stance:
        return self.cfg.stance(name)

    def neutral(self, stance: Stance, height: float | None = None) -> list[Vec3]:
        """The six neutral foot points of ``stance`` in the upright frame (mirrored flipped)."""
        feet = leg_to_body(stance_feet(stance), self.geometry)
        h = stance.height if height is None else height
        sign = -1.0 if self.upside_down else 1.0
        return [(float(f[0]), sign * float(f[1]), -h) for f in feet]

    # ----------------------------------------------------------------- commands

    def _clamped(self, field: str, requested: float, applied: float, reason: str) -> None:
        self.emit(
            CommandClamped(
                t=self.t,
                source=self.name,
                field=field,
                requested=requested,
                applied=applied,
                reason=reason,
            )
        )

    def _refuse(self, cmd: MotionCommand, reason: str) -> None:
        fields = {
            k: v
            for k in cmd.__dataclass_fields__
            if k not in ("t", "source") and (v := getattr(cmd, k)) not in (None, False)
        }
        self.emit(CommandRefused(t=self.t, source=self.name, command=repr(fields), reason=reason))

    def _command(self, cmd: MotionCommand) -> None:
        """Check one command and make it the wanted state, or refuse it whole."""
        w = self.want
        loco = self.loco
        for key in (
            "vx_m_s",
            "vy_m_s",
            "yaw_rate_rad_s",
            "turn_radius_m",
            "step_height_m",
            "step_length_m",
            "body_height_m",
            "roll_rad",
            "pitch_rad",
        ):
            value = getattr(cmd, key)
            if value is not None and not (isinstance(value, int | float) and math.isfinite(value)):
                self._refuse(cmd, f"{key} = {value!r}: not a finite number")
                return
        if cmd.gait is not None and cmd.gait not in GAITS:
            self._refuse(cmd, f"unknown gait {cmd.gait!r}; allowed: {', '.join(GAITS)}")
            return
        if cmd.mode is not None and cmd.mode not in MODES:
            self._refuse(cmd, f"unknown mode {cmd.mode!r}; allowed: {', '.join(MODES)}")
            return
        if cmd.stance is not None and cmd.stance not in self.cfg.stances:
            allowed = ", ".join(sorted(self.cfg.stances))
            self._refuse(cmd, f"unknown stance {cmd.stance!r}; allowed: {allowed}")
            return
        upside = w.upside_down if cmd.upside_down is None else cmd.upside_down
        mode = cmd.mode or w.mode
        if upside and mode != "walk":
            self._refuse(cmd, "upside down the robot walks: its wheels face the sky (6.8.1)")
            return
        radius = cmd.turn_radius_m
        if radius is not None:
            inner = loco.min_turn_radius_mm / 1000
            if abs(radius) < inner:
                self._refuse(
                    cmd,
                    f"turn_radius_m = {radius:g}: inside the body; allowed: |R| ≥ {inner:g} m "
                    "(spin in place with yaw_rate_rad_s instead)",
                )
                return
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
            w.step_height = self._limit(
                "step_height_m",
                cmd.step_height_m,
                0.0,
                loco.max_step_height_mm / 1000,
                "0 … locomotion.max_step_height_mm",
            )
        if cmd.step_length_m is not None:
            w.step_length = self._limit(
                "step_length_m",
                cmd.step_length_m,
                0.01,
                loco.max_step_length_mm / 1000,
                "0.01 m … locomotion.max_step_length_mm (the workspace)",
            )
        if cmd.body_height_m is not None:
            low = loco.sit_height_mm / 1000
            high = max(s.height_mm for s in self.cfg.stances.values()) / 1000
            w.body_height = self._limit(
                "body_height_m",
                cmd.body_height_m,
                low,
                high,
                "the seated height … the highest stance",
            )
        limit = math.radians(20.0)
        if cmd.roll_rad is not None:
            w.roll = self._limit("roll_rad", cmd.roll_rad, -limit, limit, "±20° of body roll")
        if cmd.pitch_rad is not None:
            w.pitch = self._limit("pitch_rad", cmd.pitch_rad, -limit, limit, "±20° of body pitch")

    def _limit(self, field: str, value: float, lo: float, hi: float, why: str) -> float:
        applied = min(max(value, lo), hi)
        if applied != value:
            self._clamped(field, value, applied, why)
        return applied

    # ----------------------------------------------------------------- the wanted motion

    def _wanted_twist(self) -> tuple[float, float, float]:
        """The wanted body twist in the upright frame, the turn radius resolved."""
        w = self.want
        if w.radius is not None:
            return w.vx, 0.0, w.vx / w.radius
        return w.vx, w.vy, w.yaw

    def _gait_limits(self, gait: Gait) -> tuple[float, float]:
        """(shortest cycle, fastest foot speed over the ground) of ``gait``."""
        beta = gait.duty_factor
        t_min = self.loco.min_swing_s / (1.0 - beta)
        return t_min, self._max_step() / (beta * t_min)

    def _max_step(self) -> float:
        """The longest step the present stance's workspace allows (cached per stance)."""
        key = (self.stance_name, self.upside_down)
        found = self._workspace.get(key)
        if found is None:
            found = self._workspace[key] = workspace_step(
                self.cfg.stance(self.stance_name),
                self.geometry,
                self.loco.max_step_length_mm / 1000,
                self.loco.max_step_height_mm / 1000,
            )
        return found

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
        if not self._clamp_said:
            self._clamp_said = True
            self._clamped("speed", fastest, v_max, why())
        k = v_max / fastest
        return twist[0] * k, twist[1] * k, twist[2] * k

    def _ramp_twist(
        self, current: tuple[float, float, float], target: tuple[float, float, float], dt: float
    ) -> tuple[float, float, float]:
        a = self.loco.max_accel_m_s2 * dt
        ay = math.radians(self.loco.max_yaw_accel_deg_s2) * dt
        return (
            _ramp(current[0], target[0], a),
            _ramp(current[1], target[1], a),
            _ramp(current[2], target[2], ay),
        )

    # ----------------------------------------------------------------- inputs

    def _take_states(self, states: ServoStates) -> None:
        wheel, direction, coxa = self.wheel_measured, self.direction_measured, self.coxa_measured
        for j in states.joints:
            joint = j.joint
            if joint == 6:
                wheel[j.leg] = j.velocity_rad_s
            elif joint == 5:
                direction[j.leg] = j.position_rad
            elif joint == 0:
                coxa[j.leg] = j.position_rad

    def _take_tilt(self, dt: float) -> None:
        """The measured pitch, low-passed: the trochanters follow a slope, not the shakes of
        each step (an accelerometer reads the body's accelerations as tilt too)."""
        if self.tilt_in is None:
            return
        tilt = self.tilt_in.latest()
        if tilt is not None:
            self.tilt_measured = tilt.pitch_rad
        k = min(1.0, dt / self.loco.tilt_filter_s)
        self.tilt_pitch += (self.tilt_measured - self.tilt_pitch) * k

    def _take_legs(self) -> None:
        if self.legs_in is not None:
            for s in self.legs_in.drain():
                self.feet[s.leg] = s.foot
                m = s.measured_foot
                if m is not None:  # on a grid: a command changes when a wheel moved, not with noise
                    g = CONTACT_GRID_M
                    self.measured_feet[s.leg] = (
                        round(m[0] / g) * g,
                        round(m[1] / g) * g,
                        round(m[2] / g) * g,
                    )

    # ----------------------------------------------------------------- steps

    async def _send(
        self, leg: int, kind: str, duration: float, target: Vec3, height: float = 0.0
    ) -> None:
        await self.steps_out.send(
            StepCommand(
                t=self.t,
                source=self.name,
                leg=leg,
                kind=kind,
                start_t=self.t,
                duration_s=duration,
                target=target,
                height_m=height,
                trajectory=self.loco.trajectory,
                duty_factor=self.gait.duty_factor,
            )
        )

    def _margin(self, down: list[int]) -> float:
        feet, neutral = self.feet, self.neutral_points
        points = [(p[0], p[1]) for p in (feet[i] or neutral[i] for i in down)]
        return support_margin(points, (self.pose_now[0], self.pose_now[1]))

    def _set_activity(self, activity: str) -> None:
        if activity != self.activity:
            self._changed("activity", self.activity, activity)
            self.activity = activity

    def _changed(self, what: str, before: str, after: str) -> None:
        self.emit(
            LocomotionChanged(t=self.t, source=self.name, what=what, before=before, after=after)
        )

    # ----------------------------------------------------------------- scripts

    def _after(self, seconds: float) -> Wait:
        until = self.t + seconds
        return lambda: self.t >= until

    def _move_all(self, targets: list[Vec3], height: float = 0.0) -> list[tuple[int, Vec3, float]]:
        return [(i, targets[i], height) for i in range(N_LEGS)]

    def _script_moves(self, moves: list[tuple[int, Vec3, float]], duration: float) -> Script:
        pending = list(moves)
        self._pending_moves = pending
        self._pending_duration = duration
        yield lambda: not self._pending_moves
        yield self._after(duration + SETTLE_S)

    def _replace(self, targets: list[Vec3], height: float, duration: float) -> Script:
        """Re-place the feet that are not at ``targets``, a tripod group at a time, lifting
        each; one leg at a time where a group's lift would leave too small a margin."""
        groups = list(TRIPOD.groups)
        for group in groups:
            legs = [LEG_NAMES.index(name) for name in group]
            legs = [i for i in legs if self._away(i, targets[i])]
            if not legs:
                continue
            down = [i for i in range(N_LEGS) if i not in legs]
            if self._margin(down) < self.loco.min_stability_margin_mm / 1000:
                # The group together is not safe: one leg at a time.
                for i in legs:
                    yield from self._script_moves([(i, targets[i], height)], duration)
                continue
            yield from self._script_moves([(i, targets[i], height) for i in legs], duration)

    def _replace_s(self) -> float:
        """A re-placing step: as long as the slowest swing the tripod makes at full speed."""
        return max(self.loco.min_swing_s, 0.5 * self.loco.transition_s)

    def _away(self, leg: int, target: Vec3) -> bool:
        foot = self.feet[leg]
        if foot is None:
            return True
        return math.dist(foot, target) > PLACED_M

    def _stand_up(self) -> Script:
        self._set_activity("standing_up")
        stance = self._stance(self.stance_name)
        seated = self.neutral(stance, self.loco.sit_height_mm / 1000)
        half = self.loco.stand_up_s / 2
        yield from self._script_moves(self._move_all(seated), half)
        self.height = stance.height
        yield from self._script_moves(self._move_all(self.neutral(stance)), half)
        self._set_activity("standing")

    def _sit_down(self) -> Script:
        self._set_activity("sitting_down")
        feet = [
            f if f is not None else n for f, n in zip(self.feet, self.neutral_points, strict=True)
        ]
        low = -self.loco.sit_height_mm / 1000
        targets = [(f[0], f[1], low) for f in feet]
        yield from self._script_moves(self._move_all(targets), self.loco.sit_down_s)
        self._set_activity("seated")

    def _change_stance(self, name: str, mode: str) -> Script:
        self._set_activity("transition")
        stance = self._stance(name)
        before = self.stance_name
        step, replace_s = self.want.step_height, self._replace_s()
        new_points = self.neutral(stance)
        beside = [(n[0], n[1], -self.height) for n in new_points]
        if self._reachable(beside):
            # The new reach at the present height, then every foot together to the new
            # height (the body rises or sinks). Never the height first: walking may have
            # left a foot half a step off, where the new height may not reach.
            yield from self._replace(beside, step, replace_s)
            yield from self._to_height(stance.height)
        else:
            # The new reach needs the new height: feet to their neutral points, the
            # height, then the new reach.
            yield from self._replace(self.neutral_points, step, replace_s)
            yield from self._to_height(stance.height)
            self.neutral_points = new_points
            yield from self._replace(new_points, step, replace_s)
        self.stance_name = name
        self.neutral_points = new_points
        if before != name:
            self._changed("stance", before, name)
        if mode != self.mode:
            self._changed("mode", self.mode, mode)
            self.mode = mode
        self._set_activity("standing")

    def _to_height(self, height: float) -> Script:
        """Every foot together to ``height`` below the coxa joints: the body rises or sinks."""
        if abs(height - self.height) <= PLACED_M:
            return
        feet = [f or n for f, n in zip(self.feet, self.neutral_points, strict=True)]
        self.height = height
        targets = [(f[0], f[1], -height) for f in feet]
        yield from self._script_moves(self._move_all(targets), self.loco.transition_s)

    def _reachable(self, points: list[Vec3]) -> bool:
        """Whether every leg reaches its point (upright frame) within its joint limits."""
        sign = -1.0 if self.upside_down else 1.0  # a flipped leg is the mirrored one (6.8.1)
        body = np.array([(p[0], sign * p[1], p[2]) for p in points])
        try:
            ik(body_to_leg(body, self.geometry), self.geometry, target="contact")
        except KinematicsError:
            return False
        return True

    def _flip(self) -> Script:
        yield from self._sit_down()
        self._set_activity("flipping")
        before = self.upside_down
        self.upside_down = not before
        yield self._after(self.loco.flip_s + SETTLE_S)
        self.neutral_points = self.neutral(self._stance(self.stance_name))
        self.feet = [None if f is None else (f[0], -f[1], f[2]) for f in self.feet]
        self.measured_feet = [None] * N_LEGS  # until the legs say where they are now
        self._changed("upside_down", str(before), str(self.upside_down))
        stance = self._stance(self.stance_name)
        self.height = stance.height
        yield from self._script_moves(self._move_all(self.neutral(stance)), self.loco.stand_up_s)
        self._set_activity("standing")

    def _align(self, headings: tuple[float, ...]) -> Script:
        """Direction servos to ``headings`` with the wheels held, then wait until they are there."""
        self._set_activity("transition")
        previous, was_steering = self.headings, self.steer
        self.steer = True
        self.headings = headings
        self.speeds = (0.0,) * N_LEGS
        tol = math.radians(self.loco.align_tolerance_deg)
        deadline = self.t + self.loco.align_timeout_s
        # Where the read plan does not read the direction servos, wait as long as the
        # largest turn takes at their Velocity Limit.
        turn = 0.0
        for i in range(N_LEGS):
            side, coxa = (1.0 if i % 2 == 0 else -1.0), self.coxa_measured[i] or 0.0
            before = side * previous[i] - coxa if was_steering else 0.0
            turn = max(turn, abs(side * headings[i] - coxa - before))
        blind = self.t + turn / self.direction_rate_max + 2 * SETTLE_S

        def aligned() -> bool:
            if self.t >= deadline:
                return True
            for i in range(N_LEGS):
                d, c, foot = self.direction_measured[i], self.coxa_measured[i], self.feet[i]
                if d is None:
                    return self.t >= blind
                if c is None or foot is None:
                    return False
                side = 1.0 if i % 2 == 0 else -1.0
                want = (side * headings[i] - c + math.pi) % (2 * math.pi) - math.pi
                if abs((d - want + math.pi) % (2 * math.pi) - math.pi) > tol:
                    return False
            return True

        yield self._after(2 * SETTLE_S)
        yield aligned

    def _enter_hybrid(self, stance: str) -> Script:
        """The hybrid gait's stance, then the wheels aligned with the way the wheels will
        drive before any of them turns (as for riding, 5.4)."""
        yield from self._change_stance(stance, "hybrid")
        share = self.loco.hybrid_wheel_share
        vx, vy, w = (v * share for v in self._wanted_twist())
        if any(abs(v) > STILL for v in (vx, vy, w)):
            cmd = wheel_twist(self._contacts(), vx, vy, w, wheel_radius=self.geometry.wheel_radius)
            yield from self._align(tuple(float(h) for h in cmd.heading))
        self._set_activity("standing")

    def _wheels_stopped(self) -> bool:
        stop = self.loco.wheel_stop_speed_m_s / self.geometry.wheel_radius
        return all(v is None or abs(v) <= stop for v in self.wheel_measured)

    # ----------------------------------------------------------------- engines

    async def _gait_tick(self, dt: float, hybrid: bool) -> None:
        loco = self.loco
        beta = self.gait.duty_factor
        target = (0.0, 0.0, 0.0) if self.winding_down or self.delayed else self._wanted_twist()
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
            step = min(self.want.step_length, self._max_step())
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
            await self._wheels_hybrid(hybrid, swinging)
            return
        starting = not self.phase_running
        if starting and self._prepare_start(legs_target):
            return  # feet first: a script places them where the gait's phase wants them
        self.phase_running = True
        new_phase = self.phase + dt / self.cycle_s
        swing_part = self.gait.swing_fraction
        lifts: list[int] = []
        durations: dict[int, float] = {}
        for i in range(N_LEGS):
            if swinging[i]:
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
            margin = self._margin(down)
            minimum = loco.min_stability_margin_mm / 1000
            if margin < minimum:
                if not self.delayed:
                    self.emit(
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
                await self._send(i, "swing", swing_s, target, self.want.step_height)
        self.delayed = False
        self.phase = new_phase % 1.0
        await self._wheels_hybrid(hybrid, swinging)

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
        stance is centred on its neutral point). Returns True when a script does it."""
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
        if not any(self._away(i, targets[i]) for i in range(N_LEGS)):
            return False
        self.leg_twist = (0.0, 0.0, 0.0)
        self.script = self._placed_for_start(targets)
        return True

    def _placed_for_start(self, targets: list[Vec3]) -> Script:
        activity = self.activity
        self._set_activity("transition")
        yield from self._replace(targets, self.want.step_height, self._replace_s())
        self._set_activity(activity if activity != "transition" else "standing")

    async def _wheels_hybrid(self, hybrid: bool, swinging: list[bool]) -> None:
        if not hybrid:
            self.steer = False
            self.speeds = (0.0,) * N_LEGS
            return
        headings, wheel_speeds = self._wheels(self._contacts(), *self.wheel_twist)
        speeds = []
        for i in range(N_LEGS):
            psi = (self.phase - self.gait.offsets[i]) % 1.0
            soon = (1.0 - psi) * self.cycle_s < WHEEL_LEAD_S
            speeds.append(0.0 if swinging[i] or soon else wheel_speeds[i])
        self.steer = True
        self.speeds = tuple(speeds)
        if any(abs(v) > STILL for v in self.wheel_twist):
            self.headings = headings

    def _wheels(
        self, contacts: list[Vec3], vx: float, vy: float, w: float
    ) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """(headings, speeds) of :func:`wheel_twist` for ``contacts``, remembered for the next
        call: riding asks the same of feet that stand still every cycle. The key is the
        floats' bytes, so that 0.0 and −0.0 (which atan2 tells apart) differ."""
        key = _WHEELS_KEY(vx, vy, w, *chain.from_iterable(contacts))
        if key != self._wheels_key:
            cmd = wheel_twist(contacts, vx, vy, w, wheel_radius=self.geometry.wheel_radius)
            self._wheels_said = (tuple(cmd.heading.tolist()), tuple(cmd.speed.tolist()))
            self._wheels_key = key
        return self._wheels_said

    def _contacts(self) -> list[Vec3]:
        """Where the wheels touch the ground, for their headings and speeds: each leg's
        measured foot, else its commanded one, else its neutral point.

        The measured foot, not the commanded: under the body's weight a leg sags, its
        servos holding a position error (in the simulation the tibia and tarsus stand 4–5°
        below their goals, the foot 3 cm inward). Speeds computed for the commanded feet
        then disagree, on a turn, with the wheels' real distances from the centre of
        rotation, and the wheels scrub against each other through the legs (thesis 6.5.2:
        "tension on the inner legs"): on a 0.6 m circle the servos drew 17.7 A with the
        commanded feet, 10.4 A with the measured ones (6.6 A riding straight)."""
        return [
            m if m is not None else f if f is not None else n
            for m, f, n in zip(self.measured_feet, self.feet, self.neutral_points, strict=True)
        ]

    def _ride_tick(self, dt: float) -> None:
        target = (0.0, 0.0, 0.0) if self.winding_down else self._limit_ride(self._wanted_twist())
        contacts = self._contacts()
        if any(abs(v) > STILL for v in target):
            headings, _ = self._wheels(contacts, *target)
            tol = math.radians(self.loco.align_tolerance_deg)
            if max(abs(a - b) for a, b in zip(headings, self.headings, strict=True)) > tol:
                # New headings: through zero speed, then align, then on (5.4, 6.5.2).
                if all(abs(v) <= STILL for v in self.wheel_twist):
                    self.script = self._align(headings)
                    return
                target = (0.0, 0.0, 0.0)
            elif any(abs(v) > STILL for v in self.wheel_twist):
                # Within the tolerance (a wheel moved as its leg sagged): steer while rolling.
                self.headings = headings
        self.wheel_twist = self._ramp_twist(self.wheel_twist, target, dt)
        if any(abs(v) > STILL for v in self.wheel_twist):
            _, self.speeds = self._wheels(contacts, *self.wheel_twist)
        else:
            self.speeds = (0.0,) * N_LEGS

    # ----------------------------------------------------------------- what next

    def _next_script(self) -> Script | None:
        """The wanted state differs from the present one: the script that bridges them."""
        w = self.want
        needs_rest = (
            w.upside_down != self.upside_down
            or w.mode != self.mode
            or (w.gait != self.gait.name and self.mode == w.mode == "walk")
            or (w.stance != self.stance_name and w.mode != "ride")
            or w.stop
        )
        if not needs_rest:
            self.winding_down = False
            return None
        # Wind down: no lift-offs, the body stops, the swings land, the wheels stop.
        self.winding_down = True
        still = all(abs(v) <= STILL for v in (*self.leg_twist, *self.wheel_twist))
        swinging = any(self.t < u for u in self.swing_until)
        if not still or swinging or not self._wheels_stopped():
            return None
        self.winding_down = False
        if w.upside_down != self.upside_down:
            self.steer = False
            return self._flip()
        if w.gait != self.gait.name and self.mode == w.mode == "walk":
            before = self.gait.name
            self.gait = GAITS[w.gait]
            self._changed("gait", before, w.gait)
            return None  # the next start places the feet for the new gait
        if w.mode != self.mode:
            self.steer = False
            stance = self.loco.ride_stance if w.mode == "ride" else w.stance
            if w.mode == "hybrid" and self.gait.name != self.loco.hybrid_gait:
                before = self.gait.name
                self.gait = GAITS[self.loco.hybrid_gait]
                self._changed("gait", before, self.gait.name)
            if w.mode == "walk" and self.gait.name != w.gait:
                before = self.gait.name
                self.gait = GAITS[w.gait]
                self._changed("gait", before, self.gait.name)
            if w.mode == "hybrid":
                return self._enter_hybrid(stance)
            return self._change_stance(stance, w.mode)
        if w.stop:
            w.stop = False
            if any(self._away(i, self.neutral_points[i]) for i in range(N_LEGS)):
                return self._replace(self.neutral_points, w.step_height, self._replace_s())
            return None
        if w.stance != self.stance_name:
            return self._change_stance(w.stance, self.mode)
        return None

    # ----------------------------------------------------------------- the cycle

    async def _tick(self, states: ServoStates) -> None:
        self.t = t = states.t
        dt = 0.0 if self.last_t is None else t - self.last_t
        self.dt = dt
        self.last_t = t
        self.last_states_t = t
        self.cycle = states.cycle
        self._take_states(states)
        self._take_legs()
        self._take_tilt(dt)
        if self.commands_in is not None:
            for cmd in self.commands_in.drain():
                if self.stopping:
                    self._refuse(cmd, "a safe stop is under way")
                    continue
                self._clamp_said = False
                self._command(cmd)
        # Scripts first: while one runs, nothing else moves the feet.
        if self.script is None and self.activity not in ("standing_up", "sitting_down", "seated"):
            self.script = self._next_script()
        if self.script is not None:
            await self._run_script()
        elif self.stopping:  # sat down for the safe stop: hold still until the bus parks
            await self._publish()
        elif self.mode == "ride":
            self._set_activity("riding" if self._rolling() else "standing")
            self.steer = True
            self._ride_tick(dt)
        else:
            hybrid = self.mode == "hybrid"
            await self._gait_tick(dt, hybrid)
            if self.phase_running:
                self._set_activity("hybrid" if hybrid else "walking")
            elif self.activity in ("walking", "hybrid"):
                self._set_activity("standing")
        await self._publish()

    def _rolling(self) -> bool:
        return any(abs(v) > STILL for v in self.wheel_twist)

    async def _run_script(self) -> None:
        assert self.script is not None
        while True:
            if self.wait is not None and not self.wait():
                break
            self.wait = None
            try:
                self.wait = next(self.script)
            except StopIteration:
                self.script = None
                self.wait = None
                break
            if self._pending_moves:
                for leg, target, height in self._pending_moves:
                    await self._send(leg, "move", self._pending_duration, target, height)
                self._pending_moves = []

    async def _publish(self) -> None:
        w = self.want
        # Body height within the stance: the feet stay, the body moves (pose z).
        steady = self.activity in ("standing", "walking", "riding", "hybrid")
        z = w.body_height - self.height if w.body_height is not None and steady else 0.0
        roll, pitch = (0.0, 0.0) if self.upside_down else (w.roll, w.pitch)
        self.pose_now = self._pose_step((0.0, 0.0, z, roll, pitch, 0.0))
        trochanter = 0.0
        if self.loco.trochanter_follows_pitch and not self.upside_down:
            # eq. 4.18: the legs turn with the body's pitch, commanded and measured.
            trochanter = min(
                max(self.pose_now[4] + self.tilt_pitch, -MAX_TROCHANTER), MAX_TROCHANTER
            )
        await self.motion_out.send(
            BodyMotion(
                t=self.t,
                source=self.name,
                cycle=self.cycle,
                twist=self.leg_twist if self.mode != "ride" else (0.0, 0.0, 0.0),
                pose=self.pose_now,  # type: ignore[arg-type]
                trochanter_rad=trochanter,
                upside_down=self.upside_down,
                steer=self.steer,
                wheel_heading_rad=self.headings,
                wheel_speed_m_s=self.speeds,
            )
        )
        if self.state_out is not None:
            # As the gait counts them: a swing that ends within this cycle is down.
            landing = self.t + self.dt
            swing = tuple(i for i in range(N_LEGS) if landing < self.swing_until[i])
            down = [i for i in range(N_LEGS) if i not in swing]
            self.margin = self._margin(down)
            twist = (
                self.leg_twist
                if self.mode == "walk"
                else tuple(a + b for a, b in zip(self.leg_twist, self.wheel_twist, strict=True))
            )
            await self.state_out.send(
                LocomotionState(
                    t=self.t,
                    source=self.name,
                    activity=self.activity,
                    mode=self.mode,
                    gait=self.gait.name,
                    stance=self.stance_name,
                    twist=twist,  # type: ignore[arg-type]
                    gait_phase=self.phase,
                    swing_legs=swing,
                    margin_m=self.margin,
                    upside_down=self.upside_down,
                )
            )

    def _pose_step(self, target: tuple[float, ...]) -> tuple[float, ...]:
        """Move the body pose toward ``target`` at a rate that covers the full range in
        ``transition_s``: 0.1 m and 20° per transition."""
        dt, span = self.dt, self.loco.transition_s
        return tuple(
            [
                _ramp(a, b, r * dt / span)
                for a, b, r in zip(self.pose_now, target, _POSE_RATES, strict=True)
            ]
        )

    async def run(self) -> None:
        self._setup()
        self.script = self._stand_up()
        self.ready()
        try:
            async for states in self.servo_state:
                await self._tick(states)
        finally:
            with self.shielded():
                await self._sit_before_stop()

    async def safe_stop(self, reason: str) -> None:
        """Sit down while the bus can still carry it out; the bus then parks the servos.

        :meth:`run` is still cycling here: it drives the sit-down, this waits for it.
        """
        if not self._begin_sit():
            return
        with anyio.move_on_after(self.loco.sit_down_s + 4 * SETTLE_S):
            while self.script is not None:
                await self.clock.sleep(SETTLE_S)

    def _begin_sit(self) -> bool:
        """Start sitting down, unless seated already, the bus silent or a leg never placed."""
        if (
            self.activity in ("seated", "sitting_down")
            or self.clock.now() - self.last_states_t > BUS_SILENT_S
            or any(f is None for f in self.feet)
        ):
            return False
        self.stopping = True
        self.script = self._sit_down()
        self.wait = None
        self.want.vx = self.want.vy = self.want.yaw = 0.0
        self.leg_twist = self.wheel_twist = (0.0, 0.0, 0.0)
        self.speeds = (0.0,) * N_LEGS
        return True

    async def _sit_before_stop(self) -> None:
        """On cancellation :meth:`run` no longer cycles: drive the sit-down from here."""
        if not self._begin_sit():
            return
        deadline = self.clock.now() + self.loco.sit_down_s + 4 * SETTLE_S
        while self.script is not None and self.clock.now() < deadline:
            states = await self.servo_state.receive()
            self.t = states.t
            self.last_t = states.t
            self.last_states_t = states.t
            self._take_legs()
            await self._run_script()
            await self._publish()
