"""Run actor graphs on virtual time and look at everything they said.

Theory of operation
-------------------
:func:`run_actors` builds the graph, runs it under a
:class:`~whexar.runtime.supervisor.Runtime` on a
:class:`~whexar.runtime.clock.VirtualEventLoop`, and records every message
published on every channel — runtime events included — in a
:class:`MessageLog`, in publish order. A *scenario* coroutine may run beside
the graph once every actor is ready, with a :class:`Harness` to feed
channels, sleep on the runtime clock, wait for a message and stop the run.

Because virtual time is deterministic, the same graph and scenario give the
same log every time; :meth:`MessageLog.digest` turns a log into a hash to
compare runs.
"""

from __future__ import annotations

import hashlib
from collections.abc import Awaitable, Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, TypeVar, overload

import anyio
from anyio.abc import TaskStatus

from whexar.runtime.channels import ChannelStats, LinkObserver, Observer, fan_out
from whexar.runtime.clock import run as run_loop
from whexar.runtime.errors import UsageError
from whexar.runtime.messages import Event, Message
from whexar.runtime.supervisor import Runtime
from whexar.runtime.wiring import EVENTS_CHANNEL, Graph, GraphSpec, build_graph

M = TypeVar("M", bound=Message)

HARNESS = "harness"
"""Publisher name of the channels a harness feeds (and ``source`` of what it makes)."""


@dataclass(frozen=True, slots=True)
class LogEntry:
    """One publish: the channel and the message."""

    channel: str
    message: Message


@dataclass
class MessageLog:
    """Every message published during a run, in order; callable as a channel observer."""

    entries: list[LogEntry] = field(default_factory=list)
    _changed: anyio.Event | None = None

    def __call__(self, channel: str, msg: Message) -> None:
        self.entries.append(LogEntry(channel, msg))
        if self._changed is not None:
            self._changed.set()
            self._changed = None

    async def changed(self) -> None:
        """Wait until the next message is logged."""
        if self._changed is None:
            self._changed = anyio.Event()
        await self._changed.wait()

    @overload
    def messages(self, channel: str | None = None) -> list[Message]: ...
    @overload
    def messages(self, channel: str | None = None, *, of: type[M]) -> list[M]: ...
    def messages(self, channel: str | None = None, *, of: type[Message] = Message) -> list[Any]:
        """Messages published on ``channel`` (every channel if ``None``) of type ``of``."""
        return [
            e.message
            for e in self.entries
            if (channel is None or e.channel == channel) and isinstance(e.message, of)
        ]

    @overload
    def events(self) -> list[Event]: ...
    @overload
    def events(self, of: type[M]) -> list[M]: ...
    def events(self, of: type[Message] = Event) -> list[Any]:
        """Runtime events of type ``of``, in order."""
        return self.messages(EVENTS_CHANNEL, of=of)

    def lines(self) -> list[str]:
        """One stable text line per entry: ``channel repr(message)``."""
        return [f"{e.channel} {e.message!r}" for e in self.entries]

    def digest(self) -> str:
        """SHA-256 of :meth:`lines`: equal digests mean identical runs."""
        h = hashlib.sha256()
        for line in self.lines():
            h.update(line.encode())
            h.update(b"\n")
        return h.hexdigest()


class Harness:
    """What a scenario gets: the live runtime, its clock, the log, and ways to act."""

    def __init__(self, runtime: Runtime, log: MessageLog) -> None:
        self.runtime = runtime
        self.log = log
        self.clock = runtime.clock

    def now(self) -> float:
        """Runtime clock time, in seconds."""
        return self.clock.now()

    async def sleep(self, dt: float) -> None:
        """Let ``dt`` seconds of runtime time pass."""
        await self.clock.sleep(dt)

    async def sleep_until(self, t: float) -> None:
        """Let runtime time reach ``t``."""
        await self.clock.sleep_until(t)

    async def feed(self, channel: str, msg: Message) -> None:
        """Publish ``msg`` on ``channel`` (which must be listed in ``feeds``)."""
        await self.runtime.channel(channel).send(msg)

    async def wait_for(
        self,
        of: type[M],
        where: Callable[[M], bool] | None = None,
        *,
        channel: str | None = None,
        timeout: float = 10.0,
    ) -> M:
        """The first message of type ``of`` (matching ``where``) logged from now on.

        Raises :class:`TimeoutError` after ``timeout`` seconds of runtime time.
        """
        seen = len(self.log.entries)
        with anyio.fail_after(timeout):
            while True:
                for entry in self.log.entries[seen:]:
                    msg = entry.message
                    if (
                        isinstance(msg, of)
                        and (channel is None or entry.channel == channel)
                        and (where is None or where(msg))
                    ):
                        return msg
                seen = len(self.log.entries)
                await self.log.changed()

    def stop(self, reason: str = "scenario asked to stop") -> None:
        """Ask the runtime to stop."""
        self.runtime.request_stop(reason)


@dataclass(frozen=True)
class RunResult:
    """What a finished run left: exit status, the message log, counters."""

    exit_code: int
    log: MessageLog
    stop_reason: str | None
    started: list[str]
    stats: dict[str, ChannelStats]
    end_time: float

    @property
    def digest(self) -> str:
        """The log's SHA-256 (see :meth:`MessageLog.digest`)."""
        return self.log.digest()

    @overload
    def events(self) -> list[Event]: ...
    @overload
    def events(self, of: type[M]) -> list[M]: ...
    def events(self, of: type[Message] = Event) -> list[Any]:
        """Runtime events of type ``of``, in order."""
        return self.log.events(of)

    @overload
    def messages(self, channel: str | None = None) -> list[Message]: ...
    @overload
    def messages(self, channel: str | None = None, *, of: type[M]) -> list[M]: ...
    def messages(self, channel: str | None = None, *, of: type[Message] = Message) -> list[Any]:
        """Messages published on ``channel`` of type ``of``."""
        return self.log.messages(channel, of=of)


Scenario = Callable[[Harness], Awaitable[None]]


def _leaf(exc: BaseException) -> BaseException:
    while isinstance(exc, BaseExceptionGroup) and len(exc.exceptions) == 1:
        exc = exc.exceptions[0]
    return exc


def _observer(log: MessageLog | None, observers: Sequence[Observer]) -> Observer | None:
    found = [o for o in (log, *observers) if o is not None]
    if not found:
        return None
    return found[0] if len(found) == 1 else fan_out(*found)


def run_actors(
    graph: Graph | GraphSpec | Mapping[str, Any],
    *,
    duration: float | None = None,
    scenario: Scenario | None = None,
    feeds: Iterable[str] = (),
    virtual: bool = True,
    handle_signals: bool = False,
    deadlock_after_s: float | None = 10.0,
    real_io: bool = False,
    observers: Sequence[Observer] = (),
    link_observer: LinkObserver | None = None,
    keep_log: bool = True,
) -> RunResult:
    """Run ``graph`` (on virtual time by default) and return everything it published.

    The run ends after ``duration`` seconds of runtime time; with no
    duration, when ``scenario`` returns. A scenario still running when the
    run ends (its duration is over, an actor was escalated) is cancelled.
    ``feeds`` names the channels the scenario publishes on. An exception in
    the scenario (a failed assert) propagates unwrapped.

    On virtual time, real I/O (a pty, a socket, a worker thread) is refused
    with :class:`~whexar.runtime.clock.VirtualTimeRealIOError` unless
    ``real_io=True`` (or the graph's ``real_io_on_virtual_time``) says the
    test means it: virtual time runs away while real I/O is pending.

    ``observers`` see every message too, after the log (a recorder);
    ``link_observer`` sees the raw bytes of the device links
    (:class:`~whexar.runtime.supervisor.Runtime`). ``keep_log=False`` keeps no
    message (the result's log and the harness's stay empty): a long run whose
    observers see everything needs no copy of it, nor the garbage collector's
    time to walk it.
    """
    if not isinstance(graph, Graph):
        graph = build_graph(graph, external=dict.fromkeys(feeds, HARNESS))
    if duration is None and scenario is None:
        raise UsageError("run_actors needs a duration, a scenario, or both")
    built: Graph = graph
    log = MessageLog()
    runtime = Runtime(
        built,
        observer=_observer(log if keep_log else None, observers),
        link_observer=link_observer,
        handle_signals=handle_signals,
    )
    codes: list[int] = []

    async def main() -> float:
        async with anyio.create_task_group() as tg:

            async def _run(*, task_status: TaskStatus[Runtime]) -> None:
                codes.append(await runtime.run(duration=duration, task_status=task_status))
                tg.cancel_scope.cancel()  # the run is over: so is a scenario still waiting

            await tg.start(_run)
            if scenario is not None:
                await scenario(Harness(runtime, log))
                if duration is None:
                    runtime.request_stop("scenario finished")
        return runtime.clock.now()

    try:
        end = run_loop(main, virtual=virtual, deadlock_after_s=deadlock_after_s, real_io=real_io)
    except BaseExceptionGroup as group:
        raise _leaf(group) from None
    return RunResult(
        exit_code=codes[0],
        log=log,
        stop_reason=runtime.stop_reason,
        started=list(runtime.started),
        stats={s.channel: s for s in runtime.stats()},
        end_time=end,
    )
