"""The actor base class and its typed ports.

Theory of operation
-------------------
An actor is a class with typed ports and one coroutine, :meth:`Actor.run`.
The runtime makes an instance, gives it its ports and clock through an
:class:`ActorContext`, and awaits ``run()`` inside its supervisor task. The
lifecycle is start → ready → run → stop:

* **start** — ``run()`` begins and opens its resources (a port, a file);
* **ready** — it calls :meth:`Actor.ready` once they are open, as a task
  started with anyio's ``TaskGroup.start`` calls ``task_status.started()``;
  the runtime starts the next actor only then;
* **run** — it works: reads its inputs, ticks, publishes;
* **stop** — the runtime cancels it; cleanup that must await (servos to a
  safe state) goes under :meth:`Actor.shielded`, which bounds it by the
  runtime's stop timeout.

An actor that raises is discarded and a fresh instance is started per its
restart policy, so state never survives a failure half-updated.

Ports are class attributes::

    class Echo(Actor):
        inp = Input(Heartbeat)
        out = Output(Heartbeat)

        async def run(self) -> None:
            self.ready()
            async for beat in self.inp:
                await self.out.send(beat)

The wiring configuration connects each port to a channel by name; reading
``self.inp`` on an instance gives its :class:`~whexar.runtime.channels.Inbox`,
``self.out`` its :class:`~whexar.runtime.channels.Outbox`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from functools import partial
from typing import Any, ClassVar, Generic, TypeVar, overload

from anyio import CancelScope
from pydantic import BaseModel, ConfigDict

from whexar.runtime.channels import Inbox, LinkObserver, LinkTap, Outbox
from whexar.runtime.clock import Clock
from whexar.runtime.messages import Event, Message
from whexar.runtime.ticker import Ticker

M = TypeVar("M", bound=Message)


class ActorParams(BaseModel):
    """Base of an actor's ``Params``: validated from the wiring's ``params`` table."""

    model_config = ConfigDict(extra="forbid", frozen=True)


class _Port(Generic[M]):
    """What :class:`Input` and :class:`Output` share: a message type and a name."""

    direction: ClassVar[str]

    def __init__(self, message_type: type[M], *, optional: bool = False) -> None:
        self.message_type = message_type
        self.optional = optional
        self.name = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __repr__(self) -> str:
        opt = ", optional" if self.optional else ""
        return f"{type(self).__name__}({self.message_type.__name__}{opt})"


class Input(_Port[M]):
    """An input port: the actor receives messages of ``message_type`` (or subclasses)."""

    direction = "input"

    @overload
    def __get__(self, obj: None, owner: type) -> Input[M]: ...
    @overload
    def __get__(self, obj: Actor, owner: type) -> Inbox[M]: ...
    def __get__(self, obj: Actor | None, owner: type) -> Input[M] | Inbox[M]:
        if obj is None:
            return self
        inbox: Inbox[M] = obj._ctx.inboxes[self.name]
        return inbox


class Output(_Port[M]):
    """An output port: the actor publishes messages of ``message_type``."""

    direction = "output"

    @overload
    def __get__(self, obj: None, owner: type) -> Output[M]: ...
    @overload
    def __get__(self, obj: Actor, owner: type) -> Outbox[M]: ...
    def __get__(self, obj: Actor | None, owner: type) -> Output[M] | Outbox[M]:
        if obj is None:
            return self
        outbox: Outbox[M] = obj._ctx.outboxes[self.name]
        return outbox


@dataclass(frozen=True)
class ActorContext:
    """Everything the runtime hands an actor instance."""

    name: str
    clock: Clock
    params: ActorParams
    inboxes: Mapping[str, Inbox[Any]]
    outboxes: Mapping[str, Outbox[Any]]
    emit: Callable[[Event], None]
    ready: Callable[[], None]
    request_stop: Callable[[str], None]
    request_safe_stop: Callable[[str], None]
    stop_timeout_s: float
    link_observer: LinkObserver | None = None


class Actor:
    """Base of every actor; subclasses declare ports and ``Params`` and implement :meth:`run`."""

    Params: ClassVar[type[ActorParams]] = ActorParams
    """The model the wiring's ``params`` table is validated against."""

    def __init__(self, ctx: ActorContext) -> None:
        self._ctx = ctx
        self.name = ctx.name
        self.clock = ctx.clock
        self.params = ctx.params
        self.cut_short = False
        """Set when cleanup under :meth:`shielded` overran the stop timeout."""

    @classmethod
    def ports(cls) -> dict[str, Input[Any] | Output[Any]]:
        """Every port the class declares (own and inherited), by name."""
        found: dict[str, Input[Any] | Output[Any]] = {}
        for klass in reversed(cls.__mro__):
            for name, value in vars(klass).items():
                if isinstance(value, Input | Output):
                    found[name] = value
        return found

    async def run(self) -> None:
        """The actor's work: open resources, call :meth:`ready`, then loop until cancelled."""
        raise NotImplementedError(f"{type(self).__name__} does not implement run()")

    async def safe_stop(self, reason: str) -> None:
        """Bring what this actor drives to a safe state; called on escalation, before stop.

        The default does nothing. The bus scheduler overrides it (servos to
        their shutdown state). It runs while :meth:`run` is still active and
        is bounded by the stop timeout.
        """

    def ready(self) -> None:
        """Report that the actor's resources are open; the runtime then starts the next one."""
        self._ctx.ready()

    def now(self) -> float:
        """The runtime clock's time, in seconds."""
        return self.clock.now()

    def emit(self, event: Event) -> None:
        """Put ``event`` on the runtime's event stream (never waits)."""
        self._ctx.emit(event)

    def request_stop(self, reason: str) -> None:
        """Ask the runtime to stop every actor (a scenario that has run its course)."""
        self._ctx.request_stop(f"{self.name}: {reason}")

    def request_safe_stop(self, reason: str) -> None:
        """Ask the runtime for a safe stop (every actor's :meth:`safe_stop`, then exit 3)."""
        self._ctx.request_safe_stop(f"{self.name}: {reason}")

    def tap(self) -> LinkTap | None:
        """Where this actor reports the raw bytes of the device link it owns, or ``None``
        when nobody records them. The link is named after the actor; the bytes go
        unchanged, in both directions, with the runtime clock's time."""
        observer = self._ctx.link_observer
        if observer is None:
            return None
        return partial(observer, self.name)

    def ticker(self, period_s: float, *, start: float | None = None) -> Ticker:
        """A deadline ticker on the runtime clock whose overruns go to the event stream."""
        return Ticker(self.clock, period_s, actor=self.name, emit=self._ctx.emit, start=start)

    @contextmanager
    def shielded(self) -> Iterator[CancelScope]:
        """A shielded scope for cleanup after cancellation, bounded by the stop timeout.

        Cleanup cut off at the bound is reported: the actor's ``ActorStopped``
        event says ``timed_out=True``.
        """
        with CancelScope(
            shield=True, deadline=self.clock.deadline(self._ctx.stop_timeout_s)
        ) as scope:
            yield scope
        if scope.cancelled_caught:
            self.cut_short = True
