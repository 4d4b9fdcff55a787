"""The runtime: starts, supervises and stops the actors of one graph.

Theory of operation
-------------------
One root task group owns everything. :meth:`Runtime.run`

1. makes the clock and the channels (one bounded buffer per subscriber);
2. starts the actors in graph order, one at a time, each under its own
   supervisor task via ``await tg.start(...)``: actor *n+1* starts only once
   actor *n* has called ``ready()`` (its resources are open);
3. waits for a stop request: SIGINT/SIGTERM (when ``handle_signals``), the
   end of ``duration``, :meth:`Runtime.request_stop`, or an escalation;
4. after an escalation, runs the **safe stop** first: the runtime's hooks,
   then every live actor's :meth:`~whexar.runtime.actor.Actor.safe_stop`,
   newest first, each bounded by the stop timeout;
5. stops the actors in reverse start order, cancelling each and giving it
   ``stop_timeout_s`` to finish its shielded cleanup before moving on.

Supervision: an actor whose ``run()`` raises (or does not report ready in
``ready_timeout_s``) is discarded; after its policy's delay a fresh instance
starts, unless that failure makes more than ``max_restarts`` within
``window_s``. Then the actor is *escalated*: it stays down, the runtime stops
safely and :meth:`run` returns :data:`EXIT_ESCALATED`. Every step is an
:class:`~whexar.runtime.messages.Event` on the ``events`` channel.
"""

from __future__ import annotations

import math
import signal
from collections import deque
from collections.abc import Awaitable, Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Final

import anyio
from anyio import TASK_STATUS_IGNORED, CancelScope
from anyio.abc import TaskStatus

from whexar.runtime.actor import Actor, ActorContext
from whexar.runtime.channels import Channel, ChannelStats, Inbox, Observer, Outbox
from whexar.runtime.clock import Clock
from whexar.runtime.messages import (
    ActorEscalated,
    ActorFailed,
    ActorReady,
    ActorRestarted,
    ActorStarting,
    ActorStopped,
    Event,
    SafeStop,
    StopRequested,
)
from whexar.runtime.wiring import EVENTS_CHANNEL, RUNTIME, ActorNode, Graph

EXIT_CLEAN: Final = 0
"""Process exit status after a clean stop."""
EXIT_ESCALATED: Final = 3
"""Process exit status after an actor was escalated (1 and 2 are the CLI's input errors)."""

SafeStopHook = Callable[[str], Awaitable[None]]
"""Called with the escalation's reason before the actors stop."""


@dataclass(eq=False)
class _Slot:
    """The runtime's record of one actor across its incarnations."""

    node: ActorNode
    scope: CancelScope = field(default_factory=CancelScope)
    done: anyio.Event = field(default_factory=anyio.Event)
    inboxes: dict[str, Inbox[Any]] = field(default_factory=dict)
    """One buffer per input, made once per run: a restarted actor finds its backlog."""
    actor: Actor | None = None
    launched: bool = False
    """Its supervisor task was started (a stop during start leaves later actors unlaunched)."""
    ready: bool = False
    reported: bool = False
    """Its first incarnation reported ready (the start loop has gone on)."""
    stop_reported: bool = False
    cut_short: bool = False
    """Its last cleanup overran the stop timeout and was cut off."""


def describe(exc: BaseException) -> str:
    """``TypeName: message`` of an exception (the first leaf of a group)."""
    while isinstance(exc, BaseExceptionGroup) and exc.exceptions:
        exc = exc.exceptions[0]
    text = str(exc)
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


class Runtime:
    """Runs one :class:`~whexar.runtime.wiring.Graph`; make a new one for each run."""

    def __init__(
        self,
        graph: Graph,
        *,
        observer: Observer | None = None,
        handle_signals: bool = False,
        safe_stop_hooks: Sequence[SafeStopHook] = (),
    ) -> None:
        self.graph = graph
        self.settings = graph.settings
        self.observer = observer
        self.handle_signals = handle_signals
        self.safe_stop_hooks = list(safe_stop_hooks)
        self.channels: dict[str, Channel[Any]] = {}
        self.started: list[str] = []
        """Names of the actors that reached ready, in start order."""
        self.stop_reason: str | None = None
        self.escalated = False
        self._clock: Clock | None = None
        self._slots: list[_Slot] = []
        self._starting: _Slot | None = None
        self._stop: anyio.Event | None = None

    # ----------------------------------------------------------------- public API

    @property
    def clock(self) -> Clock:
        """The run's clock (exists once :meth:`run` has begun)."""
        if self._clock is None:
            raise RuntimeError("the runtime is not running")
        return self._clock

    def channel(self, name: str) -> Channel[Any]:
        """The live channel called ``name`` (for feeding it from outside the graph)."""
        return self.channels[name]

    def stats(self) -> list[ChannelStats]:
        """Counters of every channel."""
        return [ch.stats() for ch in self.channels.values()]

    def emit(self, event: Event) -> None:
        """Put ``event`` on the ``events`` channel; never waits (overflow is counted)."""
        self.channels[EVENTS_CHANNEL].send_nowait(event)

    @property
    def stopping(self) -> bool:
        """True once a stop was requested."""
        return self._stop is not None and self._stop.is_set()

    def request_stop(self, reason: str) -> None:
        """Ask the runtime to stop; the first reason given is kept."""
        if self._stop is None or self._stop.is_set():
            return
        self.stop_reason = reason
        self.emit(StopRequested(t=self.clock.now(), source=RUNTIME, reason=reason))
        self._stop.set()
        if self._starting is not None:  # do not wait for an actor that is still starting
            self._starting.scope.cancel()

    def request_safe_stop(self, reason: str) -> None:
        """Stop as after an escalation: safe stop first, then exit status 3.

        For an actor that lost hardware it cannot do without (a femur servo,
        the servo port): the robot must be brought to rest, not just left.
        """
        if self._stop is None or self._stop.is_set():
            return
        self.escalated = True
        self.request_stop(f"safe stop: {reason}")

    async def run(
        self,
        *,
        duration: float | None = None,
        task_status: TaskStatus[Runtime] = TASK_STATUS_IGNORED,
    ) -> int:
        """Run the graph until stopped; returns the exit status (0 clean, 3 escalated).

        ``task_status.started(self)`` fires once every actor is ready (or the
        start was cut short by a stop), so ``await tg.start(runtime.run)``
        resumes with the graph up.
        """
        if self._stop is not None:
            raise RuntimeError("a Runtime runs once; make a new one")
        self._clock = Clock()
        self._stop = anyio.Event()
        self._open_channels()
        self._slots = [_Slot(node) for node in self.graph.actors]
        for slot in self._slots:
            slot.inboxes = {
                port: Inbox(None, None)
                if channel is None
                else Inbox(channel, self.channels[channel].subscribe(slot.node.name))
                for port, channel in slot.node.inputs.items()
            }
        async with anyio.create_task_group() as tg:
            if self.handle_signals:
                await tg.start(self._watch_signals)
            if duration is not None:
                tg.start_soon(self._stop_after, duration)
            for slot in self._slots:
                if self._stop.is_set():
                    break
                self._starting = slot
                slot.launched = True
                await tg.start(self._supervise, slot)
                self._starting = None
            task_status.started(self)
            await self._stop.wait()
            if self.escalated:
                await self._safe_stop(self.stop_reason or "escalation")
            await self._stop_all()
            tg.cancel_scope.cancel()
        return EXIT_ESCALATED if self.escalated else EXIT_CLEAN

    # ----------------------------------------------------------------- internals

    def _open_channels(self) -> None:
        self.channels = {
            name: Channel(
                name, node.message_type, node.policy, node.capacity, observer=self.observer
            )
            for name, node in self.graph.channels.items()
        }

    def _context(self, slot: _Slot, on_ready: Callable[[], None]) -> ActorContext:
        node = slot.node
        return ActorContext(
            name=node.name,
            clock=self.clock,
            params=node.params,
            inboxes=slot.inboxes,
            outboxes={
                port: Outbox(tuple(self.channels[c] for c in chans))
                for port, chans in node.outputs.items()
            },
            emit=self.emit,
            ready=on_ready,
            request_stop=self.request_stop,
            request_safe_stop=self.request_safe_stop,
            stop_timeout_s=self.settings.stop_timeout_s,
        )

    async def _supervise(self, slot: _Slot, *, task_status: TaskStatus[None]) -> None:
        node = slot.node
        policy = node.restart
        clock = self.clock
        failures: deque[float] = deque()
        reason = "stop"
        try:
            with slot.scope:
                incarnation = 0
                while True:
                    error = await self._incarnate(slot, incarnation, task_status)
                    if error is None:
                        reason = "returned"
                        break
                    if self.stopping:
                        break  # a failure while stopping is reported, never restarted
                    now = clock.now()
                    failures.append(now)
                    while failures[0] < now - policy.window_s:
                        failures.popleft()
                    if len(failures) > policy.max_restarts:
                        reason = "escalated"
                        self._escalate(node, len(failures), error)
                        break
                    await clock.sleep(policy.delay_s)
                    incarnation += 1
                    self.emit(
                        ActorRestarted(
                            t=clock.now(),
                            source=RUNTIME,
                            actor=node.name,
                            incarnation=incarnation,
                            failures=len(failures),
                        )
                    )
        finally:
            if not slot.reported:
                task_status.started()  # let the start loop go on (to stop)
            if not slot.stop_reported:
                slot.stop_reported = True
                self.emit(
                    ActorStopped(
                        t=clock.now(),
                        source=RUNTIME,
                        actor=node.name,
                        reason=reason,
                        timed_out=slot.cut_short,
                    )
                )
            slot.done.set()

    async def _incarnate(
        self, slot: _Slot, incarnation: int, task_status: TaskStatus[None]
    ) -> str | None:
        """Run one fresh instance; ``None`` if it returned after ready, else what went wrong."""
        node = slot.node
        clock = self.clock
        ready_scope = CancelScope(deadline=clock.deadline(self.settings.ready_timeout_s))
        is_ready = False

        def on_ready() -> None:
            nonlocal is_ready
            if is_ready:
                return
            is_ready = slot.ready = True
            ready_scope.deadline = math.inf
            self.emit(
                ActorReady(t=clock.now(), source=RUNTIME, actor=node.name, incarnation=incarnation)
            )
            if not slot.reported:
                slot.reported = True
                self.started.append(node.name)
                task_status.started()

        self.emit(
            ActorStarting(t=clock.now(), source=RUNTIME, actor=node.name, incarnation=incarnation)
        )
        actor = node.cls(self._context(slot, on_ready))
        slot.actor = actor
        error: str
        try:
            with ready_scope:
                await actor.run()
        except Exception as exc:
            error = describe(exc)
        else:
            if ready_scope.cancelled_caught:
                error = f"did not report ready within {self.settings.ready_timeout_s} s"
            elif not is_ready:
                error = "run() returned before reporting ready"
            else:
                return None
        finally:
            slot.actor = None
            slot.ready = False
            slot.cut_short = actor.cut_short
        self.emit(
            ActorFailed(
                t=clock.now(),
                source=RUNTIME,
                actor=node.name,
                incarnation=incarnation,
                phase="run" if is_ready else "start",
                error=error,
            )
        )
        return error

    def _escalate(self, node: ActorNode, failures: int, error: str) -> None:
        window = node.restart.window_s
        self.emit(
            ActorEscalated(
                t=self.clock.now(),
                source=RUNTIME,
                actor=node.name,
                failures=failures,
                window_s=window,
            )
        )
        self.escalated = True
        self.request_stop(
            f"escalation: actor {node.name!r} failed {failures} times "
            f"within {window:g} s (last: {error})"
        )

    async def _safe_stop(self, reason: str) -> None:
        clock = self.clock
        self.emit(SafeStop(t=clock.now(), source=RUNTIME, reason=reason))
        timeout = self.settings.stop_timeout_s
        for hook in self.safe_stop_hooks:
            try:
                with anyio.move_on_after(timeout):
                    await hook(reason)
            except Exception as exc:  # one broken hook must not skip the rest of the safe stop
                name = getattr(hook, "__qualname__", repr(hook))
                self.emit(
                    ActorFailed(
                        t=clock.now(),
                        source=RUNTIME,
                        actor=RUNTIME,
                        incarnation=-1,
                        phase="safe_stop",
                        error=f"hook {name}: {describe(exc)}",
                    )
                )
        for slot in reversed(self._slots):
            actor = slot.actor
            if actor is None or not slot.ready:
                continue
            try:
                with anyio.move_on_after(timeout):
                    await actor.safe_stop(reason)
            except Exception as exc:
                self.emit(
                    ActorFailed(
                        t=clock.now(),
                        source=RUNTIME,
                        actor=slot.node.name,
                        incarnation=-1,
                        phase="safe_stop",
                        error=describe(exc),
                    )
                )

    async def _stop_all(self) -> None:
        clock = self.clock
        for slot in reversed(self._slots):
            if not slot.launched or slot.done.is_set():
                continue  # never started, or already ended: nothing to wait for
            slot.scope.cancel()
            with anyio.move_on_after(self.settings.stop_timeout_s):
                await slot.done.wait()
            if not slot.done.is_set() and not slot.stop_reported:
                slot.stop_reported = True
                self.emit(
                    ActorStopped(
                        t=clock.now(),
                        source=RUNTIME,
                        actor=slot.node.name,
                        reason="stop",
                        timed_out=True,
                    )
                )

    async def _stop_after(self, duration: float) -> None:
        await self.clock.sleep_until(duration)
        self.request_stop(f"duration {duration:g} s elapsed")

    async def _watch_signals(self, *, task_status: TaskStatus[None]) -> None:
        with anyio.open_signal_receiver(signal.SIGINT, signal.SIGTERM) as signals:
            task_status.started()
            async for signum in signals:
                self.request_stop(f"signal {signal.Signals(signum).name}")
