"""The coordinator's scripts: changes that move feet, step by step (6.3–6.8).

Theory of operation
-------------------
A script is a generator of *waits*: each step of it orders some legs to move
(:meth:`Scripts.script_moves` queues their :class:`StepCommand` s), then
yields a condition on time or on the servos; the planner calls it again,
every cycle, once the condition holds (:meth:`LocomotionPlanner.run_script`).
While one runs, nothing else moves the feet.

* **stand up**: every leg from the pose the servos report to the seated pose
  (in joint space, the legs' first move), then the body lifted to the stance;
* **sit down**: the body lowered onto the ground, the feet where they are;
* **change stance** (and walk ↔ ride): the new reach at the present height,
  then the height, re-placing the feet a tripod group at a time (one leg at
  a time where a group's lift would leave too small a stability margin);
* **flip** (6.8.1): sit, turn the trochanters 180°, stand up on the back;
* **align**: the direction servos to new headings with the wheels held,
  until the servos report them there (or, where the read plan does not read
  them, as long as the turn takes at their Velocity Limit);
* **enter hybrid**: the hybrid gait's stance, then the wheels aligned;
* **placed for start**: the feet where a gait's phase table wants them;
* **restep**: one leg stepped again at a reflex's request (6.7.1, 6.7.3), a swing
  to its neutral point moved by the offset asked, if the other five feet hold the
  body with the stability margin; said with :class:`Restepped`.

Each script sets the activity it runs under and the one it ends in.
"""

from __future__ import annotations

import math

from whexar.actors.locomotion.activity import Activity
from whexar.actors.locomotion.core import PLACED_M, SETTLE_S, STILL, PlannerCore, Script, Wait
from whexar.actors.messages import ReflexRequest, Restepped, Vec3
from whexar.kinematics.gait import TRIPOD
from whexar.kinematics.wheels import wheel_twist
from whexar.robot import LEG_NAMES, N_LEGS


class Scripts(PlannerCore):
    """The scripts (module docstring), over the coordinator's state."""

    # ----------------------------------------------------------------- building blocks

    def after(self, seconds: float) -> Wait:
        until = self.t + seconds
        return lambda: self.t >= until

    def move_all(self, targets: list[Vec3], height: float = 0.0) -> list[tuple[int, Vec3, float]]:
        return [(i, targets[i], height) for i in range(N_LEGS)]

    def script_moves(self, moves: list[tuple[int, Vec3, float]], duration: float) -> Script:
        """Order ``moves`` ((leg, target, lift) each), then wait until they are done."""
        self.pending_moves = list(moves)
        self.pending_duration = duration
        yield lambda: not self.pending_moves
        yield self.after(duration + SETTLE_S)

    def replace(self, targets: list[Vec3], height: float, duration: float) -> Script:
        """Re-place the feet that are not at ``targets``, a tripod group at a time, lifting
        each; one leg at a time where a group's lift would leave too small a margin."""
        for group in TRIPOD.groups:
            legs = [LEG_NAMES.index(name) for name in group]
            legs = [i for i in legs if self.away(i, targets[i])]
            if not legs:
                continue
            yield from self.judged(legs)
            down = [i for i in range(N_LEGS) if i not in legs]
            if self.margin(down) < self.loco.min_stability_margin_mm / 1000:
                # The group together is not safe: one leg at a time.
                for i in legs:
                    yield from self.script_moves([(i, targets[i], height)], duration)
                continue
            yield from self.script_moves([(i, targets[i], height) for i in legs], duration)

    def awaiting(self, legs: list[int]) -> bool:
        """Whether one of ``legs`` awaits its touchdown's judgement: a foot lifted then
        would be judged in the air (``no_contact``), its search for the ground cut off. A
        leg that says so for longer than ``touchdown_wait_s`` is not waited for."""
        return any(
            since is not None and self.t - since < self.touchdown_wait_s
            for since in (self.awaited_since[i] for i in legs)
        )

    def judged(self, legs: list[int]) -> Script:
        """Wait until none of ``legs`` awaits its touchdown's judgement (:meth:`awaiting`)."""
        if self.awaiting(legs):
            yield lambda: not self.awaiting(legs)

    def replace_s(self) -> float:
        """A re-placing step: as long as the slowest swing the tripod makes at full speed."""
        return max(self.loco.min_swing_s, 0.5 * self.loco.transition_s)

    def restep(self, req: ReflexRequest) -> Script:
        """Step ``req.restep_leg`` again, to its neutral point moved by the offset asked (the
        module docstring): a swing searching as the gait's do, then the walk goes on."""
        leg = req.restep_leg
        assert leg is not None
        n = self.neutral_points[leg]
        dx, dy = req.restep_offset_m
        target = (n[0] + dx, n[1] + dy, n[2])
        down = [i for i in range(N_LEGS) if i != leg]
        margin = self.margin(down)
        minimum = self.loco.min_stability_margin_mm / 1000
        why = ""
        if margin < minimum:
            why = f"lifting it would leave a margin of {margin * 1000:.0f} mm"
        elif not self.reachable(
            [target if i == leg else n for i, n in enumerate(self.neutral_points)]
        ):
            why = "out of its reach"
        if why:
            self.say(self._restepped(req, target, why))
            return
        self.set_activity(Activity.TRANSITION)
        duration = self.replace_s()
        self.swing_until[leg] = self.t + duration
        self.send_step(leg, "swing", duration, target, self.asked_step_height())
        yield self.after(duration + SETTLE_S)
        self.say(self._restepped(req, target))
        self.set_activity(Activity.STANDING)

    def _restepped(self, req: ReflexRequest, target: Vec3, why: str = "") -> Restepped:
        assert req.restep_leg is not None
        return Restepped(
            t=self.t,
            source=self.name,
            leg=req.restep_leg,
            reflex=req.reflex,
            target=target,
            done=not why,
            reason=why,
        )

    def to_height(self, height: float) -> Script:
        """Every foot together to ``height`` below the coxa joints: the body rises or sinks."""
        if abs(height - self.height) <= PLACED_M:
            return
        feet = [f or n for f, n in zip(self.feet, self.neutral_points, strict=True)]
        self.height = height
        targets = [(f[0], f[1], -height) for f in feet]
        yield from self.script_moves(self.move_all(targets), self.loco.transition_s)

    # ----------------------------------------------------------------- the scripts

    def stand_up(self) -> Script:
        self.set_activity(Activity.STANDING_UP)
        stance = self.stance(self.stance_name)
        seated = self.neutral(stance, self.loco.sit_height_mm / 1000)
        half = self.loco.stand_up_s / 2
        yield from self.script_moves(self.move_all(seated), half)
        self.height = stance.height
        yield from self.script_moves(self.move_all(self.neutral(stance)), half)
        self.set_activity(Activity.STANDING)

    def sit_down(self) -> Script:
        self.set_activity(Activity.SITTING_DOWN)
        feet = [
            f if f is not None else n for f, n in zip(self.feet, self.neutral_points, strict=True)
        ]
        low = -self.loco.sit_height_mm / 1000
        targets = [(f[0], f[1], low) for f in feet]
        yield from self.script_moves(self.move_all(targets), self.loco.sit_down_s)
        self.set_activity(Activity.SEATED)

    def change_stance(self, name: str, mode: str) -> Script:
        self.set_activity(Activity.TRANSITION)
        stance = self.stance(name)
        before = self.stance_name
        step, replace_s = self.asked_step_height(), self.replace_s()
        new_points = self.neutral(stance)
        beside = [(n[0], n[1], -self.height) for n in new_points]
        if self.reachable(beside):
            # The new reach at the present height, then every foot together to the new
            # height (the body rises or sinks). Never the height first: walking may have
            # left a foot half a step off, where the new height may not reach.
            yield from self.replace(beside, step, replace_s)
            yield from self.to_height(stance.height)
        else:
            # The new reach needs the new height: feet to their neutral points, the
            # height, then the new reach.
            yield from self.replace(self.neutral_points, step, replace_s)
            yield from self.to_height(stance.height)
            self.neutral_points = new_points
            yield from self.replace(new_points, step, replace_s)
        self.stance_name = name
        self.neutral_points = new_points
        if before != name:
            self.changed("stance", before, name)
        if mode != self.mode:
            self.changed("mode", self.mode, mode)
            self.mode = mode
        self.set_activity(Activity.STANDING)

    def flip(self) -> Script:
        yield from self.sit_down()
        self.set_activity(Activity.FLIPPING)
        before = self.upside_down
        self.upside_down = not before
        yield self.after(self.loco.flip_s + SETTLE_S)
        self.neutral_points = self.neutral(self.stance(self.stance_name))
        self.feet = [None if f is None else (f[0], -f[1], f[2]) for f in self.feet]
        # Until the legs say where they are now.
        self.measured_feet = [None] * N_LEGS
        self.measured_raw = [None] * N_LEGS
        self.changed("upside_down", str(before), str(self.upside_down))
        stance = self.stance(self.stance_name)
        self.height = stance.height
        yield from self.script_moves(self.move_all(self.neutral(stance)), self.loco.stand_up_s)
        self.set_activity(Activity.STANDING)

    def align(self, headings: tuple[float, ...]) -> Script:
        """Direction servos to ``headings`` with the wheels held, then wait until they are there."""
        self.set_activity(Activity.TRANSITION)
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

        yield self.after(2 * SETTLE_S)
        yield aligned

    def enter_hybrid(self, stance: str) -> Script:
        """The hybrid gait's stance, then the wheels aligned with the way the wheels will
        drive before any of them turns (as for riding, 5.4)."""
        yield from self.change_stance(stance, "hybrid")
        share = self.loco.hybrid_wheel_share
        vx, vy, w = (v * share for v in self.asked_twist())
        if any(abs(v) > STILL for v in (vx, vy, w)):
            cmd = wheel_twist(self.contacts(), vx, vy, w, wheel_radius=self.geometry.wheel_radius)
            yield from self.align(tuple(float(h) for h in cmd.heading))
        self.set_activity(Activity.STANDING)

    def placed_for_start(self, targets: list[Vec3]) -> Script:
        activity = self.activity
        self.set_activity(Activity.TRANSITION)
        yield from self.judged(list(range(N_LEGS)))
        yield from self.replace(targets, self.asked_step_height(), self.replace_s())
        self.set_activity(activity if activity != Activity.TRANSITION else Activity.STANDING)
