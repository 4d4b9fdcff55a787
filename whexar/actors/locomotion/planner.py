"""The locomotion planner: the coordinator's policy, a plain class (Žák 2023, 4.2.5, 5.4,
6.3–6.8).

Theory of operation
-------------------
:meth:`LocomotionPlanner.cycle` is one control cycle of the coordinator. It
takes the cycle's :class:`ServoStates` and what arrived since the last one
(:class:`MotionCommand` s, the legs' :class:`LegState` s, the newest
:class:`BodyTilt`) and returns what the coordinator says, in order: events,
:class:`StepCommand` s, :class:`BodyMotion` for the legs and
:class:`LocomotionState`. In a cycle it

1. checks each command and merges it into the *wanted* state
   (:mod:`.intent`: clamped with an event, or refused whole);
2. ramps the body's velocity toward the wanted one (``max_accel_m_s2``);
3. runs what it is doing: a *script* (:mod:`.scripts`: stand up, sit down,
   change stance, walk ↔ ride, flip) or a steady engine (the gait, riding,
   the hybrid gait), its activity changing only along the table of
   :mod:`.activity`;
4. says the body motion (twist, pose, trochanter, wheels) and its state.

Everything is planned in the *upright frame* (the body frame of a robot on
its feet, z up from the ground); upside down, the legs mirror it (6.8.1).

The steady engines (gait, riding, hybrid) and their limits are :mod:`.engines`.

A gait change, a stance change and walk ↔ ride first wind down (no new
lift-offs, the body stops, the swings land), then run their script, then
resume. On a stop or a safe stop the robot sits down (:meth:`begin_sit`),
cycled by :meth:`stop_cycle` once the actor no longer runs its loop.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Final

from whexar.actors.locomotion.activity import QUIET, STEADY, Activity
from whexar.actors.locomotion.core import SETTLE_S, STILL, Script
from whexar.actors.locomotion.engines import ramp
from whexar.actors.locomotion.intent import refused, take_command
from whexar.actors.locomotion.losses import WalkOnLosses
from whexar.actors.locomotion.settle import SETTLE_PERIOD_S, settled
from whexar.actors.messages import (
    BodyMotion,
    BodyTilt,
    GaitChoice,
    LegState,
    LocomotionState,
    MotionCommand,
    ReflexRequest,
    ServoStates,
)
from whexar.config import RobotConfig
from whexar.kinematics.gait import AUTO_GAIT, GAITS
from whexar.robot import N_LEGS
from whexar.runtime.messages import Message

CONTACT_GRID_M: Final = 0.005
"""Measured feet are rounded to this grid before the wheels' kinematics use them."""
BUS_SILENT_S: Final = 0.2
"""No servo states for this long: the bus cannot carry out a sit-down any more."""
SIT_MARGIN_S: Final = 4 * SETTLE_S
"""How much longer than ``sit_down_s`` a sit-down before a stop may take."""
_POSE_RATES: Final = (0.1, 0.1, 0.1, math.radians(20), math.radians(20), math.radians(20))
"""Body pose change per transition (m, rad): x, y, z, roll, pitch, yaw."""


class LocomotionPlanner(WalkOnLosses):
    """The coordinator's policy: gaits, riding, stances, transitions (module docstring).

    ``name`` is the ``source`` of what it says; ``report`` makes it say its
    :class:`LocomotionState` every cycle."""

    def __init__(self, cfg: RobotConfig, *, name: str, report: bool = True) -> None:
        super().__init__(cfg, name=name)
        self.report = report
        self.tilt_pitch = 0.0
        self.tilt_roll = 0.0
        self.tilt_measured = (0.0, 0.0)
        self.max_trochanter = math.radians(self.loco.max_trochanter_deg)
        self.last_t: float | None = None
        self.last_states_t = -math.inf
        self.cycle_no = 0
        self.script = self.stand_up()  # the first script stands the robot up
        self.stopping = False
        """A safe stop is under way: the robot sits down and takes no more commands."""
        self.stop_reason = "a safe stop is under way"
        """Why commands are refused while :attr:`stopping`."""
        self.margin_m = math.inf
        self.gait_choice: str = self.loco.gait
        """The gait selector's latest choice: the gait while the operator asks for auto."""

    # ----------------------------------------------------------------- the cycle

    def cycle(
        self,
        states: ServoStates,
        *,
        commands: Iterable[MotionCommand] = (),
        legs: Iterable[LegState] = (),
        tilt: BodyTilt | None = None,
        tilt_wired: bool = False,
        requests: Iterable[ReflexRequest] = (),
        gait_choice: GaitChoice | None = None,
    ) -> list[Message]:
        """One control cycle (module docstring); ``tilt_wired`` says whether a tilt input
        exists at all (without one, the trochanters follow the commanded pitch only);
        ``requests`` are the reflexes' (:mod:`.asks`), ``gait_choice`` the gait selector's
        latest. Returns what the coordinator says, in order."""
        out = self.out = []
        self.t = t = states.t
        dt = 0.0 if self.last_t is None else t - self.last_t
        self.dt = dt
        self.last_t = t
        self.last_states_t = t
        self.cycle_no = states.cycle
        self._take_states(states)
        lost, back = self.losses.take(states)
        for leg, joint in lost:
            self.joint_lost(leg, joint)
        for leg, joint in back:
            self.joint_back(leg, joint)
        self._take_legs(legs)
        if tilt_wired:
            self._take_tilt(tilt, dt)
        for req in requests:
            if self.asks.take(req):
                self._sit_for(req)
        if gait_choice is not None and gait_choice.gait in GAITS:
            self.gait_choice = gait_choice.gait
        for cmd in commands:
            if self.stopping:
                out.append(refused(cmd, self.stop_reason, t=self.t, source=self.name))
                continue
            self.clamp_said = False
            out.extend(take_command(self.want, cmd, self.cfg, t=self.t, source=self.name))
        if self.no_wheel and self.want.mode != "walk":
            self._walk_without_wheels()
        # Scripts first: while one runs, nothing else moves the feet.
        if self.script is None and self.activity not in QUIET:
            self.script = self._next_script()
        if self.script is not None:
            self.run_script()
        elif self.stopping:
            pass  # sat down for the safe stop: hold still until the bus parks
        elif self.mode == "ride":
            self.set_activity(Activity.RIDING if self.rolling() else Activity.STANDING)
            self.steer = True
            self._ride_tick(dt)
        else:
            hybrid = self.mode == "hybrid"
            self._gait_tick(dt, hybrid)
            if self.phase_running:
                self.set_activity(Activity.HYBRID if hybrid else Activity.WALKING)
            elif self.activity in (Activity.WALKING, Activity.HYBRID):
                self.set_activity(Activity.STANDING)
            if self.activity == Activity.STANDING:
                self._settle()
            if self.script is None:
                self._ride_riders()
        self._publish()
        return out

    def begin_sit(self, now: float) -> bool:
        """Start sitting down for a stop, unless seated already, the bus silent since
        :data:`BUS_SILENT_S` before ``now`` or a leg never placed; True if it started."""
        if (
            self.activity in (Activity.SEATED, Activity.SITTING_DOWN)
            or now - self.last_states_t > BUS_SILENT_S
            or any(f is None for f in self.feet)
        ):
            return False
        self.stopping = True
        self.script = self.sit_down()
        self.wait = None
        self.want.vx = self.want.vy = self.want.yaw = 0.0
        self.leg_twist = self.wheel_twist = (0.0, 0.0, 0.0)
        self.speeds = (0.0,) * N_LEGS
        return True

    def _sit_for(self, req: ReflexRequest) -> None:
        """A reflex asks the robot to sit down and stay seated (the battery, 5.3.1)."""
        why = f": {req.reason}" if req.reason else ""
        self.changed("seated_by", "", f"{req.reflex}{why}")
        if not self.stopping and not self.begin_sit(self.t):
            self.stopping = True  # seated already, or never stood: it stays so
        self.stop_reason = f"{req.reflex} sat the robot down{why}"

    def stop_cycle(self, states: ServoStates, legs: Iterable[LegState] = ()) -> list[Message]:
        """A cycle of the sit-down before a stop, once the actor's loop no longer runs: the
        script only, then the body motion and state."""
        out = self.out = []
        self.t = states.t
        self.last_t = states.t
        self.last_states_t = states.t
        self._take_legs(legs)
        self.run_script()
        self._publish()
        return out

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

    def _take_tilt(self, tilt: BodyTilt | None, dt: float) -> None:
        """The measured pitch, low-passed: the trochanters follow a slope, not the shakes of
        each step (an accelerometer reads the body's accelerations as tilt too)."""
        if tilt is not None:
            self.tilt_measured = (tilt.roll_rad, tilt.pitch_rad)
        k = min(1.0, dt / self.loco.tilt_filter_s)
        self.tilt_roll += (self.tilt_measured[0] - self.tilt_roll) * k
        self.tilt_pitch += (self.tilt_measured[1] - self.tilt_pitch) * k

    def _take_legs(self, legs: Iterable[LegState]) -> None:
        for s in legs:
            self.feet[s.leg] = s.foot
            if not s.touchdown_pending:
                self.awaited_since[s.leg] = None
            elif self.awaited_since[s.leg] is None:
                self.awaited_since[s.leg] = s.t
            m = s.measured_foot
            self.measured_raw[s.leg] = m
            if m is not None:  # on a grid: a command changes when a wheel moved, not with noise
                g = CONTACT_GRID_M
                self.measured_feet[s.leg] = (
                    round(m[0] / g) * g,
                    round(m[1] / g) * g,
                    round(m[2] / g) * g,
                )

    # ----------------------------------------------------------------- what next

    def wanted_gait(self) -> str:
        """The gait to walk: the operator's, or the selector's while the operator's is auto."""
        g = self.want.gait
        return self.gait_choice if g == AUTO_GAIT else g

    def _next_script(self) -> Script | None:
        """The wanted state differs from the present one: the script that bridges them."""
        w = self.want
        gait = self.wanted_gait()
        restep = self.asks.restep
        leg = -1 if restep is None or restep.restep_leg is None else restep.restep_leg
        if restep is not None and (
            self.mode != "walk" or self.upside_down or not 0 <= leg < N_LEGS
        ):
            self.asks.restep = None  # on the wheels, on its back, or no such leg: no step
            why = "riding: the legs stand on their wheels" if self.mode != "walk" else "flipped"
            if not 0 <= leg < N_LEGS:
                why = f"no leg {leg}: legs are 0…{N_LEGS - 1}"
            self.say(self._restepped(restep, (0.0, 0.0, 0.0), why))
            restep = None
        needs_rest = (
            restep is not None
            or w.upside_down != self.upside_down
            or w.mode != self.mode
            or (gait != self.gait.name and self.mode == w.mode == "walk")
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
        if not still or swinging or not self.wheels_stopped():
            return None
        self.winding_down = False
        if restep is not None:
            self.asks.restep = None
            return self.restep(restep)
        if w.upside_down != self.upside_down:
            self.steer = False
            return self.flip()
        if gait != self.gait.name and self.mode == w.mode == "walk":
            self._change_gait(gait)
            return None  # the next start places the feet for the new gait
        if w.mode != self.mode:
            self.steer = False
            stance = self.loco.ride_stance if w.mode == "ride" else w.stance
            if w.mode == "hybrid" and self.gait.name != self.loco.hybrid_gait:
                self._change_gait(self.loco.hybrid_gait)
            if w.mode == "walk" and self.gait.name != gait:
                self._change_gait(gait)
            if w.mode == "hybrid":
                return self.enter_hybrid(stance)
            return self.change_stance(stance, w.mode)
        if w.stop:
            w.stop = False
            if any(self.away(i, self.neutral_points[i]) for i in range(N_LEGS)):
                return self.replace(self.neutral_points, self.asked_step_height(), self.replace_s())
            return None
        if w.stance != self.stance_name:
            return self.change_stance(w.stance, self.mode)
        return None

    def _change_gait(self, name: str) -> None:
        before = self.gait.name
        self.gait = GAITS[name]
        self.changed("gait", before, name)

    def run_script(self) -> None:
        """Step the script while its waits hold, ordering the moves each step queues."""
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
            if self.pending_moves:
                for leg, target, height in self.pending_moves:
                    self.send_step(leg, "move", self.pending_duration, target, height)
                self.pending_moves = []

    def _settle(self) -> None:
        """Standing: the feet's goals follow where the feet are (:mod:`.settle`)."""
        tau = self.loco.settle_s
        t = self.t
        if tau <= 0.0 or t - self.settle_t < SETTLE_PERIOD_S - 1e-9:
            return
        if any(t < until for until in self.swing_until) or any(self.leg_twist):
            return
        self.settle_t = t
        feet = self.feet
        placed = [None if f is None else self.placed(i, f) for i, f in enumerate(feet)]
        moves = settled(
            feet,
            placed,
            self.measured_raw,
            self.neutral_points,
            fraction=1.0 - math.exp(-SETTLE_PERIOD_S / tau),
            limit_m=self.loco.settle_max_mm / 1000,
        )
        for leg, target in moves.items():
            if leg not in self.riders:
                self.send_step(leg, "move", SETTLE_PERIOD_S, target)

    # ----------------------------------------------------------------- saying it

    def _publish(self) -> None:
        w = self.want
        # Body height within the stance: the feet stay, the body moves (pose z).
        steady = self.activity in STEADY
        z = w.body_height - self.height if w.body_height is not None and steady else 0.0
        roll, pitch = (0.0, 0.0) if self.upside_down else (w.roll, w.pitch)
        self.pose_now = self._pose_step((0.0, 0.0, z, roll, pitch, 0.0))
        trochanter = 0.0
        if self.loco.trochanter_follows_pitch and not self.upside_down:
            # eq. 4.18: the legs turn with the body's pitch, commanded and measured.
            limit = self.max_trochanter
            trochanter = min(max(self.pose_now[4] + self.tilt_pitch, -limit), limit)
        asked = self.asks.trochanter()
        if asked is not None and not self.upside_down:  # the trochanter reflex (6.7.6)
            limit = self.max_trochanter
            trochanter = min(max(asked, -limit), limit)
        if self.trochanter_held is not None and not self.upside_down:
            trochanter = self.trochanter_held
        self.trochanter_rad = trochanter
        # The ground as gravity sees it: the body's measured tilt less its pose on the feet.
        self.ground_tilt = (
            (0.0, 0.0)
            if self.upside_down
            else (self.tilt_roll - self.pose_now[3], self.tilt_pitch - self.pose_now[4])
        )
        self.say(
            BodyMotion(
                t=self.t,
                source=self.name,
                cycle=self.cycle_no,
                twist=self.leg_twist if self.mode != "ride" else (0.0, 0.0, 0.0),
                pose=self.pose_now,  # type: ignore[arg-type]
                trochanter_rad=trochanter,
                upside_down=self.upside_down,
                steer=self.steer,
                wheel_heading_rad=self.headings,
                wheel_speed_m_s=self.speeds,
                steer_legs=tuple(sorted(self.riders)) if self.mode == "walk" else (),
            )
        )
        if not self.report:
            return
        # As the gait counts them: a swing that ends within this cycle is down.
        landing = self.t + self.dt
        swing = tuple(i for i in range(N_LEGS) if landing < self.swing_until[i])
        down = [i for i in range(N_LEGS) if i not in swing]
        self.margin_m = self.margin(down)
        twist = (
            self.leg_twist
            if self.mode == "walk"
            else tuple(a + b for a, b in zip(self.leg_twist, self.wheel_twist, strict=True))
        )
        self.say(
            LocomotionState(
                t=self.t,
                source=self.name,
                activity=self.activity.value,
                mode=self.mode,
                gait=self.gait.name,
                stance=self.stance_name,
                twist=twist,  # type: ignore[arg-type]
                gait_phase=self.phase,
                swing_legs=swing,
                margin_m=self.margin_m,
                upside_down=self.upside_down,
                cycle_s=self.cycle_s if self.phase_running else 0.0,
                gait_auto=w.gait == AUTO_GAIT,
            )
        )

    def _pose_step(self, target: tuple[float, ...]) -> tuple[float, ...]:
        """Move the body pose toward ``target`` at a rate that covers the full range in
        ``transition_s``: 0.1 m and 20° per transition."""
        dt, span = self.dt, self.loco.transition_s
        return tuple(
            [
                ramp(a, b, r * dt / span)
                for a, b, r in zip(self.pose_now, target, _POSE_RATES, strict=True)
            ]
        )
