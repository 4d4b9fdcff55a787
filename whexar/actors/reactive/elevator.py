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
swings go over. Once no swing has been blocked for ``hold_s`` the raise is
withdrawn: the operator's step again.
"""

from __future__ import annotations

from collections.abc import Iterable

from pydantic import Field

from whexar.actors.messages import SwingEnded
from whexar.actors.reactive.reflex import Command, Reflex, ReflexParams
from whexar.config import RobotConfig
from whexar.runtime.messages import Message


class ElevatorParams(ReflexParams):
    """The elevator's raise and how long it keeps it (docs/reflexes.md)."""

    raise_m: float = Field(0.03, gt=0.0, le=0.2)
    """Each blocked swing raises the step by this much, m (half the default 6 cm step)."""
    max_raise_m: float = Field(0.06, gt=0.0, le=0.3)
    """The most it raises the step above the operator's, m (the default step doubled)."""
    hold_s: float = Field(4.8, gt=0.0, le=60.0)
    """The raise is kept this long after the last blocked swing, s (three tripod cycles
    of 1.6 s: every leg has stepped over what blocked one)."""


class Elevator(Reflex):
    """Raises the step after a blocked swing (module docstring)."""

    inputs = ("swings",)
    priority = 20
    tick_s = 0.1
    Params = ElevatorParams
    params: ElevatorParams

    def __init__(self, params: ReflexParams, *, name: str, cfg: RobotConfig) -> None:
        super().__init__(params, name=name, cfg=cfg)
        self.raised = 0.0
        self.last_blocked = -1e9

    def react(self, t: float, msg: Message) -> Iterable[Command]:
        if not isinstance(msg, SwingEnded) or msg.outcome != "blocked":
            return ()
        p = self.params
        self.last_blocked = t
        before = self.raised
        self.raised = min(self.raised + p.raise_m, p.max_raise_m)
        self.active = True
        self.reason = f"leg {msg.leg} blocked on its way up: the step {self.raised * 100:+.0f} cm"
        if self.raised == before:
            return ()
        return (self.request(t, step_raise_m=self.raised, reason=self.reason),)

    def tick(self, t: float) -> Iterable[Command]:
        if self.raised == 0.0 or t - self.last_blocked < self.params.hold_s:
            return ()
        self.raised = 0.0
        self.active = False
        return (self.request(t, step_raise_m=0.0, reason="no swing blocked any more"),)
