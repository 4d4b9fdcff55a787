"""The actor that runs one reflex: its inputs in, its overrides and its activity out.

Theory of operation
-------------------
One :class:`ReflexActor` per reflex (``params.reflex`` names its class,
:func:`~whexar.actors.reactive.reflex.resolve_reflex`). At the graph's build its
parameters are checked against the reflex's ``Params``, so a wrong class name,
an unknown parameter or a value out of range stops the run before it starts,
naming the actor. At start it checks that every input the reflex declares is
wired, then hands each message of each input to :meth:`Reflex.react` as it
arrives (and calls :meth:`Reflex.tick` every ``tick_s``), stamps the overrides
it returns with the reflex's priority and sends them to the legs, its
requests to the coordinator and its events to the runtime's event stream; a
:class:`~whexar.actors.reactive.reflex.Shutdown` stops the run.

Inhibition: every reflex publishes its changes of activity on
``reflex-activity`` and reads everyone's. While a reflex that names this one in
its ``inhibits`` is active, this one's inputs are not handed to it and it sends
nothing; it says so (``inhibited``) on the same channel.

A reflex that raises fails its actor: the runtime starts a fresh one (its state
does not survive half-updated) and, past its restart policy, disables it with
an :class:`~whexar.runtime.messages.ActorDisabled` event while the robot walks
on (the graphs made from ``[[reflexes]]`` set ``exhausted = "disable"``). On
its way down a reflex that was active says it no longer is, so that nobody
stays inhibited by it.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import anyio
from pydantic import Field, model_validator

from whexar.actors.messages import JointGoals, ReflexActivity, ReflexRequest
from whexar.actors.reactive.reflex import (
    STREAMS,
    Command,
    Reflex,
    Shutdown,
    check_params,
    inhibitions,
    resolve_reflex,
)
from whexar.config import ConfigFile, RobotConfig, load_config
from whexar.runtime.actor import Actor, ActorParams, Input, Output
from whexar.runtime.channels import Inbox
from whexar.runtime.messages import Event, Message


class ReflexActor(Actor):
    """Runs the reflex ``params.reflex`` (module docstring)."""

    class Params(ActorParams):
        reflex: str
        """Its class: ``package.module:Class`` or a ``whexar.reflexes`` entry point."""
        params: dict[str, Any] = Field(default_factory=dict)
        """Its parameters, checked by its ``Params``."""
        priority: int | None = None
        """Its rank at the legs; absent: the class's."""
        inhibits: tuple[str, ...] = ()
        """Reflexes it holds back while active, beside the class's own."""
        config: ConfigFile | None = None
        """Robot configuration file; absent: the built-in defaults."""

        @model_validator(mode="after")
        def _known_reflex(self) -> ReflexActor.Params:
            try:
                cls = resolve_reflex(self.reflex)
            except LookupError as exc:
                raise ValueError(f"reflex {exc}") from None
            try:
                check_params(cls, self.params)
            except ValueError as exc:
                raise ValueError(f"reflex {self.reflex!r}: {exc}") from None
            return self

    params: Params
    swings = Input(STREAMS["swings"][0], optional=True)
    legs = Input(STREAMS["legs"][0], optional=True)
    servo_state = Input(STREAMS["servo_state"][0], optional=True)
    health = Input(STREAMS["health"][0], optional=True)
    loads = Input(STREAMS["loads"][0], optional=True)
    ranges = Input(STREAMS["ranges"][0], optional=True)
    tilt = Input(STREAMS["tilt"][0], optional=True)
    imu = Input(STREAMS["imu"][0], optional=True)
    motion = Input(STREAMS["motion"][0], optional=True)
    locomotion = Input(STREAMS["locomotion"][0], optional=True)
    activity_in = Input(ReflexActivity, optional=True)
    """Every reflex's activity: who holds whom back."""
    override = Output(JointGoals)
    """Override goals for the legs' ``reflex`` inputs."""
    request = Output(ReflexRequest, optional=True)
    """Requests to the coordinator's ``requests`` input."""
    activity = Output(ReflexActivity, optional=True)

    async def run(self) -> None:
        p = self.params
        cls = resolve_reflex(p.reflex)
        cfg = load_config(p.config) if p.config else RobotConfig()
        policy = cls(check_params(cls, p.params), name=self.name, cfg=cfg)
        priority = cls.priority if p.priority is None else p.priority
        inhibits = inhibitions(cls, p.inhibits)
        unwired = [i for i in cls.inputs if not getattr(self, i).connected]
        if unwired:
            raise RuntimeError(
                f"reflex {p.reflex!r} reads {unwired}, which the graph does not wire to "
                f"actor {self.name!r}"
            )
        run = _Run(self, policy, priority, inhibits)
        self.ready()
        try:
            async with anyio.create_task_group() as tg:
                for port in cls.inputs:
                    tg.start_soon(run.feed, getattr(self, port))
                if self.activity_in.connected:
                    tg.start_soon(run.watch, self.activity_in)
                if cls.tick_s is not None:
                    tg.start_soon(run.ticks, cls.tick_s)
        finally:
            run.going_down()


class _Run:
    """One incarnation's state: who holds this reflex back, and what it said last."""

    def __init__(
        self, actor: ReflexActor, policy: Reflex, priority: int, inhibits: tuple[str, ...]
    ) -> None:
        self.actor = actor
        self.policy = policy
        self.priority = priority
        self.inhibits = inhibits
        self.holding: set[str] = set()
        """The active reflexes that hold this one back."""
        self.said: tuple[bool, bool] = (False, False)
        """(active, inhibited) as last published."""

    async def feed(self, inbox: Inbox[Message]) -> None:
        async for msg in inbox:
            if not self.holding:
                await self.send(self.policy.react(self.actor.now(), msg))

    async def ticks(self, period_s: float) -> None:
        async for _ in self.actor.ticker(period_s):
            if not self.holding:
                await self.send(self.policy.tick(self.actor.now()))

    async def watch(self, inbox: Inbox[ReflexActivity]) -> None:
        name = self.actor.name
        async for msg in inbox:
            if msg.reflex == name:
                continue
            if msg.active and name in msg.inhibits:
                self.holding.add(msg.reflex)
            else:
                self.holding.discard(msg.reflex)
            await self.report()

    async def send(self, commands: Iterable[Command]) -> None:
        for c in commands:
            if isinstance(c, Shutdown):
                self.actor.request_stop(c.reason)
            elif isinstance(c, Event):
                self.actor.emit(c)
            elif isinstance(c, ReflexRequest):
                if not self.actor.request.connected:
                    raise RuntimeError(
                        f"reflex {self.actor.name!r} asked the coordinator {c!r}, and its "
                        "request output is not wired"
                    )
                await self.actor.request.send(c)
            else:
                await self.actor.override.send(
                    JointGoals(
                        t=c.t, source=c.source, goals=c.goals, reflex=True, priority=self.priority
                    )
                )
        await self.report()

    def _activity(self) -> ReflexActivity | None:
        now = (self.policy.active and not self.holding, bool(self.holding))
        if now == self.said:
            return None
        self.said = now
        why = self.policy.reason if now[0] else ""
        if now[1]:
            why = "held back by " + ", ".join(sorted(self.holding))
        return ReflexActivity(
            t=self.actor.now(),
            source=self.actor.name,
            reflex=self.actor.name,
            active=now[0],
            reason=why,
            inhibits=self.inhibits,
            inhibited=now[1],
        )

    async def report(self) -> None:
        msg = self._activity()
        if msg is not None and self.actor.activity.connected:
            await self.actor.activity.send(msg)

    def going_down(self) -> None:
        """Not active any more (it failed, or the run stops): nobody stays held back."""
        if self.said[0] and self.actor.activity.connected:
            self.actor.activity.send_nowait(
                ReflexActivity(
                    t=self.actor.now(),
                    source=self.actor.name,
                    reflex=self.actor.name,
                    active=False,
                    reason="stopped",
                    inhibits=self.inhibits,
                )
            )
