"""The leg controller: one actor per leg, owning its seven joints (Žák 2023, 4.2.6, 5.4).

Theory of operation
-------------------
A leg actor wakes on every :class:`ServoStates` (one per bus cycle) and, in
that cycle:

1. takes the step commands the coordinator sent it (:class:`StepCommand`),
   the newest :class:`BodyMotion` and, when wired, the force sensors
   (:class:`LegLoads`) and reflex goals;
2. advances its foot along the step it executes, in the *upright frame*:
   the body frame of a robot standing on its feet (x forward, y left, z up,
   the ground below). A swing follows the commanded shape from wherever the
   foot lifted to the target; a foot on the ground is carried by the body's
   stepping twist, p ← p − (v + ω ẑ × p)·dt; a move follows a minimum-jerk
   path (in joint space the first time, from whatever pose the servos
   report, so it never passes outside the limits);
3. turns the foot into joint angles: body pose (eq. 3 of Diosdado 2014,
   3.2), leg frame, inverse kinematics (eq. 4.7–4.19) with the trochanter at
   the angle the coordinator gives (the body pitch, eq. 4.18). An IK that
   fails holds the last good pose and says so (:class:`IkFailed`);
4. steers and drives the wheel: direction = s·ψ − coxa (5.1), wheel rate =
   speed / radius (eq. 5.18), the wheel stopped whenever the foot is in the
   air;
5. sends the goals that changed by half a tick or more to the bus scheduler (which
   keeps the others) and reports :class:`LegState`.

Adaptive swing (Diosdado 2014, 3.5–3.6): contact comes from the force
sensor when frames arrive, otherwise from the femur current (thesis 6.7.3).
A swing whose foot meets the ground from its apex on stops there, and the
stance continues from that height; a swing that ends without ground, or
meets something on its way up, is reported (:class:`SwingEnded`): the
searching and elevator reflexes of a later layer act on it. A contact that
never went away after lift-off is not believed (a stuck sensor).

The leg flip (6.8.1): when :class:`BodyMotion` says ``upside_down`` changed,
the trochanter turns by 180° while the other joints hold: the leg, rotated
about its own long axis, now reaches the ground on the robot's back. With
the trochanter at −π, IK is the upright IK of the mirrored leg.

Reflex overrides (the interface the reactive layer uses): a reflex actor
publishes :class:`JointGoals` with ``reflex=True`` on the channel wired to
this leg's ``reflex`` input. Each goal for one of this leg's positioning
joints (coxa…tarsus) takes that joint over for
``locomotion.reflex_hold_s`` from the goal's ``t``; the leg forwards it to the
bus marked ``reflex`` (which wins over anything else in that bus cycle) and
keeps following its own trajectory underneath. Once no reflex goal has held
the joint for ``reflex_hold_s``, the leg blends from the reflex's angle back
to its own over ``locomotion.reflex_blend_s``: no jump. A reflex keeps
control by sending again; it never has to hand control back explicitly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final

import numpy as np
from pydantic import field_validator

from whexar.actors.messages import (
    BodyMotion,
    IkFailed,
    JointGoal,
    JointGoals,
    LegLoads,
    LegState,
    ServoStates,
    StepCommand,
    SwingEnded,
)
from whexar.config import ConfigFile, ContactSource, RobotConfig, load_config
from whexar.errors import KinematicsError
from whexar.kinematics.cpg import OSCILLATORS, cpg_orbit
from whexar.kinematics.geometry import SIDE_SIGN, LegGeometry
from whexar.kinematics.leg import ik_point
from whexar.kinematics.trajectory import SWING_SHAPES, FootTrajectory
from whexar.robot import LEG_NAMES, N_JOINTS, leg_index
from whexar.runtime.actor import Actor, ActorParams, Input, Output

STEP_KINDS: Final = ("swing", "stance", "move", "hold")
TRAJECTORIES: Final = (*SWING_SHAPES, *OSCILLATORS)
"""Swing shapes a :class:`StepCommand` may name: analytic (Diosdado 2014, 3.3–3.4) or a CPG
orbit (Grzelczyk et al., 8.4)."""
SWING_SAMPLES: Final = 64
"""Samples of a swing shape's table; linear interpolation between them is within 0.1 mm."""
FSR_FRESH_S: Final = 0.5
"""Force-sensor frames older than this no longer count (auto falls back to the current)."""
MIN_SIN: Final = 0.05
"""eq. 5.19 divides by sin α: below this (a joint within 3° of straight) it says nothing."""
FLIPPED_TROCHANTER: Final = -math.pi
"""Trochanter angle of a flipped leg: Goal Position tick 0, inside the register's turn."""
HALF_TICK_RAD: Final = math.pi / 4096
"""Half a Goal Position tick (0.088°): goals closer than this reach the wire unchanged."""
_POSITIONING: Final = 5
_DIRECTION: Final = 5
_WHEEL: Final = 6


def min_jerk(u: float) -> float:
    """Minimum-jerk blend 10u³ − 15u⁴ + 6u⁵ for u in [0, 1]: zero speed and acceleration at
    both ends (Flash and Hogan 1985)."""
    u = 0.0 if u < 0.0 else 1.0 if u > 1.0 else u
    return u * u * u * (10.0 + u * (-15.0 + 6.0 * u))


@dataclass(frozen=True, slots=True)
class SwingShape:
    """A swing's normalised shape: forward progress f(u) ∈ [0, 1] and height h(u) ∈ [0, 1]."""

    name: str
    u: tuple[float, ...]
    forward: tuple[float, ...]
    height: tuple[float, ...]
    apex_u: float

    def at(self, u: float) -> tuple[float, float]:
        """(f, h) at swing phase ``u`` by linear interpolation in the table."""
        n = len(self.u) - 1
        x = (0.0 if u < 0.0 else 1.0 if u > 1.0 else u) * n
        k = min(int(x), n - 1)
        w = x - k
        f, h = self.forward, self.height
        return f[k] + w * (f[k + 1] - f[k]), h[k] + w * (h[k + 1] - h[k])


_SHAPES: dict[tuple[str, float], SwingShape] = {}


def swing_shape(name: str, duty_factor: float) -> SwingShape:
    """The table of swing shape ``name`` for a gait of duty factor β (cached).

    Built from :class:`~whexar.kinematics.trajectory.FootTrajectory` with unit step length
    and height over the swing part of the leg phase, [0, 1 − β), so the analytic shapes and
    the CPG orbits (re-timed to the gait) come from one place.
    """
    key = (name, round(duty_factor, 9))
    found = _SHAPES.get(key)
    if found is not None:
        return found
    swing = cpg_orbit(name) if name in OSCILLATORS else name
    trajectory = FootTrajectory(1.0, 1.0, duty_factor, swing)  # type: ignore[arg-type]
    u = np.linspace(0.0, 1.0, SWING_SAMPLES + 1)
    # The last sample is the touchdown itself: the leg phase 1 − β, where the stance begins.
    phase = np.minimum(u * trajectory.swing_fraction, trajectory.swing_fraction - 1e-7)
    s, h = trajectory.at(phase)
    forward = (s - s[0]) / (s[-1] - s[0]) if s[-1] != s[0] else u
    # Height above the straight line from lift-off to touchdown (a CPG orbit is not at 0
    # there), normalised so the apex is the commanded step height.
    lifted = np.maximum(h - (h[0] * (1 - u) + h[-1] * u), 0.0)
    height = lifted / (float(np.max(lifted)) or 1.0)
    height[0] = height[-1] = 0.0
    shape = SwingShape(
        name,
        tuple(u.tolist()),
        tuple(forward.tolist()),
        tuple(height.tolist()),
        float(u[int(np.argmax(height))]),
    )
    _SHAPES[key] = shape
    return shape


@dataclass(slots=True)
class _Step:
    kind: str
    start_t: float
    duration: float
    origin: list[float]
    target: tuple[float, float, float]
    height: float
    shape: SwingShape | None
    joint_space: tuple[list[float], list[float]] | None = None
    lifted: bool = False
    """A swing's foot was seen off the ground (so a contact now is new ground)."""
    reported: bool = False
    ended: bool = False


def planar_fk(angles: list[float], geometry: LegGeometry) -> tuple[float, float, float]:
    """The wheel contact in the leg frame from five joint angles; scalar, for every cycle.

    The chain of :mod:`whexar.kinematics.leg` written out: femur, tibia and tarsus in the
    leg plane (outward r, down s), the trochanter turning that plane about the leg's long
    axis, the coxa turning it about the vertical.
    """
    c, t1, f, tb, ts = angles
    a2, a3 = geometry.femur, geometry.tibia
    a4 = geometry.contact_offset
    phi = f
    r = geometry.trochanter_offset + a2 * math.cos(phi)
    s = -a2 * math.sin(phi)
    phi += tb
    r += a3 * math.cos(phi)
    s -= a3 * math.sin(phi)
    phi += ts
    r += a4 * math.cos(phi)
    s -= a4 * math.sin(phi)
    zeta = s * math.sin(t1)
    y = s * math.cos(t1)
    return r * math.cos(c) - zeta * math.sin(c), y, r * math.sin(c) + zeta * math.cos(c)


class LegActor(Actor):
    """Executes the coordinator's steps for one leg: trajectory, IK, wheels, contact."""

    class Params(ActorParams):
        leg: str
        """The leg this actor drives: RF, LF, RM, LM, RR or LR (or 0…5)."""
        config: ConfigFile | None = None
        """Robot configuration file; absent: the built-in defaults."""
        contact: ContactSource | None = None
        """Overrides ``locomotion.contact`` (e.g. ``none`` on emulators without ground)."""

        @field_validator("leg")
        @classmethod
        def _known_leg(cls, value: str) -> str:
            leg_index(value)  # raises UsageError naming the allowed legs
            return value

    params: Params
    servo_state = Input(ServoStates)
    steps = Input(StepCommand, optional=True)
    motion = Input(BodyMotion, optional=True)
    loads = Input(LegLoads, optional=True)
    reflex = Input(JointGoals, optional=True)
    goals = Output(JointGoals)
    state = Output(LegState, optional=True)

    # ----------------------------------------------------------------- set-up

    def _setup(self) -> None:
        p = self.params
        self.cfg: RobotConfig = load_config(p.config) if p.config else RobotConfig()
        self.loco = self.cfg.locomotion
        self.leg = leg_index(p.leg)
        self.leg_name = LEG_NAMES[self.leg]
        self.geometry = self.cfg.leg_geometry()
        self.contact_source: ContactSource = p.contact or self.loco.contact
        mount = self.geometry.mounts[self.leg]
        self.mount = (float(mount[0]), float(mount[1]), float(mount[2]))
        self.side = float(SIDE_SIGN[self.leg])
        self.upside_down = False
        self.flip: tuple[float, float, float] | None = None
        """(start_t, from, to) of a trochanter flip under way."""
        self.trochanter = 0.0
        self.foot: list[float] | None = None
        self.angles: list[float] | None = None
        """The last good positioning angles (coxa…tarsus) sent."""
        self.measured: list[float | None] = [None] * N_JOINTS
        self.currents: list[float | None] = [None] * N_JOINTS
        self.step: _Step | None = None
        self.twist = (0.0, 0.0, 0.0)
        self.pose: tuple[float, ...] = (0.0,) * 6
        self.rotation: tuple[float, ...] | None = None
        self.last_t: float | None = None
        self.cycle = 0
        self.ik_ok = True
        self.contact = False
        self.fsr_t = -math.inf
        self.fsr_contact = False
        self.reflex_goals: dict[int, tuple[float, float]] = {}
        """joint → (angle, time of the reflex goal)."""
        self.blends: dict[int, tuple[float, float]] = {}
        """joint → (reflex angle at release, release time)."""
        self.wheel_radius = self.geometry.wheel_radius
        self.sent: list[float] = [math.inf] * N_JOINTS
        """The goals last sent, per joint (rad, or rad/s for the wheel); inf: none yet."""
        self.steer = False
        self.heading = 0.0
        self.speed = 0.0
        self.flip_to = False
        self.airborne = False
        """The foot is in the air this cycle (a swing, or a move with a lift): wheel stopped."""
        # Looked up once, not every cycle: a port attribute is a descriptor and a mapping
        # lookup. An optional input or output the wiring left unconnected is None here.
        self.steps_in = self.steps if self.steps.connected else None
        self.motion_in = self.motion if self.motion.connected else None
        self.loads_in = self.loads if self.loads.connected else None
        self.reflex_in = self.reflex if self.reflex.connected else None
        self.goals_out = self.goals
        self.state_out = self.state if self.state.connected else None
        self.contact_current_a = self.loco.contact_current_a
        self.femur = self.geometry.femur
        self.tibia = self.geometry.tibia

    # ----------------------------------------------------------------- frames

    def _frame(self) -> tuple[float, float, float]:
        """(side sign, mount y, mount z) of this leg in the upright frame (mirrored flipped)."""
        if self.upside_down:
            return -self.side, -self.mount[1], -self.mount[2]
        return self.side, self.mount[1], self.mount[2]

    def _to_leg(self, p: list[float] | tuple[float, float, float]) -> tuple[float, float, float]:
        """Upright-frame point → this leg's frame, through the body pose (p' = Rᵀ(p − t))."""
        x, y, z = p
        if self.rotation is not None:
            px, py, pz = x - self.pose[0], y - self.pose[1], z - self.pose[2]
            r = self.rotation
            x = r[0] * px + r[3] * py + r[6] * pz
            y = r[1] * px + r[4] * py + r[7] * pz
            z = r[2] * px + r[5] * py + r[8] * pz
        side, my, mz = self._frame()
        return -side * (y - my), -(z - mz), x - self.mount[0]

    def _from_leg(self, q: tuple[float, float, float]) -> tuple[float, float, float]:
        """This leg's frame → upright frame (the pose undone)."""
        side, my, mz = self._frame()
        x = self.mount[0] + q[2]
        y = my - side * q[0]
        z = mz - q[1]
        if self.rotation is not None:
            r = self.rotation
            x, y, z = (
                r[0] * x + r[1] * y + r[2] * z + self.pose[0],
                r[3] * x + r[4] * y + r[5] * z + self.pose[1],
                r[6] * x + r[7] * y + r[8] * z + self.pose[2],
            )
        return x, y, z

    # ----------------------------------------------------------------- inputs

    def _take_motion(self) -> None:
        inbox = self.motion_in
        motion = inbox.latest() if inbox is not None else None
        if motion is None:
            return
        self.twist = motion.twist
        self.steer = motion.steer and not motion.upside_down
        self.heading = motion.wheel_heading_rad[self.leg]
        self.speed = motion.wheel_speed_m_s[self.leg]
        if motion.pose != self.pose:
            self.pose = motion.pose
            if any(motion.pose):
                _, _, _, roll, pitch, yaw = motion.pose
                cr, sr = math.cos(roll), math.sin(roll)
                cp, sp = math.cos(pitch), math.sin(pitch)
                cy, sy = math.cos(yaw), math.sin(yaw)
                # R = R_z(yaw) · R_y(pitch) · R_x(roll), row-major (kinematics.body.BodyPose).
                self.rotation = (
                    cy * cp,
                    cy * sp * sr - sy * cr,
                    cy * sp * cr + sy * sr,
                    sy * cp,
                    sy * sp * sr + cy * cr,
                    sy * sp * cr - cy * sr,
                    -sp,
                    cp * sr,
                    cp * cr,
                )
            else:
                self.rotation = None
        if motion.upside_down != self.upside_down and self.flip is None:
            self.flip = (
                motion.t,
                FLIPPED_TROCHANTER if self.upside_down else self.trochanter,
                FLIPPED_TROCHANTER if motion.upside_down else 0.0,
            )
            self.flip_to = motion.upside_down
        if self.flip is None and not self.upside_down:
            self.trochanter = motion.trochanter_rad

    def _take_steps(self, t: float) -> None:
        if self.steps_in is None:
            return
        for cmd in self.steps_in.drain():
            if cmd.leg != self.leg:
                continue
            self._begin(cmd, t)

    def _begin(self, cmd: StepCommand, t: float) -> None:
        shape = None
        if cmd.kind == "swing":
            shape = swing_shape(cmd.trajectory, cmd.duty_factor)
        joint_space = None
        origin = list(self.foot) if self.foot is not None else [0.0, 0.0, 0.0]
        if cmd.kind == "move" and (self.foot is None or self.angles is None):
            # First move after start: from the pose the servos report, in joint space.
            start = [m if m is not None else 0.0 for m in self.measured[:_POSITIONING]]
            goal = self._solve(cmd.target)
            if goal is None:
                goal = list(start)
            joint_space = (start, goal)
            origin = list(self._from_leg(planar_fk(start, self.geometry)))
        elif cmd.kind in ("stance", "hold") and self.foot is None:
            return  # nothing to hold yet: the first command must place the foot
        self.step = _Step(
            cmd.kind,
            cmd.start_t,
            max(cmd.duration_s, 1e-6),
            origin,
            cmd.target,
            cmd.height_m,
            shape,
            joint_space,
        )
        if self.foot is None:
            self.foot = list(origin)

    def _take_state(self, states: ServoStates) -> None:
        # Which joints a cycle carries depends on the read plan's rates: look for this
        # leg's in every cycle (42 entries) rather than keep an index that rarely holds.
        leg, measured, currents = self.leg, self.measured, self.currents
        for j in states.joints:
            if j.leg == leg:
                position = j.position_rad
                if position is not None:
                    measured[j.joint] = position
                currents[j.joint] = j.current_a

    def _take_loads(self, t: float) -> None:
        if self.loads_in is None:
            return
        loads = self.loads_in.latest()
        if loads is not None:
            self.fsr_t = loads.t
            self.fsr_contact = loads.contacts[self.leg]

    def _take_reflex(self) -> None:
        if self.reflex_in is None:
            return
        for msg in self.reflex_in.drain():
            if not msg.reflex:
                continue
            for g in msg.goals:
                angle = g.position_rad
                mine = g.leg == self.leg and g.joint < _POSITIONING
                if mine and angle is not None and math.isfinite(angle):
                    self.reflex_goals[g.joint] = (angle, msg.t)
                    self.blends.pop(g.joint, None)

    # ----------------------------------------------------------------- contact

    def _contact(self, t: float) -> tuple[bool, str]:
        source = self.contact_source
        if source == "auto":
            source = "fsr" if t - self.fsr_t <= FSR_FRESH_S else "current"
        if source == "fsr":
            return (self.fsr_contact and t - self.fsr_t <= FSR_FRESH_S), "fsr"
        if source == "current":
            amps = self.currents[2]
            return (amps is not None and abs(amps) > self.contact_current_a), "current"
        return False, "none"

    def _load(self) -> tuple[float | None, float | None]:
        """eq. 5.19, F_i = I_i / (L_i · sin α_{i+1}), for the femur and tibia segments."""
        return self._segment_load(2, self.femur), self._segment_load(3, self.tibia)

    def _segment_load(self, joint: int, length: float) -> float | None:
        amps, nxt = self.currents[joint], self.measured[joint + 1]
        if amps is None or nxt is None:
            return None
        sin = math.sin(nxt)
        return None if abs(sin) < MIN_SIN else amps / (length * sin)

    # ----------------------------------------------------------------- the foot

    def _advance(self, t: float, dt: float, contact: bool, source: str) -> tuple[str, float]:
        step, foot = self.step, self.foot
        if step is None or foot is None:
            return "idle", 0.0
        u = (t - step.start_t) / step.duration
        u = 0.0 if u < 0.0 else 1.0 if u > 1.0 else u
        if step.kind == "swing" and not step.ended:
            assert step.shape is not None
            f, h = step.shape.at(u)
            o, g = step.origin, step.target
            foot[0] = o[0] + (g[0] - o[0]) * f
            foot[1] = o[1] + (g[1] - o[1]) * f
            foot[2] = o[2] + (g[2] - o[2]) * f + step.height * h
            if source != "none":
                self._adapt(step, u, contact)
            elif u >= 1.0:
                step.ended = True
            return "swing", u
        if step.kind == "move" and not step.ended:
            s = min_jerk(u)
            o, g = step.origin, step.target
            foot[0] = o[0] + (g[0] - o[0]) * s
            foot[1] = o[1] + (g[1] - o[1]) * s
            foot[2] = o[2] + (g[2] - o[2]) * s + step.height * math.sin(math.pi * u)
            if u >= 1.0:
                step.ended = True  # its last pose (joint space included) is sent this cycle
            return "move", u
        # On the ground: the body carries the foot (stance, hold, a finished swing or move).
        vx, vy, w = self.twist
        if dt > 0.0 and (vx or vy or w):
            x, y = foot[0], foot[1]
            if w:
                c, s_ = math.cos(-w * dt), math.sin(-w * dt)
                x, y = c * x - s_ * y, s_ * x + c * y
            foot[0], foot[1] = x - vx * dt, y - vy * dt
        kind = "stance" if step.kind in ("swing", "stance") else "hold"
        return kind, u

    def _adapt(self, step: _Step, u: float, contact: bool) -> None:
        """Adaptive swing (Diosdado 2014, 3.5–3.6) on the contact reading of this cycle."""
        assert step.shape is not None
        if not contact:
            if u > 0.0:
                step.lifted = True
            if u >= 1.0:
                step.ended = True
                self._swing_ended("no_contact", step)
            return
        if not step.lifted or u <= 0.0:
            return  # still on the ground at lift-off, or a sensor stuck on
        if u >= 1.0:
            step.ended = True
            return  # touchdown where expected
        if u < step.shape.apex_u:
            if not step.reported:
                step.reported = True
                self._swing_ended("blocked", step)  # the elevator reflex's case
            return
        step.ended = True
        self._swing_ended("early_contact", step)

    def _swing_ended(self, outcome: str, step: _Step) -> None:
        assert self.foot is not None
        self.emit(
            SwingEnded(
                t=self.now(),
                source=self.name,
                leg=self.leg,
                outcome=outcome,
                ground_offset_m=self.foot[2] - step.target[2],
            )
        )

    # ----------------------------------------------------------------- IK and goals

    def _solve(self, p: list[float] | tuple[float, float, float]) -> list[float] | None:
        pitch = 0.0 if self.upside_down or self.flip is not None else self.trochanter
        try:
            solution = ik_point(self._to_leg(p), self.geometry, pitch=pitch, target="contact")
        except KinematicsError as exc:
            if self.ik_ok:
                self.ik_ok = False
                x, y, z = p
                self.emit(
                    IkFailed(
                        t=self.now(),
                        source=self.name,
                        leg=self.leg,
                        target=(x, y, z),
                        reason=str(exc),
                    )
                )
            return None
        self.ik_ok = True
        return list(solution)

    def _trochanter(self, t: float) -> float:
        if self.flip is None:
            return FLIPPED_TROCHANTER if self.upside_down else self.trochanter
        start, a, b = self.flip
        u = (t - start) / self.loco.flip_s
        if u >= 1.0:
            self.flip = None
            self.upside_down = self.flip_to
            if self.foot is not None:
                self.foot[1] = -self.foot[1]  # the same leg pose, seen from the other side
            return b
        return a + (b - a) * min_jerk(u)

    def _goals(self, t: float, angles: list[float], airborne: bool) -> JointGoals | None:
        """This cycle's goals that differ from the ones last sent (None: nothing new).

        The bus keeps a joint's goal until a new one comes, and sends a servo its goal
        again on its own before the Bus Watchdog would expire: an unchanged goal need not
        travel. A position within half a Goal Position tick of the last is unchanged."""
        if self.steer and not self.upside_down:
            # direction = s·ψ − coxa (wheels.direction_for_heading, 5.1), within one turn.
            direction = self.side * self.heading - angles[0]
            direction = (direction + math.pi) % (2 * math.pi) - math.pi
        else:
            direction = 0.0
        speed = 0.0 if airborne or not self.steer or self.upside_down else self.speed
        last = self.sent
        name, leg = self.name, self.leg
        goals = []
        for j, angle in enumerate((*angles, direction)):  # the positioning joints, direction
            if abs(angle - last[j]) >= HALF_TICK_RAD:
                last[j] = angle
                goals.append(JointGoal(t=t, source=name, leg=leg, joint=j, position_rad=angle))
        rate = speed / self.wheel_radius
        if rate != last[_WHEEL]:
            last[_WHEEL] = rate
            goals.append(JointGoal(t=t, source=name, leg=leg, joint=_WHEEL, velocity_rad_s=rate))
        return JointGoals(t=t, source=name, goals=tuple(goals)) if goals else None

    def _apply_reflex(self, t: float, angles: list[float]) -> tuple[list[float], list[JointGoal]]:
        """Reflex-held joints, and the blend back from them (module docstring)."""
        hold, blend = self.loco.reflex_hold_s, self.loco.reflex_blend_s
        forwarded: list[JointGoal] = []
        out = list(angles)
        for joint, (angle, since) in list(self.reflex_goals.items()):
            if t - since <= hold:
                out[joint] = angle
                forwarded.append(
                    JointGoal(t=t, source=self.name, leg=self.leg, joint=joint, position_rad=angle)
                )
            else:
                del self.reflex_goals[joint]
                self.blends[joint] = (angle, since + hold)
        for joint, (angle, released) in list(self.blends.items()):
            w = (t - released) / blend
            if w >= 1.0:
                del self.blends[joint]
                continue
            out[joint] = angle + (angles[joint] - angle) * min_jerk(w)
        return out, forwarded

    # ----------------------------------------------------------------- the cycle

    async def _tick(self, states: ServoStates) -> None:
        t = states.t
        dt = 0.0 if self.last_t is None else t - self.last_t
        self.last_t = t
        self.cycle = states.cycle
        self._take_state(states)
        self._take_motion()
        self._take_loads(t)
        self._take_reflex()
        self._take_steps(t)
        contact, source = self._contact(t)
        self.contact = contact
        phase, progress = self._advance(t, dt, contact, source)
        if self.foot is None:
            return  # no command yet: the bus holds the servos where they stand
        troch = self._trochanter(t)
        step = self.step
        angles: list[float] | None
        if step is not None and step.joint_space is not None and phase == "move":
            a, b = step.joint_space
            s = min_jerk(progress)
            angles = [x + (y - x) * s for x, y in zip(a, b, strict=True)]
        elif self.flip is not None and self.angles is not None:
            angles = list(self.angles)
            phase = "flip"
        else:
            angles = self._solve(self.foot)
        if angles is None:
            angles = self.angles
            if angles is None:
                return
        else:
            self.angles = angles
        angles = list(angles)
        angles[1] = troch
        if self.reflex_goals or self.blends:
            angles, forwarded = self._apply_reflex(t, angles)
            if forwarded:
                phase = "reflex"
                for g in forwarded:  # the bus now holds the reflex's goal for these joints
                    self.sent[g.joint] = math.inf
                await self.goals_out.send(
                    JointGoals(t=t, source=self.name, goals=tuple(forwarded), reflex=True)
                )
        airborne = phase in ("swing", "flip") or (
            phase == "move" and step is not None and step.height > 0.0
        )
        goals = self._goals(t, angles, airborne)
        if goals is not None:
            await self.goals_out.send(goals)
        if self.state_out is not None:
            measured = None
            coxa, trochanter, femur, tibia, tarsus = self.measured[:_POSITIONING]
            if trochanter is None:
                trochanter = troch  # a plan that does not read it (the default) leaves its goal
            if coxa is not None and femur is not None and tibia is not None and tarsus is not None:
                q = planar_fk([coxa, trochanter, femur, tibia, tarsus], self.geometry)
                if self.upside_down:
                    q = (q[0], -q[1], q[2])
                measured = self._from_leg(q)
            foot = self.foot
            await self.state_out.send(
                LegState(
                    t=t,
                    source=self.name,
                    leg=self.leg,
                    cycle=self.cycle,
                    phase=phase,
                    progress=progress,
                    foot=(foot[0], foot[1], foot[2]),
                    measured_foot=measured,
                    contact=contact,
                    contact_source=source,
                    load=self._load(),
                    ik_ok=self.ik_ok,
                )
            )

    async def run(self) -> None:
        self._setup()
        self.ready()
        async for states in self.servo_state:
            await self._tick(states)
