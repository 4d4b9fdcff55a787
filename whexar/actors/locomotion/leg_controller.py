"""The leg controller: one leg's policy, a plain class (Žák 2023, 4.2.6, 5.4).

Theory of operation
-------------------
:meth:`LegController.cycle` is one control cycle of one leg: it takes the
time, the cycle's :class:`ServoStates` and whatever arrived since the last
cycle — the coordinator's :class:`StepCommand` s and newest
:class:`BodyMotion`, the force sensors (:class:`LegLoads`), override goals —
and returns, in order, what the leg says: its events, the goals that
changed (:class:`JointGoals`), how its swing ended (:class:`SwingEnded`) and
its :class:`LegState`. No ``await``, no channel, no clock: the actor
(:mod:`whexar.actors.locomotion.leg`) only receives, calls and publishes.

In a cycle the leg

1. advances its foot along the step it executes, in the *upright frame*:
   the body frame of a robot standing on its feet (x forward, y left, z up,
   the ground below). A swing follows the commanded shape from wherever the
   foot lifted to the target; a foot on the ground is carried by the body's
   stepping twist, p ← p − (v + ω ẑ × p)·dt; a move follows a minimum-jerk
   path (in joint space the first time, from whatever pose the servos
   report, so it never passes outside the limits);
2. turns the foot into joint angles: body pose (eq. 3 of Diosdado 2014,
   3.2), leg frame, inverse kinematics (eq. 4.7–4.19) with the trochanter at
   the angle the coordinator gives (the body pitch, eq. 4.18), which carries
   the foot on its arc as the thesis's leg does (the stride stays parallel to
   the ground; :func:`~whexar.kinematics.leg.trochanter_arc`). An IK that
   fails holds the last good pose and says so (:class:`IkFailed`);
3. applies the overrides (below): the leg alone decides each of its joints'
   goals;
4. steers and drives the wheel: direction = s·ψ − coxa (5.1), wheel rate =
   speed / radius (eq. 5.18), the wheel stopped whenever the foot is in the
   air;
5. says the goals that changed by half a tick or more (the bus keeps the
   others) and its :class:`LegState`.

Adaptive swing (Diosdado 2014, 3.5–3.6): contact is the leg's contact
estimate (:mod:`whexar.kinematics.contact`: the force sensor, else the femur
current, with a confidence; a sensor set aside or taken back is a
:class:`ContactDegraded` or :class:`ContactRestored` event), or, for a foot
searching down, the ground holding it (its goal error grown by
``contact.search_stop_m``). Each swing's end is a :class:`SwingEnded`
(:mod:`.steps`): the typed signal a reflex subscribes to. A settling move that
comes while a foot searches carries the search on; another step on the ground
(the walk stops) leaves an awaited touchdown to be judged when due; only a new
swing judges it at once. A swing stopped early stands where the joints hold the
foot across the ground (:mod:`.tracking`).

The leg flip (6.8.1): when :class:`BodyMotion` says ``upside_down`` changed,
the trochanter turns by 180° while the other joints hold: the leg, rotated
about its own long axis, now reaches the ground on the robot's back. With
the trochanter at −π, IK is the upright IK of the mirrored leg.

Overrides (the interface the reactive layer uses): :class:`JointGoals`
marked ``reflex`` on the leg's override input take its positioning joints
over for ``locomotion.reflex_hold_s``, the highest priority winning, then
blend back over ``locomotion.reflex_blend_s`` (:mod:`.overrides`); the leg's
own trajectory goes on underneath, and the leg alone decides its joints' goals.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Final

from whexar.actors.locomotion.frames import LegFrame
from whexar.actors.locomotion.overrides import Overrides
from whexar.actors.locomotion.steps import (
    Step,
    StepSpec,
    advance,
    begin,
    interrupted,
    load_error,
)
from whexar.actors.locomotion.tracking import Lift, Tracked, stand_where_stopped, tracked
from whexar.actors.locomotion.wire_goals import WireGoals
from whexar.actors.messages import (
    BodyMotion,
    ContactDegraded,
    ContactRestored,
    IkFailed,
    JointGoals,
    LegLoads,
    LegState,
    ServoStates,
    StepCommand,
    SwingEnded,
)
from whexar.config import ContactSource, RobotConfig
from whexar.errors import KinematicsError
from whexar.kinematics.contact import ContactEstimator, segment_load
from whexar.kinematics.leg import fk_point, ik_point, trochanter_arc
from whexar.kinematics.trajectory import SwingOutcome, min_jerk, swing_table
from whexar.robot import N_JOINTS, POSITIONING_JOINTS
from whexar.runtime.messages import Message

FLIPPED_TROCHANTER: Final = -math.pi
"""Trochanter angle of a flipped leg: Goal Position tick 0, inside the register's turn."""
_POSITIONING: Final = len(POSITIONING_JOINTS)


class LegController:
    """One leg's policy: steps, stance, swing, IK, wheel, contact, overrides (module
    docstring). ``name`` is the ``source`` of what it says; ``report`` makes it say its
    :class:`LegState` every cycle."""

    def __init__(
        self,
        cfg: RobotConfig,
        leg: int,
        *,
        name: str,
        contact: ContactSource | None = None,
        report: bool = True,
    ) -> None:
        self.cfg = cfg
        self.loco = cfg.locomotion
        self.leg = leg
        self.name = name
        self.report = report
        self.geometry = cfg.leg_geometry()
        self.contact_source: ContactSource = contact or self.loco.contact
        self.frame = LegFrame(self.geometry, leg)
        """This leg's frame in the upright frame, through the body pose."""
        self.side = self.frame.side
        self.flip: tuple[float, float, float] | None = None
        """(start_t, from, to) of a trochanter flip under way."""
        self.flip_to = False
        self.trochanter = 0.0
        self.foot: list[float] | None = None
        self.angles: list[float] | None = None
        """The last good positioning angles (coxa…tarsus) from the IK."""
        self.lift = Lift()
        """How high the joints have lifted the foot in the step under way."""
        self.measured: list[float | None] = [None] * N_JOINTS
        self.read_t = [-math.inf] * N_JOINTS  # when each joint's position was last read
        self.currents: list[float | None] = [None] * N_JOINTS
        self.step: Step | None = None
        self.twist = (0.0, 0.0, 0.0)
        self.last_t: float | None = None
        self.cycle_no = 0
        self.ik_ok = True
        self.contact = False
        self.confidence = 0.0
        self.phase = "idle"
        """The phase of the last cycle: the contact estimate's expectation."""
        self.fsr_t = -math.inf
        self.fsr_contact: bool | None = None
        self.femur_current: float | None = None
        self.current_t = -math.inf
        self.estimator = ContactEstimator(
            cfg.contact.model(self.loco.contact_current_a), self.contact_source
        )
        self.spec = StepSpec.of(cfg.contact)
        self.unjudged: Step | None = None
        """A swing whose touchdown a step on the ground interrupted: judged when due."""
        self.search_stop_m = cfg.contact.search_stop_m
        self.load_error: float | None = None  # counts under the loaded feet's mean (steps)
        self.foot_error: float | None = None
        """The foot's distance from its goals' point at the last state (``foot_error_m``)."""
        self.search_from: float | None = None
        """The foot error when the present search began."""
        self.overrides = Overrides(leg, self.loco.reflex_hold_s, self.loco.reflex_blend_s)
        self.wheel_radius = self.geometry.wheel_radius
        self.wire = WireGoals(name, leg)
        self.sent = self.wire.sent  # per joint (rad, or rad/s for the wheel); inf: none yet
        self.steer = False
        self.heading = 0.0
        self.speed = 0.0
        self.femur = self.geometry.femur
        self.tibia = self.geometry.tibia
        self._out: list[Message] = []
        self._now = 0.0

    # ----------------------------------------------------------------- inputs

    def _take_motion(self, motion: BodyMotion | None) -> None:
        if motion is None:
            return
        self.twist = motion.twist
        self.steer = (motion.steer or self.leg in motion.steer_legs) and not motion.upside_down
        self.heading = motion.wheel_heading_rad[self.leg]
        self.speed = motion.wheel_speed_m_s[self.leg]
        if motion.pose != self.frame.pose:
            self.frame.set_pose(motion.pose)
        if motion.upside_down != self.frame.upside_down and self.flip is None:
            self.flip = (
                motion.t,
                FLIPPED_TROCHANTER if self.frame.upside_down else self.trochanter,
                FLIPPED_TROCHANTER if motion.upside_down else 0.0,
            )
            self.flip_to = motion.upside_down
        if self.flip is None and not self.frame.upside_down:
            self.trochanter = motion.trochanter_rad

    def _begin(self, cmd: StepCommand) -> None:
        shape = None
        if cmd.kind == "swing":
            shape = swing_table(cmd.trajectory, cmd.duty_factor)
        joint_space = None
        origin = list(self.foot) if self.foot is not None else [0.0, 0.0, 0.0]
        if cmd.kind == "move" and (self.foot is None or self.angles is None):
            # First move after start: from the pose the servos report, in joint space.
            start = [m if m is not None else 0.0 for m in self.measured[:_POSITIONING]]
            goal = self._solve(cmd.target)
            if goal is None:
                goal = list(start)
            joint_space = (start, goal)
            origin = list(self.frame.from_leg(fk_point(start, self.geometry)))
        elif cmd.kind in ("stance", "hold") and self.foot is None:
            return  # nothing to hold yet: the first command must place the foot
        waiting = self.unjudged
        if waiting is not None and cmd.kind == "swing":  # lifted again: judged now
            self.unjudged = None
            self._swing_ended(cmd.start_t, waiting.judged(self.contact), waiting)
        old, what = self.step, None
        if old is not None and old.awaiting:  # a new step before its touchdown was judged
            what = interrupted(old, cmd, self.contact)
            if what == "judge":
                self._swing_ended(cmd.start_t, old.judged(self.contact), old)
            elif what == "wait":
                self.unjudged = old
        self.step = begin(cmd, origin, shape, joint_space, self.spec)
        self.lift.reset()
        if old is not None and what == "carry":
            self.step.carry_search(old)
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
                    self.read_t[j.joint] = states.t
                currents[j.joint] = amps = j.current_a
                if amps is not None and j.joint == 2:
                    self.femur_current, self.current_t = amps, states.t

    def _take_loads(self, loads: LegLoads | None) -> None:
        if loads is not None:
            self.fsr_t = loads.t
            self.fsr_contact = loads.contacts[self.leg]
            if self.spec.balance_gain > 0.0:  # for a stance asked to share its load
                self.load_error = load_error(loads.counts, loads.contacts, self.leg)

    # ----------------------------------------------------------------- contact

    def _contact(self, t: float) -> tuple[bool, str]:
        est = self.estimator.estimate(
            t,
            self.phase,
            fsr=self.fsr_contact,
            fsr_t=self.fsr_t,
            current_a=self.femur_current,
            current_t=self.current_t,
        )
        self.confidence = est.confidence
        for c in self.estimator.take_changes():
            event = ContactRestored if c.usable else ContactDegraded
            self._out.append(
                event(t=self._now, source=self.name, leg=self.leg, sensor=c.sensor, reason=c.reason)
            )
        return est.contact, est.source

    def _stopped_by_ground(self) -> bool:
        """A searching foot the ground holds: its goal went on down, the foot did not."""
        err = self.foot_error
        if err is not None and self.search_from is None:
            self.search_from = err
        return err is not None and err - (self.search_from or 0.0) >= self.search_stop_m

    def load(self) -> tuple[float | None, float | None]:
        """eq. 5.19 for the femur and tibia segments (:func:`segment_load`)."""
        i, q = self.currents, self.measured
        return segment_load(i[2], self.femur, q[3]), segment_load(i[3], self.tibia, q[4])

    # ----------------------------------------------------------------- the foot

    def _swing_ended(self, t: float, outcome: SwingOutcome, step: Step) -> None:
        assert self.foot is not None
        self._out.append(
            SwingEnded(
                t=t,
                source=self.name,
                leg=self.leg,
                outcome=outcome,
                ground_offset_m=self.foot[2] - step.ground(),
                confidence=self.confidence,
            )
        )

    # ----------------------------------------------------------------- IK and goals

    def _solve(
        self, p: list[float] | tuple[float, float, float], ground_z: float | None = None
    ) -> list[float] | None:
        """Joint angles for foot point ``p`` (upright frame), the trochanter carrying the
        foot on its arc (:func:`trochanter_arc`) about the point on the ground below it:
        ``ground_z`` is the ground's height there (``None``: ``p`` is on the ground)."""
        pitch = 0.0 if self.frame.upside_down or self.flip is not None else self.trochanter
        q = self.frame.to_leg(p)
        if pitch != 0.0:
            depth = None if ground_z is None else self.frame.to_leg((p[0], p[1], ground_z))[1]
            q = trochanter_arc(q, pitch, depth)
        try:
            solution = ik_point(q, self.geometry, pitch=pitch, target="contact")
        except KinematicsError as exc:
            if self.ik_ok:
                self.ik_ok = False
                x, y, z = p
                self._out.append(
                    IkFailed(
                        t=self._now,
                        source=self.name,
                        leg=self.leg,
                        target=(x, y, z),
                        reason=str(exc),
                    )
                )
            return None
        self.ik_ok = True
        return list(solution)

    def _trochanter_at(self, t: float) -> float:
        if self.flip is None:
            return FLIPPED_TROCHANTER if self.frame.upside_down else self.trochanter
        start, a, b = self.flip
        u = (t - start) / self.loco.flip_s
        if u >= 1.0:
            self.flip = None
            self.frame.upside_down = self.flip_to
            if self.foot is not None:
                self.foot[1] = -self.foot[1]  # the same leg pose, seen from the other side
            return b
        return a + (b - a) * min_jerk(u)

    def _goals(self, t: float, angles: list[float], airborne: bool) -> JointGoals | None:
        """This cycle's goals that differ from the ones last said (:mod:`.wire_goals`;
        None: nothing new)."""
        if self.steer and not self.frame.upside_down:
            # direction = s·ψ − coxa (wheels.direction_for_heading, 5.1), within one turn.
            direction = self.side * self.heading - angles[0]
            direction = (direction + math.pi) % (2 * math.pi) - math.pi
        else:
            direction = 0.0
        speed = 0.0 if airborne or not self.steer or self.frame.upside_down else self.speed
        # The positioning joints, then the direction; the wheel's velocity.
        return self.wire.changed(t, enumerate((*angles, direction)), speed / self.wheel_radius)

    def take_overrides(self, now: float, overrides: Iterable[JointGoals]) -> JointGoals | None:
        """Override goals that arrive between two cycles, taken at once (the priority
        decides, as in a cycle): the goals of the joints they now hold, to send the bus
        straight away — it writes them at its next cycle, not one cycle later. ``None``:
        nothing new for the bus (or the leg not yet placed)."""
        self.overrides.take(now, overrides)
        if self.foot is None or self.angles is None:
            return None
        held = sorted(self.overrides.held.items())
        return self.wire.changed(now, ((joint, angle) for joint, (angle, _, _) in held))

    # ----------------------------------------------------------------- the cycle

    def cycle(
        self,
        now: float,
        states: ServoStates,
        *,
        motion: BodyMotion | None = None,
        loads: LegLoads | None = None,
        overrides: Iterable[JointGoals] = (),
        steps: Iterable[StepCommand] = (),
    ) -> list[Message]:
        """One control cycle (module docstring): ``states`` is the cycle's servo states,
        ``now`` the clock's time (events are stamped with it), the rest what arrived since
        the last cycle (``motion`` and ``loads`` the newest, if any). Returns what the leg
        says, in order: events, :class:`SwingEnded`, :class:`JointGoals`,
        :class:`LegState`."""
        self._now = now
        out = self._out = []
        t = states.t
        dt = 0.0 if self.last_t is None else t - self.last_t
        self.last_t = t
        self.cycle_no = states.cycle
        self._take_state(states)
        self._take_motion(motion)
        self._take_loads(loads)
        self.overrides.take(now, overrides)
        for cmd in steps:
            if cmd.leg == self.leg:
                self._begin(cmd)
        contact, source = self._contact(t)
        if self.phase == "search" and not contact:
            contact = self._stopped_by_ground()
        self.contact = contact
        waiting = self.unjudged
        if waiting is not None and (contact or waiting.touchdown_due(t)):
            self.unjudged = None
            self._swing_ended(t, waiting.judged(contact), waiting)
        phase, progress, outcome, before = "idle", 0.0, None, None
        if self.step is not None and self.foot is not None:
            # The stance shares its load while the estimate reads the force sensors.
            balance = self.load_error if source == "fsr" else None
            before = (self.foot[0], self.foot[1], self.foot[2])  # what the goals sent came from
            raised = self.lift.raised()  # only a lifted foot's swing can be blocked
            phase, progress, outcome = advance(
                self.step, self.foot, self.twist, t, dt, contact, source, balance, raised
            )
            if outcome is not None:
                self._swing_ended(t, outcome, self.step)
        if self.foot is None:
            return out  # no command yet: the bus holds the servos where they stand
        troch = self._trochanter_at(t)
        # Where the joints hold the foot, against the goals (.tracking): read once a cycle.
        seen = tracked(self.measured, self.read_t, self.sent, t, troch, self.geometry, self.frame)
        step = self.step
        if step is not None and step.kind == "swing":
            self.lift.see(seen)
            if outcome == "early_contact" and before is not None and self.lift.enough(step.height):
                stand_where_stopped(self.foot, before, seen)  # .tracking: off an edge
        angles: list[float] | None
        if step is not None and step.joint_space is not None and phase == "move":
            a, b = step.joint_space
            s = min_jerk(progress)
            angles = [x + (y - x) * s for x, y in zip(a, b, strict=True)]
        elif self.flip is not None and self.angles is not None:
            angles = list(self.angles)
            phase = "flip"
        else:
            # A foot in the air (a swing, a lifted move) takes the arc of the ground it
            # lands on: its path keeps its shape, shifted as the stance feet are.
            ground = step.target[2] if step is not None and step.height > 0.0 else None
            angles = self._solve(self.foot, ground)
        if angles is None:
            angles = self.angles
            if angles is None:
                return out
        else:
            self.angles = angles
        angles = list(angles)
        angles[1] = troch
        if self.overrides:
            angles, held = self.overrides.apply(t, angles)
            if held:
                phase = "reflex"
        airborne = phase in ("swing", "flip") or (
            phase == "move" and step is not None and step.height > 0.0
        )
        goals = self._goals(t, angles, airborne)
        if goals is not None:
            out.append(goals)
        if phase != "search":
            self.search_from = None
        self.phase = phase
        if self.report:
            out.append(self._state(t, phase, progress, seen, contact, source))
        return out

    def _state(
        self,
        t: float,
        phase: str,
        progress: float,
        seen: Tracked | None,
        contact: bool,
        source: str,
    ) -> LegState:
        measured = None if seen is None else seen.measured
        error = None if seen is None else seen.error
        if error is not None:
            self.foot_error = error
        assert self.foot is not None
        foot = self.foot
        return LegState(
            t=t,
            source=self.name,
            leg=self.leg,
            cycle=self.cycle_no,
            phase=phase,
            progress=progress,
            foot=(foot[0], foot[1], foot[2]),
            measured_foot=measured,
            contact=contact,
            contact_source=source,
            load=self.load(),
            ik_ok=self.ik_ok,
            contact_confidence=self.confidence,
            foot_error_m=error,
            touchdown_pending=self.unjudged is not None
            or (self.step is not None and self.step.awaiting),
        )
