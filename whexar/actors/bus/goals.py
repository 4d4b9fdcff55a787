"""The goal policy: which goal each servo holds, and which goals a cycle writes.

A goal is taken as it is given: the latest per joint wins, whoever sent it
(deciding between goal sources — a reflex's override and the gait's
trajectory — is the leg's business, not the bus's). Every goal is brought
within the joint's limits: a position is clamped to the limits and rounded
to a tick *inside* them, a wheel speed to the servo's Velocity Limit (each
clamp a :class:`GoalClamped`); a goal that is no command at all (not finite,
absurdly far out, a position for a wheel) is refused (:class:`GoalRefused`).
Nothing outside the limits reaches the wire.

A cycle writes the goals that changed, and those of servos no packet
addressed for half the Bus Watchdog period, so that every servo keeps
hearing the host. A write the port failed to send is counted
(:class:`WriteFailed`) and its goals go out again in the next cycle.

:class:`GoalPolicy` does no I/O and reads no clock: it takes the time and
the goals, and returns the writes and the events.
"""

from __future__ import annotations

import math
from collections.abc import Container, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Final

from whexar.actors.bus.servos import GOAL_POSITION, GOAL_VELOCITY, Servo
from whexar.actors.messages import GoalClamped, GoalRefused, JointGoal, JointGoals, WriteFailed
from whexar.bus import control_table as ct
from whexar.bus.sdk import COMM_SUCCESS, comm_name
from whexar.runtime.messages import Event

ABSURD_TURNS: Final = 1.0
"""A position goal more than this many turns beyond its joint's limits is refused, not
clamped: it is an upstream bug, not a command to saturate."""
ABSURD_SPEED_FACTOR: Final = 10.0
"""Likewise a wheel speed beyond this multiple of the servo's Velocity Limit."""

_ABSURD_RAD: Final = ABSURD_TURNS * 2 * math.pi
_RAD_PER_TICK: Final = ct.ticks_to_rad(ct.CENTER_TICKS + 1)
_CENTER_TICKS: Final = ct.CENTER_TICKS


@dataclass(slots=True)
class Write:
    """One Sync Write of a cycle: a goal register (4 bytes, signed), the value per servo."""

    register: ct.Register
    values: dict[int, int]


@dataclass(slots=True)
class Slot:
    """What the policy knows of one servo's goal."""

    servo: Servo
    goal: int | None = None
    """The goal to hold: ticks (position joints) or velocity units (the wheel)."""
    sent: int | None = None
    """The goal the servo last acknowledged receiving (a write that went out)."""
    addressed_at: float = 0.0
    """When a packet last addressed it (what feeds its Bus Watchdog)."""


class GoalPolicy:
    """Goals in (clamped or refused), writes out; one :class:`Slot` per servo.

    ``source`` names the events' maker (the actor); ``keepalive_s`` is how long a
    servo may go unaddressed before its goal is written again (``math.inf``: never).
    """

    def __init__(self, servos: Mapping[int, Servo], source: str, keepalive_s: float) -> None:
        self.source = source
        self.keepalive_s = keepalive_s
        self.slots: dict[int, Slot] = {sid: Slot(s) for sid, s in servos.items()}
        """Every servo's slot, in the table's order (the order of a write's servos)."""
        self.by_joint = {(s.leg, s.joint): self.slots[sid] for sid, s in servos.items()}
        self.clamped = 0
        """Goals clamped so far (start-up goals included)."""
        self.write_failures = 0
        """Sync Writes the port failed to send so far."""

    # ----------------------------------------------------------------- goals in

    def take(self, now: float, messages: Iterable[JointGoals]) -> list[Event]:
        """Take ``messages`` in their order (the latest goal per joint wins); the clamps
        and refusals, as events."""
        events: list[Event] = []
        for msg in messages:
            for g in msg.goals:
                self._take(now, g, events)
        return events

    def _take(self, now: float, g: JointGoal, events: list[Event]) -> None:
        slot = self.by_joint.get((g.leg, g.joint))
        if slot is None:
            self._refuse(
                now, g, f"no joint {g.joint} on leg {g.leg} (legs 0–5, joints 0–6)", events
            )
            return
        servo = slot.servo
        if servo.endless:
            self._take_speed(now, slot, g, events)
            return
        want = g.position_rad
        if want is None:
            what = "a speed" if g.velocity_rad_s is not None else "no goal"
            reason = f"{what} for {servo.name}, a positioned joint: give position_rad"
            self._refuse(now, g, reason, events)
            return
        if not math.isfinite(want):
            reason = f"position_rad = {want!r} for {servo.name}: not a finite number"
            self._refuse(now, g, reason, events)
            return
        sent = min(max(want, servo.lo), servo.hi)
        if abs(want - sent) > _ABSURD_RAD:
            reason = (
                f"position_rad = {want!r} for {servo.name}: more than a turn beyond its "
                f"limits ({servo.lo:.3f}…{servo.hi:.3f} rad)"
            )
            self._refuse(now, g, reason, events)
            return
        if sent != want:
            events.append(self._clamp(now, servo, want, sent))
        tick = _CENTER_TICKS + round(sent / _RAD_PER_TICK)  # ct.rad_to_ticks, inlined
        slot.goal = servo.lo_tick if tick < servo.lo_tick else min(tick, servo.hi_tick)

    def _take_speed(self, now: float, slot: Slot, g: JointGoal, events: list[Event]) -> None:
        servo = slot.servo
        speed = g.velocity_rad_s
        if g.position_rad is not None or speed is None:
            what = "a position" if g.position_rad is not None else "no goal"
            self._refuse(now, g, f"{what} for {servo.name}, a wheel: give velocity_rad_s", events)
            return
        limit = ct.velocity_to_rad_s(servo.speed_limit)
        if not math.isfinite(speed) or abs(speed) > ABSURD_SPEED_FACTOR * limit:
            reason = (
                f"velocity_rad_s = {speed!r} for {servo.name}: not a speed "
                f"(its Velocity Limit is {limit:.3f} rad/s)"
            )
            self._refuse(now, g, reason, events)
            return
        units = max(-servo.speed_limit, min(servo.speed_limit, ct.rad_s_to_velocity(speed)))
        if abs(speed) > limit:
            events.append(self._clamp(now, servo, speed, ct.velocity_to_rad_s(units), "rad/s"))
        slot.goal = units

    def _refuse(self, now: float, g: JointGoal, reason: str, events: list[Event]) -> None:
        events.append(
            GoalRefused(t=now, source=self.source, leg=g.leg, joint=g.joint, reason=reason)
        )

    def _clamp(
        self, now: float, servo: Servo, requested: float, sent: float, unit: str = "rad"
    ) -> GoalClamped:
        self.clamped += 1
        return GoalClamped(
            t=now,
            source=self.source,
            servo_id=servo.id,
            requested_rad=requested,
            sent_rad=sent,
            unit=unit,
        )

    def start(self, now: float, ticks: Mapping[int, int]) -> list[Event]:
        """Start-up goals: each position (a present or held one, ticks) within the limits,
        a clamp event if it was not; a wheel's goal as given (velocity units)."""
        events: list[Event] = []
        for sid, tick in ticks.items():
            slot = self.slots[sid]
            servo = slot.servo
            if servo.endless:
                slot.goal = tick
                continue
            inside = servo.clamp_tick(tick)
            if inside != tick:
                requested, sent = ct.ticks_to_rad(tick), ct.ticks_to_rad(inside)
                events.append(self._clamp(now, servo, requested, sent))
            slot.goal = inside
        return events

    # ----------------------------------------------------------------- writes out

    def writes(self, now: float, out: Container[int]) -> list[Write]:
        """The goals to write at ``now``: those that changed, and those of servos the Bus
        Watchdog would soon miss; none for a servo in ``out`` (not in the cycle)."""
        pos: dict[int, int] = {}
        vel: dict[int, int] = {}
        stale = now - self.keepalive_s
        for sid, slot in self.slots.items():
            goal = slot.goal
            if goal is None or sid in out:
                continue
            if goal != slot.sent or slot.addressed_at <= stale:
                (vel if slot.servo.endless else pos)[sid] = goal
        writes = []
        if pos:
            writes.append(Write(GOAL_POSITION, pos))
        if vel:
            writes.append(Write(GOAL_VELOCITY, vel))
        return writes

    def written(
        self, t: float, now: float, writes: Sequence[Write], results: Sequence[int]
    ) -> list[Event]:
        """The port's result for each of a cycle's ``writes`` (started at ``t``): a write
        sent is the servos' goal and addresses them; one not sent is an event, and its
        goals go out again next cycle (``sent`` stays as it was)."""
        events: list[Event] = []
        slots = self.slots
        for w, result in zip(writes, results, strict=True):
            if result == COMM_SUCCESS:
                for sid, value in w.values.items():
                    slot = slots[sid]
                    slot.sent = value
                    slot.addressed_at = t
                continue
            self.write_failures += 1
            events.append(
                WriteFailed(
                    t=now,
                    source=self.source,
                    register=w.register.name,
                    servos=len(w.values),
                    result=comm_name(result),
                )
            )
        return events

    def addressed(self, ids: Iterable[int], t: float) -> None:
        """A packet addressed the servos ``ids`` at ``t`` (a cycle's read, start-up)."""
        slots = self.slots
        for sid in ids:
            slots[sid].addressed_at = t

    def holding(self, ids: Iterable[int], goals: Mapping[int, int] | None = None) -> None:
        """The servos ``ids`` hold their goal: the one in ``goals`` where it has one (just
        written), else the one they have (kept under torque)."""
        for sid in ids:
            slot = self.slots[sid]
            if goals is not None:
                slot.goal = goals.get(sid, slot.goal)
            slot.sent = slot.goal

    def restored(self, sid: int, now: float) -> None:
        """A restore wrote the servo's goal again at ``now``."""
        slot = self.slots[sid]
        slot.sent = slot.goal
        slot.addressed_at = now

    def stopped(self, ids: Iterable[int]) -> None:
        """The wheels ``ids`` were brought to zero speed (a park)."""
        for sid in ids:
            slot = self.slots[sid]
            slot.goal = slot.sent = 0
