"""The coordinator's state and the geometry every part of its policy shares.

:class:`PlannerCore` holds what the coordinator knows — the wanted state, the
present gait, stance and mode, each leg's commanded and measured foot, the
wheels — and answers the questions the scripts (:mod:`.scripts`) and the
engines (:mod:`.planner`) both ask: the neutral points of a stance, the
static stability margin of a set of feet, whether a leg reaches a point,
where the wheels touch the ground, the wheels' headings and speeds for a
twist. What it says in a cycle (events, step commands) it collects in order
for the cycle to return. No ``await``, no channel, no clock.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Iterator
from itertools import chain
from typing import Final

import numpy as np

from whexar.actors.locomotion.activity import Activity, checked
from whexar.actors.locomotion.asks import Asks
from whexar.actors.locomotion.frames import LegFrame
from whexar.actors.locomotion.intent import Wanted
from whexar.actors.messages import LocomotionChanged, StepCommand, Vec3
from whexar.bus import control_table as ct
from whexar.config import RobotConfig
from whexar.errors import KinematicsError
from whexar.kinematics.body import (
    Stance,
    body_to_leg,
    leg_to_body,
    stance_feet,
    workspace_step,
)
from whexar.kinematics.gait import GAITS, Gait
from whexar.kinematics.leg import ik, trochanter_arc
from whexar.kinematics.stability import gravity_cog, support_margin
from whexar.kinematics.wheels import wheel_twist
from whexar.robot import N_LEGS
from whexar.runtime.messages import Message

GAIT_START: Final = 1.0 - 1e-9
"""Cycle phase a gait starts from: just before 0, so the legs at offset 0 lift first."""
PLACED_M: Final = 0.005
"""A foot within this of its target needs no re-placement."""
SETTLE_S: Final = 0.05
"""Margin after a commanded move before the next step of a script (a few bus cycles)."""
STILL: Final = 1e-6
"""|twist| below this is standing still."""
_WHEELS_KEY: Final = struct.Struct("<21d").pack
"""The key of :meth:`PlannerCore.wheels`: a twist and six contact points, as bytes."""

Wait = Callable[[], bool]
Script = Iterator[Wait]
"""A script: a generator of waits, each true once the script may go on (:mod:`.scripts`)."""


def velocity_limit(model: str) -> float:
    """The Velocity Limit (44) a servo of ``model`` starts with, rad/s (e-manual)."""
    return ct.velocity_to_rad_s(ct.model(model).register("velocity_limit").initial or 0)


class PlannerCore:
    """The coordinator's state and shared geometry (module docstring)."""

    def __init__(self, cfg: RobotConfig, *, name: str) -> None:
        self.cfg = cfg
        self.name = name
        """The ``source`` of everything the coordinator says."""
        loco = self.loco = cfg.locomotion
        self.geometry = cfg.leg_geometry()
        self.want = Wanted.of(cfg)
        self.asks = Asks(loco.max_step_height_mm / 1000)
        """What the reflexes ask on top of what the operator wants (:mod:`.asks`)."""
        self.gait: Gait = GAITS[loco.gait]
        self.stance_name = loco.stance
        self.mode = "walk"
        self.upside_down = False
        self.activity = Activity.STANDING_UP
        self.leg_twist = (0.0, 0.0, 0.0)
        self.wheel_twist = (0.0, 0.0, 0.0)
        self.headings: tuple[float, ...] = (0.0,) * N_LEGS
        self.speeds: tuple[float, ...] = (0.0,) * N_LEGS
        self.steer = False
        self.phase = GAIT_START
        self.cycle_s = loco.max_cycle_s
        self.dt = 0.0
        self.t = 0.0
        self.swing_until = [-math.inf] * N_LEGS
        self.feet: list[Vec3 | None] = [None] * N_LEGS
        self.measured_feet: list[Vec3 | None] = [None] * N_LEGS
        """Where each leg's foot is: its present angles' forward kinematics (:meth:`contacts`)."""
        self.measured_raw: list[Vec3 | None] = [None] * N_LEGS
        """The same, off the grid (the settling stance's errors are millimetres)."""
        self.awaited_since: list[float | None] = [None] * N_LEGS
        """Since when each leg's touchdown is awaited (``LegState.touchdown_pending``)."""
        contact = cfg.contact
        self.touchdown_wait_s = (
            contact.touchdown_s + loco.max_step_height_mm / 1000 / contact.search_speed_m_s
        )
        """The longest a touchdown is waited for: its wait and a search as deep as the
        highest step (a leg that says it awaits one for longer is not waited for)."""
        self.share_below_cos = math.cos(math.radians(contact.balance_tilt_deg))
        """The ground's tilt from level, as its cosine, from which stances share the load."""
        self.settle_t = -math.inf
        self.wheel_measured: list[float | None] = [None] * N_LEGS
        self.direction_measured: list[float | None] = [None] * N_LEGS
        self.coxa_measured: list[float | None] = [None] * N_LEGS
        self.height = cfg.stance(self.stance_name).height
        self.neutral_points: list[Vec3] = self.neutral(cfg.stance(self.stance_name))
        self.pose_now: tuple[float, ...] = (0.0,) * 6
        self.trochanter_rad = 0.0
        """The trochanter angle last said (eq. 4.18): it carries the feet on their arcs."""
        self.ground_tilt = (0.0, 0.0)
        """(roll, pitch) of the ground under the feet as gravity sees it (rad)."""
        self.cog: tuple[float, float, float] = (
            cfg.body.cog_mm[0] / 1000,
            cfg.body.cog_mm[1] / 1000,
            cfg.body.cog_mm[2] / 1000,
        )
        """The robot's centre of gravity in the body frame, m (``body.cog_mm``)."""
        self.frames = [LegFrame(self.geometry, i) for i in range(N_LEGS)]
        """The legs' frames under the body pose: where the arcs are drawn."""
        self.riders: set[int] = set()
        """Legs riding their wheel for a lost coxa: they never lift (:mod:`.losses`)."""
        self.riding: set[int] = set()
        """The riders told to ride since their last other step."""
        self.pending_moves: list[tuple[int, Vec3, float]] = []
        self.pending_duration = 0.0
        self._workspace: dict[tuple[str, bool], float] = {}
        joints = cfg.joints
        self.wheel_rate_max = velocity_limit(joints.by_name("wheel").model)
        self.direction_rate_max = velocity_limit(joints.by_name("direction").model)
        self._wheels_key = b""
        self._wheels_said: tuple[tuple[float, ...], tuple[float, ...]] = ((), ())
        self.script: Script | None = None
        """The script under way (:mod:`.scripts`); while one runs, nothing else moves feet."""
        self.wait: Wait | None = None
        """What the script waits for before its next step."""
        self.winding_down = False
        self.delayed = False
        """A lift-off waits for the stability margin (:class:`SwingDelayed` said)."""
        self.clamp_said = False
        self.phase_running = False
        self.out: list[Message] = []
        """What this cycle says so far, in order (events and step commands)."""

    def asked_twist(self) -> Vec3:
        """The twist to move toward: the operator's, as the reflexes bend it."""
        return self.asks.twist(self.want.twist())

    def asked_step_height(self) -> float:
        """The step height to swing with: the operator's, or higher where a reflex asks."""
        return self.asks.step_height(self.want.step_height)

    # ----------------------------------------------------------------- saying

    def say(self, msg: Message) -> None:
        """Add an event or a step command to what this cycle says."""
        self.out.append(msg)

    def set_activity(self, activity: Activity) -> None:
        """Change the activity, along the transition table only (:mod:`.activity`)."""
        if activity != self.activity:
            self.changed("activity", self.activity, checked(self.activity, activity))
            self.activity = activity

    def changed(self, what: str, before: str, after: str) -> None:
        """Say that ``what`` changed (:class:`LocomotionChanged`)."""
        self.say(
            LocomotionChanged(
                t=self.t, source=self.name, what=what, before=str(before), after=str(after)
            )
        )

    def send_step(
        self, leg: int, kind: str, duration: float, target: Vec3, height: float = 0.0
    ) -> None:
        """Order ``leg`` to start a step now (:class:`StepCommand`)."""
        if kind != "ride":
            self.riding.discard(leg)
        self.say(
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
                search_depth_m=self.asks.search_depth() if kind == "swing" else 0.0,
                reach_depth_m=self.asks.reach_depth() if kind == "swing" else 0.0,
                share_load=kind in ("swing", "stance") and self.sloped(),
            )
        )

    def sloped(self) -> bool:
        """The ground tilts ``contact.balance_tilt_deg`` or more (:attr:`ground_tilt`): the
        stances share their load there (:class:`StepCommand`'s ``share_load``)."""
        roll, pitch = self.ground_tilt
        return math.cos(roll) * math.cos(pitch) <= self.share_below_cos

    # ----------------------------------------------------------------- geometry

    def stance(self, name: str) -> Stance:
        return self.cfg.stance(name)

    def neutral(self, stance: Stance, height: float | None = None) -> list[Vec3]:
        """The six neutral foot points of ``stance`` in the upright frame (mirrored flipped)."""
        feet = leg_to_body(stance_feet(stance), self.geometry)
        h = stance.height if height is None else height
        sign = -1.0 if self.upside_down else 1.0
        return [(float(f[0]), sign * float(f[1]), -h) for f in feet]

    def placed(self, leg: int, foot: Vec3) -> Vec3:
        """Where ``leg`` puts a foot planned at ``foot`` (upright frame): the trochanter
        carries it on its arc (:func:`trochanter_arc`) in the leg's frame under the body
        pose, as the leg does."""
        theta = self.trochanter_rad
        if theta == 0.0 or self.upside_down:
            return foot
        frame = self.frames[leg]
        if frame.pose != self.pose_now:
            frame.set_pose(self.pose_now)
        return frame.from_leg(trochanter_arc(frame.to_leg(foot), theta))

    def margin(self, down: list[int]) -> float:
        """The static stability margin of the feet of legs ``down`` (3.2.2); a leg never
        placed counts at its neutral point.

        The feet are where the trochanter carries them (:func:`trochanter_arc`, as the
        legs place them), and the robot's CoG (``body.cog_mm``: below the body centre,
        the legs hang under it) is projected along gravity onto their plane
        (:func:`gravity_cog`): on a slope the point the supports must enclose lies
        downhill of the one straight below the body."""
        feet, neutral = self.feet, self.neutral_points
        points: list[tuple[float, float]] = []
        ground = 0.0
        for i in down:
            x, y, z = self.placed(i, feet[i] or neutral[i])
            points.append((x, y))
            ground += z
        pose = self.pose_now
        roll, pitch = self.ground_tilt
        cx, cy, cz = self.cog
        cog = (pose[0] + cx, pose[1] + cy)
        if points and (roll != 0.0 or pitch != 0.0):
            cog = gravity_cog(cog, pose[2] + cz - ground / len(points), roll, pitch)
        return support_margin(points, cog)

    def away(self, leg: int, target: Vec3) -> bool:
        """Whether ``leg``'s foot is more than :data:`PLACED_M` from ``target`` (a rider's
        never is: its foot stays where its lost coxa left it)."""
        foot = self.feet[leg]
        if leg in self.riders:
            return False
        if foot is None:
            return True
        return math.dist(foot, target) > PLACED_M

    def reachable(self, points: list[Vec3]) -> bool:
        """Whether every leg reaches its point (upright frame) within its joint limits."""
        sign = -1.0 if self.upside_down else 1.0  # a flipped leg is the mirrored one (6.8.1)
        body = np.array([(p[0], sign * p[1], p[2]) for p in points])
        try:
            ik(body_to_leg(body, self.geometry), self.geometry, target="contact")
        except KinematicsError:
            return False
        return True

    def max_step(self) -> float:
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

    # ----------------------------------------------------------------- the wheels

    def contacts(self) -> list[Vec3]:
        """Where the wheels touch the ground, for their headings and speeds: each leg's
        measured foot, else its commanded one, else its neutral point.

        The measured foot, not the commanded: under the body's weight a leg sags, its
        servos holding a position error, and speeds computed for the commanded feet then
        disagree, on a turn, with the wheels' real distances from the centre of rotation:
        the wheels scrub against each other through the legs (thesis 6.5.2: "tension on
        the inner legs"; docs/architecture.md has the currents measured both ways)."""
        return [
            m if m is not None else f if f is not None else n
            for m, f, n in zip(self.measured_feet, self.feet, self.neutral_points, strict=True)
        ]

    def wheels(
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

    def wheels_stopped(self) -> bool:
        stop = self.loco.wheel_stop_speed_m_s / self.geometry.wheel_radius
        return all(v is None or abs(v) <= stop for v in self.wheel_measured)

    def rolling(self) -> bool:
        return any(abs(v) > STILL for v in self.wheel_twist)
