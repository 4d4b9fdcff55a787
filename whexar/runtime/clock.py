"""Time for the runtime: the one module that reads a clock.

Theory of operation
-------------------
Every actor reads time and sleeps through a :class:`Clock`, and a clock is a
view of the event loop's own time. Whether time is real or virtual is
therefore a property of the loop the runtime runs on, chosen once at
:func:`run`:

* **real time** — a stock asyncio loop; ``Clock.now()`` is monotonic seconds
  since the clock was made. This is what runs on the robot.
* **virtual time** — :class:`VirtualEventLoop`, an asyncio selector loop whose
  ``time()`` is a counter. Whenever no callback is ready and no file
  descriptor has anything to say, the loop jumps straight to the next timer
  instead of waiting for it. Tests, simulation and replay run here: the same
  inputs give the same interleaving every time, and a minute of robot time
  costs only the work done in it.

Why an own asyncio loop, and not trio's ``MockClock`` or ``looptime``
--------------------------------------------------------------------
* The serial transport of the sensor board is pyserial-asyncio, which needs
  asyncio; a trio-based virtual clock would keep it out of virtual-time
  tests. So the runtime is anyio on the asyncio backend, always.
* Measured here: 10 tasks ticking at 100 Hz for 60 virtual seconds (60,000
  wake-ups) take about 0.33 s of wall time on this loop, against about 1.5 s
  with ``looptime`` and 1.2 s with trio's ``MockClock`` (numbers from the
  project's notes on virtual time). The loop is thirty lines, with no
  dependency.

Deadlines are exact at any magnitude
------------------------------------
:meth:`Clock.sleep_until` schedules the timer at the deadline itself, and the
loop jumps to the timer's own time, so a 100 Hz ticker wakes at exactly
``t0 + k·0.01`` after any number of cycles. asyncio runs the timers due
before ``time() + clock resolution``; with a fixed resolution (1 ns) that sum
stops moving once one ulp of the time exceeds 2 ns — about 1.7e7 s — and the
timer at ``now`` never became due: the loop spun in place. The virtual loop
makes the resolution one ulp of its current time instead, so "due" means
exactly ``when <= now`` at any magnitude: epoch-stamped replays at 1.8e9 s
wake on their deadlines as a test at 0.1 s does. The loop's time stays the
float the deadline was given in (not integer nanoseconds): rounding to
nanoseconds would move 676 of the first 5,000 points of ``0.25 + k·0.01``
off the grid a ticker computes, so a tick's time would no longer equal the
time it woke at.

Virtual time and real I/O
-------------------------
Virtual time jumps whenever the loop has nothing to do, so anything that
waits on the real world — a serial port, a socket, a worker thread — lets it
run away (4,343 virtual seconds passed in one second of waiting for a pty).
The virtual loop therefore notices real I/O: a file descriptor it is asked to
watch (other than its own wake-up pipe), work handed to an executor, or a
worker thread calling back into it (which is how every asyncio and anyio way
of running a thread reports). Unless real I/O was allowed explicitly
(``real_io=True`` here, ``[runtime] real_io_on_virtual_time = true`` in a
wiring file), the first such notice is refused with
:class:`VirtualTimeRealIOError`: the runtime stops the graph in order and
raises it; a bare :func:`run` raises it from the loop. A descriptor is
noticed when it is registered; a thread only when it first calls back, and
virtual time may have jumped while it worked. So an actor that knows it is
about to open a real device says so first with :meth:`Clock.uses_real_io`,
which refuses at once, before anything is opened, and names the device.
Allowed real I/O works as on a real loop — the loop polls descriptors
without waiting before every jump and bytes ready win over the jump — but it
is not deterministic in time, and work in a thread stays invisible to the
loop while it runs.

Nothing may wait on the wall clock outside this module; a process-level
deadline (:class:`WallAlarm`) lives here too.
"""

from __future__ import annotations

import asyncio
import contextlib
import contextvars
import math
import os
import select
import selectors
import struct
import threading
import time
from collections.abc import Awaitable, Callable
from concurrent.futures import Executor
from typing import Any, TypeVar, TypeVarTuple, cast

import anyio

from whexar.runtime.errors import UsageError

T = TypeVar("T")
Ts = TypeVarTuple("Ts")

__all__ = [
    "Clock",
    "RealIOHandler",
    "VirtualEventLoop",
    "VirtualTimeDeadlockError",
    "VirtualTimeRealIOError",
    "WallAlarm",
    "monotonic",
    "run",
    "wait_until",
    "wall_stamp",
    "wall_time",
]


class VirtualTimeDeadlockError(RuntimeError):
    """Every task waits for something that no timer or descriptor will deliver."""


class VirtualTimeRealIOError(UsageError):
    """A run on virtual time waited on real I/O without saying it may (see the module doc)."""

    def __init__(self, what: str, task: asyncio.Task[Any] | None = None) -> None:
        self.what = what
        self.task = task
        """The task that did it, when the loop saw it happen in one (not in a callback)."""
        super().__init__(
            f"virtual time refuses real I/O: {what}. Virtual time jumps whenever the loop "
            "waits, so it would run away while real I/O is pending. Run on real time, use an "
            "in-process emulator, or allow it explicitly: real_io_on_virtual_time = true under "
            "[runtime] in the wiring file (real_io=True for run() and run_actors())"
        )


RealIOHandler = Callable[[VirtualTimeRealIOError], None]
"""Told (on the loop's thread) when a virtual loop refuses real I/O; the runtime stops."""


class _JumpingSelector:
    """Wraps the loop's selector: poll without waiting, then jump to the next timer."""

    def __init__(self, loop: VirtualEventLoop, inner: selectors.BaseSelector) -> None:
        self._loop = loop
        self._inner = inner

    def select(self, timeout: float | None = None) -> list[tuple[selectors.SelectorKey, int]]:
        loop = self._loop
        refused = loop._refused_unhandled
        if refused is not None:  # no runtime to stop in order: end the run here
            loop._refused_unhandled = None
            raise refused
        if timeout is not None:
            events = self._inner.select(0)
            if events or timeout <= 0:
                return events
            # asyncio drops cancelled handles from the head of the heap before it
            # asks for the timeout, so the head is the timer that set it. Jumping
            # to its own time (not now + timeout) keeps deadlines exact.
            scheduled: list[asyncio.TimerHandle] = getattr(loop, "_scheduled", [])
            target = scheduled[0].when() if scheduled else loop.time() + timeout
            if target != math.inf:
                loop._advance(target)
                return events
        # No timer (or only one at infinity): only I/O, a signal or another
        # thread can wake us.
        events = self._inner.select(loop.deadlock_after_s)
        if not events and loop.deadlock_after_s is not None:
            raise VirtualTimeDeadlockError(
                "virtual time: no timer is set and nothing arrived for "
                f"{loop.deadlock_after_s} s of wall time; every task is waiting"
            )
        return events

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)


def _describe_fd(fd: Any) -> str:
    number = fd if isinstance(fd, int) else fd.fileno()
    try:
        target = os.readlink(f"/proc/self/fd/{number}")
    except OSError:  # not Linux, or already closed
        return f"file descriptor {number}"
    return f"file descriptor {number} ({target})"


def _name_of(fn: object) -> str:
    return str(getattr(fn, "__qualname__", None) or repr(fn))


class VirtualEventLoop(asyncio.SelectorEventLoop):
    """An asyncio loop on virtual time: idle time is skipped, not waited.

    ``deadlock_after_s`` bounds how long (in wall seconds) the loop may wait
    for I/O when no timer is set; ``None`` (the default) waits indefinitely,
    as a real loop would. Test harnesses set it so that a deadlocked scenario
    fails instead of hanging. ``real_io`` allows real I/O (see the module
    docstring); without it the first real I/O is refused.
    """

    def __init__(self, *, deadlock_after_s: float | None = None, real_io: bool = False) -> None:
        self._now = 0.0
        self.deadlock_after_s = deadlock_after_s
        self.real_io = real_io
        """Whether real I/O is allowed on this loop (the runtime may set it from the graph)."""
        self.real_io_handler: RealIOHandler | None = None
        """Who is told of refused real I/O; ``None``: the loop raises it itself."""
        self._refused = False
        self._refused_unhandled: VirtualTimeRealIOError | None = None
        self._watching = False  # the loop's own wake-up pipe is not real I/O
        super().__init__()
        inner = cast(selectors.BaseSelector, self._selector)  # type: ignore[has-type]
        self._selector = cast(Any, _JumpingSelector(self, inner))
        self._advance(0.0)
        self._watching = True

    @property
    def virtual_now(self) -> float:
        """Virtual seconds since the loop was made (what :meth:`time` returns)."""
        return self._now

    def time(self) -> float:
        """Virtual seconds since the loop was made."""
        return self._now

    def _advance(self, target: float) -> None:
        if target > self._now:
            self._now = target
        # asyncio runs the timers with ``when < time() + resolution``; one ulp
        # makes that exactly ``when <= now``, at 0.1 s as at 1.8e9 s.
        self._clock_resolution = math.ulp(self._now)

    # ----------------------------------------------------------------- real I/O

    def _on_loop_thread(self) -> bool:
        # asyncio's private ``_thread_id`` is the loop's thread while it runs.
        thread: int | None = getattr(self, "_thread_id", None)
        return thread is not None and thread == threading.get_ident()

    def _running_elsewhere(self) -> bool:
        thread: int | None = getattr(self, "_thread_id", None)
        return thread is not None and thread != threading.get_ident()

    def notice_real_io(self, what: str) -> None:
        """Report real I/O (``what`` names it); refused once, unless :attr:`real_io` allows it.

        Safe from any thread. The refusal goes to :attr:`real_io_handler` on
        the loop's thread, or, with no handler, is raised by the loop.
        """
        if self.real_io or self._refused:
            return
        self._refused = True
        here = self._on_loop_thread()
        error = VirtualTimeRealIOError(what, asyncio.current_task(self) if here else None)
        handler = self.real_io_handler
        if handler is None:
            self._refused_unhandled = error
            if self._running_elsewhere():
                cast(Any, self)._write_to_self()  # wake a loop waiting on I/O: it raises now
        elif here:
            self.call_soon(handler, error)
        else:
            super().call_soon_threadsafe(handler, error)

    def _add_reader(self, fd: Any, callback: Callable[..., object], *args: Any) -> Any:
        if self._watching:
            self.notice_real_io(f"{_describe_fd(fd)} watched for reading")
        return cast(Any, super())._add_reader(fd, callback, *args)

    def _add_writer(self, fd: Any, callback: Callable[..., object], *args: Any) -> Any:
        if self._watching:
            self.notice_real_io(f"{_describe_fd(fd)} watched for writing")
        return cast(Any, super())._add_writer(fd, callback, *args)

    def run_in_executor(
        self, executor: Executor | None, func: Callable[[*Ts], T], *args: *Ts
    ) -> asyncio.Future[T]:
        """As asyncio's; on virtual time, work for a thread is real I/O."""
        self.notice_real_io(f"{_name_of(func)} handed to a worker thread (run_in_executor)")
        return super().run_in_executor(executor, func, *args)

    def call_soon_threadsafe(
        self,
        callback: Callable[[*Ts], object],
        *args: *Ts,
        context: contextvars.Context | None = None,
    ) -> asyncio.Handle:
        """As asyncio's; a call from another thread means a thread's work was waited on."""
        if self._running_elsewhere():
            thread = threading.current_thread().name
            self.notice_real_io(
                f"thread {thread!r} called back into the loop ({_name_of(callback)})"
            )
        return super().call_soon_threadsafe(callback, *args, context=context)


def _wake(future: asyncio.Future[None]) -> None:
    if not future.done():
        future.set_result(None)


class Clock:
    """The runtime's time: seconds since the clock was made, on the running loop.

    Build it inside the running loop (the runtime does). ``virtual`` says
    whether the loop is a :class:`VirtualEventLoop`.
    """

    __slots__ = ("_loop", "_t0", "virtual")

    def __init__(self) -> None:
        self._loop = asyncio.get_running_loop()
        self.virtual = isinstance(self._loop, VirtualEventLoop)
        self._t0 = self._loop.time()

    def now(self) -> float:
        """Seconds since this clock was made."""
        return self._loop.time() - self._t0

    def loop_time(self, t: float) -> float:
        """Clock time ``t`` as the event loop's (and anyio's) time, for cancel-scope deadlines."""
        return t + self._t0

    async def sleep_until(self, t: float) -> None:
        """Sleep until clock time ``t`` (at once if it has passed); cancellable."""
        if t != t:  # NaN would break the timer heap's order
            raise UsageError(f"sleep_until(t = {t!r}): expected a time in seconds, not NaN")
        loop = self._loop
        future: asyncio.Future[None] = loop.create_future()
        handle = loop.call_at(t + self._t0, _wake, future)
        try:
            await future
        finally:
            handle.cancel()

    async def sleep(self, dt: float) -> None:
        """Sleep ``dt`` seconds of this clock's time."""
        await self.sleep_until(self.now() + max(0.0, dt))

    def deadline(self, dt: float) -> float:
        """The loop time ``dt`` seconds from now (``inf`` stays ``inf``)."""
        return math.inf if math.isinf(dt) else self._loop.time() + dt

    # ----------------------------------------------------------------- real I/O

    @property
    def real_io(self) -> bool:
        """Whether real I/O is allowed: always on real time; on virtual time, if allowed."""
        loop = self._loop
        return not isinstance(loop, VirtualEventLoop) or loop.real_io

    def allow_real_io(self) -> None:
        """Allow real I/O on this (virtual) loop: the graph said so explicitly."""
        if isinstance(self._loop, VirtualEventLoop):
            self._loop.real_io = True

    def on_real_io(self, handler: RealIOHandler | None) -> None:
        """Who is told when the virtual loop refuses real I/O (the runtime); ``None``: the loop."""
        if isinstance(self._loop, VirtualEventLoop):
            self._loop.real_io_handler = handler

    def uses_real_io(self, what: str) -> None:
        """Say that the caller is about to wait on real I/O (``what``: a device, a port).

        On virtual time that has not allowed it, raises
        :class:`VirtualTimeRealIOError` naming ``what``: an actor opening a real
        device calls this first, so the refusal names the device and comes
        before anything is opened. On real time it does nothing.
        """
        loop = self._loop
        if isinstance(loop, VirtualEventLoop) and not loop.real_io:
            raise VirtualTimeRealIOError(what)


def run(
    fn: Callable[[*Ts], Awaitable[T]],
    *args: *Ts,
    virtual: bool = False,
    deadlock_after_s: float | None = None,
    real_io: bool = False,
) -> T:
    """Run ``fn(*args)`` under anyio on asyncio, on virtual or real time.

    ``real_io`` allows real I/O on virtual time (refused otherwise, see the
    module docstring); it changes nothing on real time.
    """
    options: dict[str, Any] = {}
    if virtual:
        options["loop_factory"] = lambda: VirtualEventLoop(
            deadlock_after_s=deadlock_after_s, real_io=real_io
        )
    return anyio.run(fn, *args, backend="asyncio", backend_options=options)


# --------------------------------------------------------------------------- threads


def monotonic() -> float:
    """Wall-clock seconds (arbitrary origin) for code outside any event loop.

    Only real-time device emulators, port-owning threads and what reports how a
    run kept up with real time (a simulation's real-time factor, a viewer's
    pace) use this: a device emulated in real time must take the time the
    device takes.
    """
    return time.perf_counter()


def wall_stamp() -> str:
    """The local date and time as ``YYYYmmdd-HHMMSS``: a default name for a recording."""
    return time.strftime("%Y%m%d-%H%M%S")


def wall_time() -> float:
    """Seconds since the epoch, the time files are stamped with: how old a recording is."""
    return time.time()


_SPIN_S = 0.0003
"""Below this, :func:`wait_until` spins: ``time.sleep`` overshoots by ~0.1 ms on Linux."""


def wait_until(deadline: float) -> None:
    """Block the calling thread until :func:`monotonic` reaches ``deadline``.

    Sleeps most of the way and spins the rest, so a 10 µs wire time is
    honoured to a few microseconds (a real-time emulator's byte timing).
    """
    while True:
        left = deadline - time.perf_counter()
        if left <= 0:
            return
        if left > _SPIN_S:
            time.sleep(left - _SPIN_S)


class WallAlarm:
    """Calls ``fire()`` in its own thread once a wall-clock deadline has passed.

    The last resort of a process that must end on time even when its event
    loop is blocked (a cleanup stuck in a blocking call): the runtime arms it
    when a stop begins, and ``fire`` ends the process. :meth:`arm` is safe
    from any thread and from a signal handler — it writes one fixed-size
    record to a pipe and takes no lock — so a signal arriving while the main
    thread holds some lock cannot deadlock it. The earliest deadline armed
    wins; :meth:`close` stops the thread without firing.
    """

    _RECORD = struct.Struct("=cd")  # command, delay in seconds; atomic on a pipe

    def __init__(self, fire: Callable[[], None], *, name: str = "wall-alarm") -> None:
        self._fire = fire
        self._read, self._write = os.pipe()
        self._closed = False
        self._thread = threading.Thread(target=self._serve, name=name, daemon=True)
        self._thread.start()

    def arm(self, delay_s: float) -> None:
        """Fire ``delay_s`` wall seconds from now, unless an earlier deadline is armed."""
        self._send(b"A", delay_s)

    def close(self) -> None:
        """Disarm for good and end the thread (idempotent)."""
        if self._closed:
            return
        self._send(b"C", 0.0)
        self._closed = True  # after the record: arm() never writes to a reused descriptor
        self._thread.join(timeout=1.0)
        os.close(self._write)

    def _send(self, command: bytes, value: float) -> None:
        if self._closed:
            return
        with contextlib.suppress(OSError):  # a full pipe: not with a handful of records
            os.write(self._write, self._RECORD.pack(command, value))

    def _serve(self) -> None:
        deadline: float | None = None
        size = self._RECORD.size
        try:
            while True:
                timeout = None if deadline is None else max(0.0, deadline - monotonic())
                readable, _, _ = select.select([self._read], [], [], timeout)
                if not readable:
                    self._fire()
                    return
                command, value = self._RECORD.unpack(os.read(self._read, size))
                if command == b"C":
                    return
                due = monotonic() + value
                deadline = due if deadline is None else min(deadline, due)
        finally:
            os.close(self._read)
