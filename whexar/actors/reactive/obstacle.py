"""The obstacle reflex: stop before what the rangefinders see, measure it, then climb it
or keep off it (4.2.2, 6.7.4).

Theory of operation
-------------------
The thesis sorts obstacles three ways (6.7.4): low ones the gait crosses (the
leg stops on them: the early-contact stop, the elevator); ones too high for
normal walking that the robot climbs after it "stops and measures their height
and depth using a rangefinder"; and high ones it must avoid, which is
navigation's work (4.2.3). Here:

* **Profile.** Each reading of a front-leg rangefinder (5.3.5) is a point of
  the ground ahead: a ray from the femur servo, at its height above where the
  front feet stand (their measured points in the body frame, in stance: the
  ground next to what the rays see, a ramp's if they stand on one; before
  any, the stance's height), pitched down by the mount
  (``ir.pitch_deg``) less the trochanter angle (which tilts the sensor, 5.3.5)
  plus the rise of the feet's plane ahead in the body frame (a least-squares
  line through the stance feet: the body pitched nose down over its feet).
  Taken in the plane of the feet (the body keeps parallel to a slope, the
  trochanter following the pitch, eq. 4.18), a slope is level: only a change
  of ground shows. A point is ``(x, z)``: along the ray, and up from the ground
  under the feet (:func:`~whexar.actors.reactive.profile.ray_point`).
* **Calibration.** Each rangefinder's gain differs from part to part (±13 %
  of its output swing, Sharp GP2Y0A21YK data sheet: ±23 % of a distance through
  eq. 5.5), enough to lift the floor 5 cm in the rays' picture. While the robot
  keeps still on level feet — seated, standing — each ray meets the floor at the
  rays' height over the sine of their pitch; the reflex learns each sensor's
  scale from that (``learn_tau_s``), within ``max_scale_error`` of 1 (further,
  something stands in front), as heading hold learns the gyroscope's level.
* **Stop.** Walking forward, a point at least ``min_height_m`` up and nearer
  than ``see_m``, in ``confirm_frames`` readings in a row: the reflex halts the
  body (``ReflexRequest.halt``) — unless the robot stands across a change of
  ground (its front feet ``level_m`` above or below its rear ones: a ramp's
  foot, a box's edge; a foot ``uneven_m`` off the others), where the feet's
  plane is no frame for the rays.
* **Measure.** Standing, it sweeps the trochanters ``scan_deg`` either side of
  their angle (``ReflexRequest.trochanter_rad``: all legs turn together, the
  body sways over its feet), one ``scan_step_deg`` every ``settle_s``, taking a
  reading at each: a profile from the ground in front over the obstacle to what
  lies behind it (:mod:`~whexar.actors.reactive.profile`). Its height is its
  highest point, its front the nearest risen point, its depth how far its top
  runs. A rise whose face is gentler than ``max_face_deg`` is a slope (the
  rangefinders see ramps too): nothing to do. Where no ray met the ground
  before the rise — the robot rode to a ramp whose foot lies under its
  sensors, or stopped late before a box — the face runs from where the front
  feet stand; if that makes it a slope, but taken straight up it would be an
  obstacle to climb, it is climbed (a higher step costs a ramp seconds; a ramp
  kept off for good strands the robot).
* **Climb** an obstacle at most ``climb_m`` high whose top the sweep saw: the
  walk goes on with the step at least its height and ``clearance_m`` (a
  ``ReflexRequest.step_height_m``; the coordinator keeps it within
  ``locomotion.max_step_height_mm``), kept until the body has gone past it —
  its front, its depth and ``pass_m`` more (the body's length behind the
  rangefinders).
* **Keep off** anything higher, or whose top it could not see: nothing goes
  forward (``ReflexRequest.block_ahead``) until the rangefinders no longer see
  it for ``clear_s``; turning, sidestepping and backing away stay the
  operator's (the navigation 4.2.3 leaves avoidance to).

It is active from the stop to its decision, and while it keeps off: the
searching, stepping and elevator reflexes are held back meanwhile (a swing put
down by the halt, a foot carried by the sweep are no lost ground and no slip). The thesis
gives no figures for this reflex (6.7.4); the defaults are the measurements in
docs/reflexes.md.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import replace
from functools import partial
from typing import Literal

import numpy as np
from pydantic import Field

from whexar.actors.messages import BodyMotion, LegState, LocomotionState, ObstacleRanges
from whexar.actors.reactive.profile import Profile, profile, ray_point
from whexar.actors.reactive.reflex import WALKING, Command, Reflex, ReflexParams
from whexar.config import RobotConfig, StanceSpec
from whexar.kinematics.leg import fk_chain
from whexar.runtime.messages import Message

STILL = frozenset({"standing"})
"""The activity in which the rangefinders learn their scale: standing still (seated, the
rays meet the floor 0.23 m ahead, where the sensor's output folds back, 5.3.5)."""
FRONT_LEGS = (0, 1)
"""RF and LF: the legs that carry the rangefinders (5.3.5)."""
REAR_LEGS = (4, 5)
RAY_DOWN_PER_TROCHANTER = -1.0
"""How a trochanter turn tilts the rays: the trochanter follows the body's pitch to keep
them level (eq. 4.18), and a nose-up pitch is negative (eq. 5.7 on the board's axes), so
turning it by +θ raises them by θ."""
STILL_M_S = 1e-3


class ObstacleParams(ReflexParams):
    """The obstacle reflex's thresholds (docs/reflexes.md)."""

    min_height_m: float = Field(0.05, gt=0.0, le=0.3)
    """Lower than this is the ground's texture, m: the gait crosses it and the leg stops
    on it (6.7.4's first kind); about the default step's height."""
    see_m: float = Field(0.7, gt=0.1, le=1.4)
    """Stop when a risen point is this near the rangefinders, m (level, along the ray):
    a mount pitched 20° down meets the ground 0.75 m ahead, and a 5 cm rise 0.66 m."""
    climb_m: float = Field(0.1, gt=0.0, le=0.35)
    """The highest obstacle it climbs, m: the tetrapod's 120 mm step (Table 5.9,
    ``locomotion.max_step_height_mm``) clears it by 2 cm."""
    clearance_m: float = Field(0.03, ge=0.0, le=0.2)
    """The step clears a climbed obstacle by this much, m."""
    scan_deg: float = Field(12.0, gt=0.0, le=30.0)
    """The trochanter sweep either side of its angle, degrees (the body sways by the
    legs' length × sin of it over its feet: 6 cm at 12°)."""
    scan_step_deg: float = Field(2.0, gt=0.0, le=10.0)
    """One reading every this much of the sweep, degrees."""
    settle_s: float = Field(0.3, gt=0.0, le=5.0)
    """Each sweep step's wait before its reading, s: the trochanters' travel and a
    sensor frame."""
    max_face_deg: float = Field(50.0, gt=0.0, lt=90.0)
    """A rise steeper than this is an obstacle's face, degrees; gentler, a slope (the
    steepest the robot walks: 32°, 6.7.6, with margin)."""
    tolerance_m: float = Field(0.02, gt=0.0, le=0.1)
    """Points within this of the highest belong to the top, m (the sensor's noise)."""
    pass_m: float = Field(1.0, ge=0.0, le=3.0)
    """After the obstacle's depth, the raised step is kept this much further, m: the
    rear feet stand 0.65 m behind the rangefinders (the sensors 0.35 m ahead of the
    body's centre, the rear feet 0.3 m behind it), and the walk slips a little."""
    level_m: float = Field(0.025, gt=0.0, le=0.3)
    """Front feet this much above or below the rear ones: the robot stands across a change
    of ground, and nothing stops it (the rays' frame is the feet's plane), m."""
    confirm_frames: int = Field(6, ge=1, le=100)
    """Readings in a row of one rangefinder that must see a rise before it stops the
    walk: the floor's points reach 7 cm for up to 4 frames while walking (the body's
    sway; 1 % of frames, docs/reflexes.md); an obstacle stays in view for seconds."""
    learn_tau_s: float = Field(0.5, gt=0.0, le=60.0)
    """Time constant of each rangefinder's scale, learnt against the floor while the robot
    keeps still, s."""
    max_scale_error: float = Field(0.25, ge=0.0, le=0.5)
    """A floor reading implying a scale further than this from 1 is not learnt from
    (something stands in front): the Sharp GP2Y0A21YK's output swing spreads ±13 % part
    to part (data sheet), ±23 % of distance through eq. 5.5's exponent."""
    uneven_m: float = Field(0.015, gt=0.0, le=0.3)
    """A stance foot this far above or below the feet's mean height: the robot stands on
    uneven ground, its body rocked over it (a foot at a trench's edge), and nothing stops
    it, m. Walking on the flat the feet stay within 5 mm (docs/reflexes.md)."""
    clear_s: float = Field(1.0, ge=0.0, le=30.0)
    """A blocked way is free once the rangefinders have seen nothing risen within
    ``see_m`` for this long, s."""


class ObstacleReflex(Reflex):
    """Stops before an obstacle, measures it, climbs it or keeps off it (module
    docstring)."""

    inputs = ("ranges", "locomotion", "motion", "legs")
    priority = 30
    inhibits = ("reflex-searching", "reflex-stepping", "reflex-elevator")
    """While it stops and measures, the legs' own reflexes are held back: a swing put
    down by the halt, a foot carried by the sweep, are no lost ground nor slip."""
    Params = ObstacleParams
    params: ObstacleParams

    def __init__(self, params: ReflexParams, *, name: str, cfg: RobotConfig) -> None:
        super().__init__(params, name=name, cfg=cfg)
        self.mount = math.radians(cfg.ir.pitch_deg)
        chain = fk_chain(np.zeros(5), cfg.leg_geometry())
        self.femur_dz = float(chain[1, 2])
        """The femur joint (the sensors' axis) above the coxa joint, m (eq. 4.4–4.6)."""
        self.femur_reach = float(math.hypot(chain[1, 0], chain[1, 1]))
        """… and out from it, m: where the rays start along the leg."""
        self.mounts = {
            i: (cfg.legs[i].mount_mm[0] / 1000, cfg.legs[i].mount_mm[1] / 1000) for i in FRONT_LEGS
        }
        """Front leg → its coxa joint's (x, y) in the body frame, m."""
        self.phase: Literal["watching", "stopping", "scanning", "climbing", "blocked"] = "watching"
        self.odometer = 0.0
        """How far the body has gone forward, m (the coordinator's twist, integrated)."""
        self.ignore_until = -math.inf
        """Odometer reading before which risen points are what was measured last."""
        self.climb_until = 0.0
        self.state: LocomotionState | None = None
        self.state_t: float | None = None
        self.trochanter = 0.0
        self.pose_z = 0.0
        self.pose_pitch = 0.0
        self.angles: list[float] = []
        self.step_t = 0.0
        self.points: list[tuple[float, float]] = []
        self.clear_since: float | None = None
        self.seen: Profile | None = None
        """The last sweep's profile."""
        self.frames = [0, 0]
        """Per rangefinder, how many readings in a row have seen something risen."""
        self.scale = [1.0, 1.0]
        """Each rangefinder's scale (right, left), learnt against the floor."""
        self.learnt = False
        self.learn_t: float | None = None
        self.foot_z: dict[int, float] = {}
        """Leg → its stance foot's height in the body frame, m (its latest)."""
        self.foot_x: dict[int, float] = {}
        """… and how far forward it stands, m."""
        self.foot_along: dict[int, float] = {}
        """Front leg → how far along the rays its stance foot stands from the sensor, m."""

    # ------------------------------------------------------------------ inputs

    def react(self, t: float, msg: Message) -> Iterable[Command]:
        if isinstance(msg, LegState):
            if msg.contact and msg.measured_foot is not None:
                x, y, z = msg.measured_foot
                self.foot_z[msg.leg], self.foot_x[msg.leg] = z, x
                if msg.leg in self.mounts:
                    mx, my = self.mounts[msg.leg]
                    reach = math.hypot(x - mx, y - my)
                    self.foot_along[msg.leg] = reach - self.femur_reach
            return ()
        if isinstance(msg, BodyMotion):
            self.trochanter = msg.trochanter_rad
            self.pose_z, self.pose_pitch = msg.pose[2], msg.pose[4]
            return ()
        if isinstance(msg, LocomotionState):
            return self._state(t, msg)
        if isinstance(msg, ObstacleRanges):
            return self._ranges(t, msg)
        return ()

    def height(self) -> float:
        """The rays' height above the ground the front feet stand on, m."""
        front = [self.foot_z[i] for i in FRONT_LEGS if i in self.foot_z]
        if front:
            return self.femur_dz - sum(front) / len(front)
        preset = self._stance()
        coxa = (preset.height_mm if preset is not None else 290.0) / 1000
        return coxa + self.pose_z + self.femur_dz

    def down(self) -> float:
        """The rays' pitch below the plane of the feet, rad: the mount less the trochanter's
        tilt, plus the plane's rise ahead in the body frame (the body pitched nose down
        over it, a foot gone down into a hole; before any foot, the body's pose)."""
        ray = self.mount + RAY_DOWN_PER_TROCHANTER * self.trochanter
        legs = list(self.foot_z)
        if len(legs) < 3:
            return ray + self.pose_pitch
        xs = [self.foot_x[i] for i in legs]
        zs = [self.foot_z[i] for i in legs]
        mx, mz = sum(xs) / len(xs), sum(zs) / len(zs)
        var = sum((x - mx) ** 2 for x in xs)
        if var < 1e-4:
            return ray + self.pose_pitch
        rise = sum((x - mx) * (z - mz) for x, z in zip(xs, zs, strict=True)) / var
        return ray + math.atan(rise)

    def _points(self, m: ObstacleRanges, h: float, down: float) -> list[tuple[float, float] | None]:
        """Each rangefinder's point (right, left) for rays at height ``h`` pitched ``down``;
        None where it gives no reading."""
        return [
            None if d is None else ray_point(d * k, down, h)
            for d, k in zip(m.distances_m, self.scale, strict=True)
        ]

    def _learn(self, t: float, m: ObstacleRanges, h: float, down: float, bent: bool) -> None:
        """Keeping still on level feet, each ray meets the floor at h / sin(down): its
        reading against that is the sensor's scale (module docstring)."""
        dt = 0.0 if self.learn_t is None else min(t - self.learn_t, 1.0)
        self.learn_t = t
        s, p = self.state, self.params
        still = s is not None and s.activity in STILL and all(abs(v) <= STILL_M_S for v in s.twist)
        front = [i for i in FRONT_LEGS if i in self.foot_z]
        if not still or len(front) < len(FRONT_LEGS) or bent or down < 0.05:
            return
        floor = h / math.sin(down)
        k = min(1.0, dt / p.learn_tau_s)
        for i, d in enumerate(m.distances_m):
            if d is None or not math.isfinite(d) or d <= 0.0:
                continue
            ratio = floor / d
            if abs(ratio - 1.0) <= p.max_scale_error:
                self.scale[i] += (ratio - self.scale[i]) * (k if self.learnt else 1.0)
                self.learnt = True

    def bent(self) -> bool:
        """The feet do not stand in one plane: the front pair ``level_m`` or more above or
        below the rear pair (a ramp's foot, a box's edge under the robot), or one foot
        ``uneven_m`` from their mean height. The rays' frame is the feet's plane, so their
        picture is not trusted then: no stop."""
        front = [self.foot_z[i] for i in FRONT_LEGS if i in self.foot_z]
        rear = [self.foot_z[i] for i in REAR_LEGS if i in self.foot_z]
        if not front or not rear:
            return False
        if abs(sum(front) / len(front) - sum(rear) / len(rear)) >= self.params.level_m:
            return True
        mean = sum(self.foot_z.values()) / len(self.foot_z)
        return any(abs(z - mean) >= self.params.uneven_m for z in self.foot_z.values())

    def _risen(self, points: Iterable[tuple[float, float]]) -> bool:
        p = self.params
        return any(x <= p.see_m and z >= p.min_height_m for x, z in points)

    def _state(self, t: float, s: LocomotionState) -> Iterable[Command]:
        if self.state_t is not None and s.mode == "walk":
            self.odometer += s.twist[0] * max(0.0, t - self.state_t)
        self.state, self.state_t = s, t
        still = all(abs(v) <= STILL_M_S for v in s.twist)
        if self.phase == "stopping" and s.activity not in WALKING and still:
            return self._start_sweep(t)
        if self.phase == "climbing" and self.odometer >= self.climb_until:
            self.phase, self.active = "watching", False
            return (self.request(t, step_height_m=0.0, reason="past the obstacle"),)
        return ()

    # ------------------------------------------------------------------ phases

    def _ranges(self, t: float, m: ObstacleRanges) -> Iterable[Command]:
        h, down = self.height(), self.down()
        bent = self.phase == "watching" and self.bent()
        if self.phase == "watching":
            self._learn(t, m, h, down, bent)
        each = self._points(m, h, down)
        points = [p for p in each if p is not None]
        s = self.state
        if self.phase == "watching":
            forward = s is not None and s.activity in WALKING and s.twist[0] > STILL_M_S
            for i, p in enumerate(each):
                risen = p is not None and self._risen([p])
                self.frames[i] = self.frames[i] + 1 if risen else 0
            fresh = self.odometer >= self.ignore_until and not bent
            if forward and fresh and max(self.frames) >= self.params.confirm_frames:
                self.phase, self.active = "stopping", True
                self.reason = "something ahead: stopping to measure it"
                return (self.request(t, halt=True, reason=self.reason),)
            return ()
        if self.phase == "scanning":
            return self._sweep(t, points)
        if self.phase == "blocked":
            if self._risen(points):
                self.clear_since = None
            elif self.clear_since is None:
                self.clear_since = t
            if self.clear_since is not None and t - self.clear_since >= self.params.clear_s:
                self.phase, self.active = "watching", False
                return (self.request(t, block_ahead=False, reason="the way ahead is clear"),)
        return ()

    def _start_sweep(self, t: float) -> Iterable[Command]:
        p = self.params
        n = max(1, round(2 * p.scan_deg / p.scan_step_deg))
        # The rays down first (the ground before the obstacle), then up over it.
        sweep = np.linspace(p.scan_deg, -p.scan_deg, n + 1) * RAY_DOWN_PER_TROCHANTER
        self.angles = [self.trochanter + math.radians(float(a)) for a in sweep]
        self.points = []
        self.phase = "scanning"
        return self._aim(t)

    def _aim(self, t: float) -> Iterable[Command]:
        self.step_t = t
        # 0 would withdraw the request: the coordinator's own angle, which is the base
        angle = self.angles[0] or 1e-9
        return (self.request(t, trochanter_rad=angle, reason="measuring the obstacle"),)

    def _sweep(self, t: float, points: list[tuple[float, float]]) -> Iterable[Command]:
        if t - self.step_t < self.params.settle_s:
            return ()
        self.points.extend(points)
        self.angles.pop(0)
        if self.angles:
            return self._aim(t)
        return self._decide(t)

    def _decide(self, t: float) -> Iterable[Command]:
        p = self.params
        sort = partial(
            profile,
            self.points,
            min_height=p.min_height_m,
            tolerance=p.tolerance_m,
            max_face_deg=p.max_face_deg,
            origin=self.height(),
        )
        seen = sort(ground=min(self.foot_along.values(), default=math.inf))
        if seen.kind == "slope" and not seen.face_seen:
            # No ray saw its face: a ramp whose foot is under the sensors, or a step as near.
            # A step low enough to climb is climbed (a high step costs a ramp nothing); a
            # higher one, kept off for good, would strand the robot at a ramp.
            upright = sort()
            if upright.kind == "obstacle" and upright.top_seen and upright.height <= p.climb_m:
                seen = replace(upright, face_seen=False)  # its face taken upright
        self.seen = seen
        yaw = math.radians(self._yaw())
        ahead = seen.front * math.cos(yaw) if math.isfinite(seen.front) else 0.0
        if seen.kind != "obstacle":
            self.phase, self.active = "watching", False
            self.ignore_until = self.odometer + ahead + p.pass_m
            what = "a slope" if seen.kind == "slope" else "nothing"
            return (self.request(t, trochanter_rad=0.0, halt=False, reason=f"{what} ahead"),)
        done = self.request(t, trochanter_rad=0.0, halt=False, reason="measured")
        size = f"{seen.height * 100:.0f} cm high, {seen.depth * 100:.0f} cm deep"
        if seen.top_seen and seen.height <= p.climb_m:
            self.phase, self.active = "climbing", False  # the legs' reflexes free again
            self.climb_until = self.odometer + ahead + seen.depth * math.cos(yaw) + p.pass_m
            self.ignore_until = self.climb_until
            self.reason = f"climbing an obstacle {size}"
            return (
                done,
                self.request(t, step_height_m=seen.height + p.clearance_m, reason=self.reason),
            )
        self.phase, self.clear_since = "blocked", None
        high = "higher than the sweep" if not seen.top_seen else size
        self.reason = f"keeping off an obstacle {high}"
        return (done, self.request(t, block_ahead=True, reason=self.reason))

    def _stance(self) -> StanceSpec | None:
        """The stance the coordinator stands in (the configured one before it says)."""
        stance = self.state.stance if self.state is not None else self.cfg.locomotion.stance
        return self.cfg.stances.get(stance)

    def _yaw(self) -> float:
        """The front coxae's yaw in the stance, degrees: the rays look that way."""
        preset = self._stance()
        return preset.front_rear_yaw_deg if preset is not None else 0.0
