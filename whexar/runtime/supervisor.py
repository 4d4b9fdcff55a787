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
safely and :meth:`run` returns :data:`EXIT_ESCALATED` — or, where its policy
says ``exhausted = "disable"`` (an actor the robot can do without, such as a
reflex), it is *disabled*: it stays down and the rest runs on. Every step is an
:class:`~whexar.runtime.messages.Event` on the ``events`` channel; a failure
carries its traceback. ``SystemExit`` (``sys.exit()``) and
``KeyboardInterrupt`` raised in an actor are failures like any other: an
actor never ends the process. Only cancellation passes through.

A stop that always ends
-----------------------
Every step of a stop is bounded by ``stop_timeout_s``: each safe-stop hook
and each actor's ``safe_stop`` (after an escalation), then each actor's stop.
An actor whose cleanup overruns its step is reported (``timed_out``) and
passed over. :meth:`Runtime.stop_bound_s` is the sum. With
``handle_signals`` the runtime owns the process, and makes that bound hold
even when an actor's cleanup ignores cancellation or blocks the event loop:

* SIGINT and SIGTERM are caught by a Python-level handler, which runs between
  two bytecodes even while the loop is blocked. It arms a :class:`WallAlarm`
  (a thread) for the stop's bound plus :data:`EXIT_GRACE_S`, then asks the
  loop to stop. Stops for other reasons arm it too.
* When the steps are done and an actor is still running (its cleanup ignored
  the cancellation), the process exits at once instead of waiting for it.
  If the loop itself is stuck, the alarm ends the process. Either way the
  exit status is the run's own (0, or 3 after an escalation), and a line on
  stderr names what was left behind.
* A second SIGINT runs the safe stop (the hooks, then every live actor's
  ``safe_stop``, each bounded; at once if one is already under way) and
  exits with :data:`EXIT_INTERRUPTED` without waiting for any cleanup; the
  alarm bounds that too.

On virtual time, real I/O the loop notices (:mod:`whexar.runtime.clock`) is
refused unless the graph sets ``real_io_on_virtual_time``: the runtime stops
in order and :meth:`Runtime.run` raises the
:class:`~whexar.runtime.clock.VirtualTimeRealIOError`.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import os
import signal
import sys
import traceback
from collections import deque
from collections.abc import Awaitable, Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from types import FrameType
from typing import Any, Final

import anyio
from anyio import TASK_STATUS_IGNORED, CancelScope
from anyio.abc import TaskStatus

from whexar.runtime.actor import Actor, ActorContext
from whexar.runtime.channels import (
    Channel,
    ChannelStats,
    Inbox,
    LinkObserver,
    Observer,
    Outbox,
    Turn,
)
from whexar.runtime.clock import Clock, VirtualTimeRealIOError, WallAlarm
from whexar.runtime.errors import DeviceUnavailableError, UsageError
from whexar.runtime.messages import (
    ActorDisabled,
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
EXIT_REFUSED: Final = 2
"""Process exit status of a refused run (real I/O on virtual time): the CLI's bad input."""
EXIT_ESCALATED: Final = 3
"""Process exit status after an actor was escalated (1 and 2 are the CLI's input errors)."""
EXIT_UNAVAILABLE: Final = 4
"""Process exit status when a device was missing, busy or not permitted at an actor's
start (:class:`~whexar.runtime.errors.DeviceUnavailableError`): the run stopped, no restart."""
EXIT_INTERRUPTED: Final = 130
"""Process exit status after a second SIGINT (128 + SIGINT, as a shell reports Ctrl-C)."""
EXIT_GRACE_S: Final = 1.0
"""Wall time past a stop's bound for the process to wind down before the alarm ends it."""

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
    turn: Turn = field(default_factory=Turn)
    """Its fairness budget, shared by all its ports (see :mod:`whexar.runtime.channels`)."""
    actor: Actor | None = None
    task: asyncio.Task[Any] | None = None
    """Its supervisor task, in which each incarnation's ``run()`` runs."""
    launched: bool = False
    """Its supervisor task was started (a stop during start leaves later actors unlaunched)."""
    ready: bool = False
    reported: bool = False
    """Its first incarnation reported ready (the start loop has gone on)."""
    stop_reported: bool = False
    cut_short: bool = False
    """Its last cleanup overran the stop timeout and was cut off."""


def _leaf(exc: BaseException) -> BaseException:
    """The first leaf of an exception group (an actor's task group wraps what it raised)."""
    while isinstance(exc, BaseExceptionGroup) and exc.exceptions:
        exc = exc.exceptions[0]
    return exc


def describe(exc: BaseException) -> str:
    """``TypeName: message`` of an exception (the first leaf of a group)."""
    exc = _leaf(exc)
    text = str(exc)
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def formatted_traceback(exc: BaseException) -> str:
    """The traceback of ``exc`` as Python prints it (a group with every leaf)."""
    return "".join(traceback.format_exception(exc))


def _is_cancellation(exc: BaseException) -> bool:
    """Cancellation (alone, or a group of nothing else) must pass; anything else is a failure."""
    cancelled = anyio.get_cancelled_exc_class()
    if isinstance(exc, BaseExceptionGroup):
        return exc.split(cancelled)[1] is None
    return isinstance(exc, cancelled)


class Runtime:
    """Runs one :class:`~whexar.runtime.wiring.Graph`; make a new one for each run.

    ``observer`` is called with every message published, ``link_observer`` with the
    raw bytes of every device link whose actor reports them (:meth:`Actor.tap
    <whexar.runtime.actor.Actor.tap>`); ``safe_stop_hooks``
    run first in a safe stop. ``handle_signals=True`` makes the runtime the
    owner of the process (the ``whexar run`` command): it catches SIGINT and
    SIGTERM and ends the process itself when a stop overruns its bound or a
    second SIGINT arrives (see the module docstring). Call :meth:`run` from
    the main thread then.
    """

    def __init__(
        self,
        graph: Graph,
        *,
        observer: Observer | None = None,
        link_observer: LinkObserver | None = None,
        handle_signals: bool = False,
        safe_stop_hooks: Sequence[SafeStopHook] = (),
    ) -> None:
        self.graph = graph
        self.settings = graph.settings
        self.observer = observer
        self.link_observer = link_observer
        self.handle_signals = handle_signals
        self.safe_stop_hooks = list(safe_stop_hooks)
        self.channels: dict[str, Channel[Any]] = {}
        self.started: list[str] = []
        """Names of the actors that reached ready, in start order."""
        self.stop_reason: str | None = None
        self.escalated = False
        self.interrupted = False
        """A second SIGINT asked to stop at once (after the safe stop)."""
        self.refusal: VirtualTimeRealIOError | None = None
        self.unavailable: str | None = None
        """What a device that was unavailable at an actor's start said (``None``: none)."""
        """Why the run was refused (real I/O on virtual time); :meth:`run` raises it."""
        self._clock: Clock | None = None
        self._slots: list[_Slot] = []
        self._starting: _Slot | None = None
        self._stop: anyio.Event | None = None
        self._running = False
        self._safe_stop_started = False
        self._safe_stop_done: anyio.Event | None = None
        self._alarm: WallAlarm | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._signals = 0
        self._urgent: asyncio.Task[None] | None = None

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
        if self._alarm is not None:
            self._alarm.arm(self.stop_bound_s() + EXIT_GRACE_S)
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

    def stop_bound_s(self) -> float:
        """The longest a stop may take now: every bounded step's timeout, summed.

        One ``stop_timeout_s`` per actor; after an escalation, one more per
        safe-stop hook and per actor for the safe stop.
        """
        actors = len(self._slots) or len(self.graph.actors)
        steps = actors + (len(self.safe_stop_hooks) + actors if self.escalated else 0)
        return steps * self.settings.stop_timeout_s

    def safe_stop_bound_s(self) -> float:
        """The longest the safe stop may take: each hook's and each actor's step, summed."""
        actors = len(self._slots) or len(self.graph.actors)
        return (len(self.safe_stop_hooks) + actors) * self.settings.stop_timeout_s

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
        self._clock = clock = Clock()
        self._stop = anyio.Event()
        self._safe_stop_done = anyio.Event()
        self._open_channels()
        self._slots = [_Slot(node) for node in self.graph.actors]
        for slot in self._slots:
            slot.inboxes = {
                port: Inbox(None, None)
                if channel is None
                else Inbox(channel, self.channels[channel].subscribe(slot.node.name), slot.turn)
                for port, channel in slot.node.inputs.items()
            }
        if self.settings.real_io_on_virtual_time:
            clock.allow_real_io()
        clock.on_real_io(self._refuse)
        self._running = True
        try:
            with self._owning_process():
                async with anyio.create_task_group() as tg:
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
                    self._leave_the_stuck()
                    tg.cancel_scope.cancel()
                if self._urgent is not None:  # a second SIGINT: it ends the process
                    with CancelScope(shield=True):
                        await self._urgent
        finally:
            self._running = False
            clock.on_real_io(None)
        if self.refusal is not None:
            raise self.refusal
        return self._exit_code()

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
                port: Outbox(tuple(self.channels[c] for c in chans), slot.turn)
                for port, chans in node.outputs.items()
            },
            emit=self.emit,
            ready=on_ready,
            request_stop=self.request_stop,
            request_safe_stop=self.request_safe_stop,
            stop_timeout_s=self.settings.stop_timeout_s,
            link_observer=self.link_observer,
        )

    async def _supervise(self, slot: _Slot, *, task_status: TaskStatus[None]) -> None:
        node = slot.node
        policy = node.restart
        clock = self.clock
        failures: deque[float] = deque()
        reason = "stop"
        slot.task = asyncio.current_task()
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
                        if policy.exhausted == "disable":
                            reason = "disabled"
                            self._disable(node, len(failures), error)
                        else:
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
        trace = ""
        raised: BaseException | None = None
        try:
            with ready_scope:
                await actor.run()
        except BaseException as exc:  # SystemExit, KeyboardInterrupt too: an actor's failure
            if _is_cancellation(exc):
                raise
            error, trace, raised = describe(exc), formatted_traceback(exc), exc
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
        leaf = _leaf(raised) if raised is not None else None
        unavailable = isinstance(leaf, DeviceUnavailableError) and not is_ready
        self.emit(
            ActorFailed(
                t=clock.now(),
                source=RUNTIME,
                actor=node.name,
                incarnation=incarnation,
                phase="run" if is_ready else "start",
                error=error,
                traceback="" if unavailable else trace,  # no bug: nothing to trace
            )
        )
        if isinstance(leaf, VirtualTimeRealIOError):
            self._refuse(leaf, node.name)  # no restart helps: allow it or run on real time
        elif unavailable:
            self._unavailable(str(leaf), node.name)  # no restart helps: plug it in, free it
        return error

    def _disable(self, node: ActorNode, failures: int, error: str) -> None:
        self.emit(
            ActorDisabled(
                t=self.clock.now(),
                source=RUNTIME,
                actor=node.name,
                failures=failures,
                window_s=node.restart.window_s,
                error=error,
            )
        )

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
        self._safe_stop_started = True
        try:
            await self._run_safe_stop(reason)
        finally:
            assert self._safe_stop_done is not None
            self._safe_stop_done.set()

    async def _run_safe_stop(self, reason: str) -> None:
        clock = self.clock
        self.emit(SafeStop(t=clock.now(), source=RUNTIME, reason=reason))
        timeout = self.settings.stop_timeout_s
        for hook in self.safe_stop_hooks:
            try:
                with anyio.move_on_after(timeout):
                    await hook(reason)
            except BaseException as exc:  # one broken hook must not skip the rest
                if _is_cancellation(exc):
                    raise
                name = getattr(hook, "__qualname__", repr(hook))
                self.emit(
                    ActorFailed(
                        t=clock.now(),
                        source=RUNTIME,
                        actor=RUNTIME,
                        incarnation=-1,
                        phase="safe_stop",
                        error=f"hook {name}: {describe(exc)}",
                        traceback=formatted_traceback(exc),
                    )
                )
        for slot in reversed(self._slots):
            actor = slot.actor
            if actor is None or not slot.ready:
                continue
            try:
                with anyio.move_on_after(timeout):
                    await actor.safe_stop(reason)
            except BaseException as exc:
                if _is_cancellation(exc):
                    raise
                self.emit(
                    ActorFailed(
                        t=clock.now(),
                        source=RUNTIME,
                        actor=slot.node.name,
                        incarnation=-1,
                        phase="safe_stop",
                        error=describe(exc),
                        traceback=formatted_traceback(exc),
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

    def _refuse(self, error: VirtualTimeRealIOError, actor: str | None = None) -> None:
        """Real I/O on virtual time: stop in order; :meth:`run` raises ``error`` at the end.

        ``actor`` raised it itself (:meth:`Clock.uses_real_io`); otherwise the
        loop noticed it, and names the actor when it happened in its task (a
        transport's callback or a thread belongs to no task: the error names
        the descriptor or the thread instead).
        """
        if self.refusal is not None:
            return
        if actor is None and error.task is not None:
            actor = next((s.node.name for s in self._slots if s.task is error.task), None)
        if actor is not None:
            error = VirtualTimeRealIOError(f"actor {actor!r}: {error.what}", error.task)
        self.refusal = error
        self.request_stop(f"refused: real I/O on virtual time ({error.what})")

    def _unavailable(self, what: str, actor: str) -> None:
        """A device missing, busy or not permitted at ``actor``'s start: stop in order,
        exit status :data:`EXIT_UNAVAILABLE`."""
        if self.unavailable is not None:
            return
        self.unavailable = f"actor {actor!r}: {what}"
        self.request_stop(f"device unavailable: {self.unavailable}")

    def _exit_code(self) -> int:
        if self.interrupted:
            return EXIT_INTERRUPTED
        if self.refusal is not None:
            return EXIT_REFUSED
        if self.unavailable is not None:
            return EXIT_UNAVAILABLE
        return EXIT_ESCALATED if self.escalated else EXIT_CLEAN

    def _still_running(self) -> list[str]:
        return [s.node.name for s in self._slots if s.launched and not s.done.is_set()]

    # ----------------------------------------------------------------- the process

    @contextmanager
    def _owning_process(self) -> Iterator[None]:
        """With ``handle_signals``: catch SIGINT/SIGTERM and keep the alarm (module docstring)."""
        if not self.handle_signals:
            yield
            return
        self._loop = asyncio.get_running_loop()
        self._alarm = WallAlarm(self._overran, name="whexar-stop-alarm")
        previous: dict[int, Any] = {}
        try:
            for signum in (signal.SIGINT, signal.SIGTERM):
                previous[signum] = signal.signal(signum, self._on_signal)
        except ValueError as exc:  # not the main thread
            self._restore(previous)
            raise UsageError(
                f"handle_signals=True: signals can only be caught in the main thread ({exc})"
            ) from None
        try:
            yield
        finally:
            self._restore(previous)

    def _restore(self, previous: dict[int, Any]) -> None:
        for signum, handler in previous.items():
            signal.signal(signum, signal.SIG_DFL if handler is None else handler)
        if self._alarm is not None:
            self._alarm.close()

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        # Runs in the main thread between two bytecodes, even while the loop is
        # blocked: it only counts, arms the alarm and hands the rest to the
        # loop, all of which is safe there (no lock is taken).
        loop, alarm = self._loop, self._alarm
        if loop is None or alarm is None:
            return
        self._signals += 1
        if self._signals == 1:
            alarm.arm(self.stop_bound_s() + EXIT_GRACE_S)
            loop.call_soon_threadsafe(self.request_stop, f"signal {signal.Signals(signum).name}")
        elif signum == signal.SIGINT and not self.interrupted:
            self.interrupted = True
            alarm.arm(self.safe_stop_bound_s() + EXIT_GRACE_S)
            loop.call_soon_threadsafe(self._interrupt)

    def _interrupt(self) -> None:
        """A second SIGINT: safe stop, then exit at once (on the loop, in a task of its own)."""
        if not self._running or self._loop is None:
            return  # the run is over: the process is about to end anyway
        self.request_stop("signal SIGINT")
        # Not in the task group: it may be cancelled already, and this task ends the process.
        self._urgent = self._loop.create_task(self._exit_after_safe_stop())

    async def _exit_after_safe_stop(self) -> None:
        with CancelScope(shield=True):
            if self._safe_stop_started:
                assert self._safe_stop_done is not None
                await self._safe_stop_done.wait()
            else:
                await self._safe_stop("second SIGINT: stop at once")
        self._exit_process("second SIGINT: safe stop done; not waiting for the actors' cleanup")

    def _leave_the_stuck(self) -> None:
        """Every step is done; an actor still running ignored its stop: do not wait for it."""
        stuck = self._still_running()
        if stuck and self.handle_signals:
            names = ", ".join(repr(n) for n in stuck)
            self._exit_process(
                f"{'actor' if len(stuck) == 1 else 'actors'} {names} still running after "
                f"the stop step (stop_timeout_s = {self.settings.stop_timeout_s:g}); "
                "not waiting any longer"
            )

    def _exit_process(self, why: str) -> None:
        """End the process now with the run's exit status (only when owning it)."""
        code = self._exit_code()
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(OSError, ValueError):  # closed: the line below still goes
                stream.flush()
        reason = f" (stopped: {self.stop_reason})" if self.stop_reason else ""
        os.write(2, f"whexar runtime: {why}{reason}; exit status {code}\n".encode())
        os._exit(code)

    def _overran(self) -> None:
        # The alarm's thread: the loop did not finish the stop within its bound.
        # No flush here: the blocked main thread may hold the streams' locks.
        code = self._exit_code()
        stuck = ", ".join(repr(n) for n in self._still_running()) or "none"
        os.write(
            2,
            f"whexar runtime: the stop overran its bound (is the event loop blocked?); "
            f"actors still running: {stuck}; exit status {code}\n".encode(),
        )
        os._exit(code)
