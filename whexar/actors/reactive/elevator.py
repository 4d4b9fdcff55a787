"""The elevator reflex: a swing blocked on its way up raises the step (4.2.2, 6.7.2).

Theory of operation
-------------------
In the thesis, the coxa's torque during a swing above a threshold made the
leg retract and repeat its swing higher, and raised the terrain
controller's step height. Here the leg tells how each swing ended
(:class:`~whexar.actors.messages.SwingEnded`): ``blocked`` is a contact met on
the way up, before the apex — something in the swing's path. Each blocked
swing raises every leg's step by ``raise_m`` more, up to ``max_raise_m``
above what the operator asked (a :class:`ReflexRequest` ``step_raise_m``; the
coordinator keeps it within ``locomotion.max_step_height_mm``), so the next
swings go over. Once no swing has been blocked for ``hold_s``, and the body
has walked ``hold_m`` since (the coordinator's commanded twist, integrated
while it walks), the raise is withdrawn: the operator's step again. The
distance is what lets every leg over: the rear feet meet a sill the front ones
met only after the body has walked the span between them, however long halts
and slower gaits make that take.

**Pushed, not blocked.** The thesis's elevator did not fire on a light obstacle
the leg simply pushed away (6.7.2). A blocked swing is confirmed by the foot held
back: within ``confirm_s`` of the contact, the leg's foot error (its
:class:`~whexar.actors.messages.LegState` ``foot_error_m``, the servos' tracking
error at the foot) reaches ``held_m``, and ``held_over_m`` beyond the leg's own
usual lag in a swing (the largest foot error of each of its unblocked swings,
a running mean over ``learn_swings``): on 30° the wave's swings lag 35–60 mm by
themselves. A foot that goes on along its path pushed what it met: the swing
is let be. A leg that cannot tell (its joints unread) is taken as blocked.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from pydantic import Field

from whexar.actors.messages import LegState, LocomotionState, SwingEnded
from whexar.actors.reactive.reflex import WALKING, Command, Reflex, ReflexParams
from whexar.config import RobotConfig
from whexar.robot import N_LEGS
from whexar.runtime.messages import Message


class ElevatorParams(ReflexParams):
    """The elevator's raise and how long it keeps it (docs/reflexes.md)."""

    raise_m: float = Field(0.03, gt=0.0, le=0.2)
    """Each blocked swing raises the step by this much, m (half the default 6 cm step)."""
    max_raise_m: float = Field(0.06, gt=0.0, le=0.3)
    """The most it raises the step above the operator's, m (the default step doubled)."""
    hold_s: float = Field(4.8, gt=0.0, le=60.0)
    """The raise is kept this long after the last blocked swing, s (three tripod cycles
    of 1.6 s)."""
    hold_m: float = Field(0.8, ge=0.0, le=5.0)
    """… and until the body has walked this far since the last blocked swing, m: the
    0.67 m from the front feet to the rear ones at the default stance, and a stride, so
    that the rear legs too have stepped over what blocked a front one (docs/reflexes.md)."""
    held_m: float = Field(0.034, gt=0.0, le=0.2)
    """A foot error this large within ``confirm_s`` of the contact confirms a blocked
    swing, m: between the 27 mm of a foot pushing a 0.3 kg sill and the 42 mm of one held
    by a fixed sill (a swing's own tracking error reaches 21 mm; docs/reflexes.md)."""
    held_over_m: float = Field(0.013, ge=0.0, le=0.2)
    """… and this far beyond the leg's usual lag in an unblocked swing, m: on the flat a
    fixed sill held the foot 21 mm beyond a swing's own 21 mm, a pushed one 6 mm; on 30°
    the wave's swings lag 35–60 mm, and a foot scraping the slope 61 mm
    (docs/reflexes.md, "A swing's own lag")."""
    learn_swings: int = Field(5, ge=1, le=100)
    """The unblocked swings a leg's usual lag is a running mean over."""
    confirm_s: float = Field(0.25, ge=0.0, le=2.0)
    """How long after the contact the foot error is watched, s; 0: every blocked swing
    fires at once (the thesis's elevator)."""


class Elevator(Reflex):
    """Raises the step after a blocked swing (module docstring)."""

    inputs = ("swings", "legs", "locomotion")
    priority = 20
    tick_s = 0.1
    Params = ElevatorParams
    params: ElevatorParams

    def __init__(self, params: ReflexParams, *, name: str, cfg: RobotConfig) -> None:
        super().__init__(params, name=name, cfg=cfg)
        self.raised = 0.0
        self.last_blocked = -1e9
        self.pending: dict[int, tuple[float, bool]] = {}
        """leg → (when its swing met something, whether its foot error was read since)."""
        self.pushed = 0
        """Blocked swings let be: the foot went on (a light obstacle pushed)."""
        self.walked = 0.0
        """How far the body has walked since the last blocked swing, m."""
        self.walk_t: float | None = None
        """When the coordinator last said it walks."""
        self.lag = [0.0] * N_LEGS
        """Per leg: its usual lag, the running mean of its unblocked swings' largest foot
        error, m."""
        self.swings = [0] * N_LEGS
        """Per leg: the unblocked swings in that mean (none yet: ``held_m`` alone)."""
        self.peak: list[float | None] = [None] * N_LEGS
        """Per leg in a swing: its largest foot error so far (None: not in a swing)."""
        self.met = [False] * N_LEGS
        """Per leg: its swing now met something (that swing's lag is not its own)."""

    def react(self, t: float, msg: Message) -> Iterable[Command]:
        if isinstance(msg, LocomotionState):
            self._walk(t, msg)
            return ()
        if isinstance(msg, LegState):
            self._learn(msg)
            return self._watch(t, msg) if msg.leg in self.pending else ()
        if not isinstance(msg, SwingEnded) or msg.outcome != "blocked":
            return ()
        self.met[msg.leg] = True
        if self.params.confirm_s <= 0.0:
            return self._blocked(t, msg.leg)
        self.pending.setdefault(msg.leg, (t, False))
        return ()

    def _learn(self, s: LegState) -> None:
        i, err = s.leg, s.foot_error_m
        if s.phase == "swing":
            peak = self.peak[i]
            if err is not None:
                self.peak[i] = err if peak is None else max(peak, err)
            return
        peak, self.peak[i] = self.peak[i], None
        met, self.met[i] = self.met[i], False
        if peak is None or met:
            return
        self.swings[i] += 1
        k = 1.0 / min(self.swings[i], self.params.learn_swings)  # the first: its own peak
        self.lag[i] += k * (peak - self.lag[i])

    def held(self, leg: int) -> float:
        """The foot error that confirms ``leg``'s blocked swing, m."""
        p = self.params
        if self.swings[leg] == 0:
            return p.held_m
        return max(p.held_m, self.lag[leg] + p.held_over_m)

    def _watch(self, t: float, s: LegState) -> Iterable[Command]:
        since, seen = self.pending[s.leg]
        err = s.foot_error_m
        if err is not None and err >= self.held(s.leg):
            del self.pending[s.leg]
            return self._blocked(t, s.leg)
        seen = seen or err is not None
        if t - since < self.params.confirm_s:
            self.pending[s.leg] = (since, seen)
            return ()
        del self.pending[s.leg]
        if not seen:  # no foot error to tell by: blocked, as the thesis took it
            return self._blocked(t, s.leg)
        self.pushed += 1
        return ()

    def _walk(self, t: float, s: LocomotionState) -> None:
        if s.activity not in WALKING:
            self.walk_t = None
            return
        if self.walk_t is not None:
            self.walked += math.hypot(s.twist[0], s.twist[1]) * (t - self.walk_t)
        self.walk_t = t

    def _blocked(self, t: float, leg: int) -> Iterable[Command]:
        p = self.params
        self.last_blocked = t
        self.walked = 0.0
        before = self.raised
        self.raised = min(self.raised + p.raise_m, p.max_raise_m)
        self.active = True
        self.reason = f"leg {leg} blocked on its way up: the step {self.raised * 100:+.0f} cm"
        if self.raised == before:
            return ()
        return (self.request(t, step_raise_m=self.raised, reason=self.reason),)

    def tick(self, t: float) -> Iterable[Command]:
        p = self.params
        if self.raised == 0.0 or t - self.last_blocked < p.hold_s or self.walked < p.hold_m:
            return ()
        self.raised = 0.0
        self.active = False
        return (self.request(t, step_raise_m=0.0, reason="no swing blocked any more"),)
