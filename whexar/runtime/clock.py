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
* Deadlines are exact. :meth:`Clock.sleep_until` schedules the timer at
  the deadline itself, and the loop jumps to the timer's own time, so a
  100 Hz ticker wakes at exactly ``t0 + k·0.01`` after any number of cycles.

Rules that keep virtual time deterministic
------------------------------------------
* Real I/O still works on the virtual loop (a pty, a socket): the loop polls
  descriptors without waiting before every jump, and a bytes-ready
  descriptor wins over the jump. Such I/O is not deterministic in time.
* Work handed to a thread is invisible to the loop: time may jump while the
  thread runs. On virtual time, devices are emulated in-loop (the servo
  emulator advances the clock by each transaction's wire time instead).
* Nothing may wait on the wall clock; only this module reads it.
"""

from __future__ import annotations

import asyncio
import math
import selectors
import time
from collections.abc import Awaitable, Callable
from typing import Any, TypeVar, TypeVarTuple, cast

import anyio

T = TypeVar("T")
Ts = TypeVarTuple("Ts")

__all__ = [
    "Clock",
    "VirtualEventLoop",
    "VirtualTimeDeadlockError",
    "monotonic",
    "run",
    "wait_until",
]


class VirtualTimeDeadlockError(RuntimeError):
    """Every task waits for something that no timer or descriptor will deliver."""


class _JumpingSelector:
    """Wraps the loop's selector: poll without waiting, then jump to the next timer."""

    def __init__(self, loop: VirtualEventLoop, inner: selectors.BaseSelector) -> None:
        self._loop = loop
        self._inner = inner

    def select(self, timeout: float | None = None) -> list[tuple[selectors.SelectorKey, int]]:
        loop = self._loop
        if timeout is None:
            # No timer at all: only I/O, a signal or another thread can wake us.
            events = self._inner.select(loop.deadlock_after_s)
            if not events and loop.deadlock_after_s is not None:
                raise VirtualTimeDeadlockError(
                    "virtual time: no timer is set and nothing arrived for "
                    f"{loop.deadlock_after_s} s of wall time; every task is waiting"
                )
            return events
        events = self._inner.select(0)
        if events or timeout <= 0:
            return events
        # asyncio drops cancelled handles from the head of the heap before it
        # asks for the timeout, so the head is the timer that set it. Jumping
        # to its own time (not now + timeout) keeps deadlines exact.
        scheduled: list[asyncio.TimerHandle] = getattr(loop, "_scheduled", [])
        target = scheduled[0].when() if scheduled else loop.virtual_now + timeout
        loop.virtual_now = max(loop.virtual_now, target)
        return events

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)


class VirtualEventLoop(asyncio.SelectorEventLoop):
    """An asyncio loop on virtual time: idle time is skipped, not waited.

    ``deadlock_after_s`` bounds how long (in wall seconds) the loop may wait
    for I/O when no timer is set; ``None`` (the default) waits indefinitely,
    as a real loop would. Test harnesses set it so that a deadlocked scenario
    fails instead of hanging.
    """

    def __init__(self, *, deadlock_after_s: float | None = None) -> None:
        self.virtual_now = 0.0
        self.deadlock_after_s = deadlock_after_s
        super().__init__()
        inner = cast(selectors.BaseSelector, self._selector)  # type: ignore[has-type]
        self._selector = cast(Any, _JumpingSelector(self, inner))

    def time(self) -> float:
        """Virtual seconds since the loop was made."""
        return self.virtual_now


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


def run(
    fn: Callable[[*Ts], Awaitable[T]],
    *args: *Ts,
    virtual: bool = False,
    deadlock_after_s: float | None = None,
) -> T:
    """Run ``fn(*args)`` under anyio on asyncio, on virtual or real time."""
    options: dict[str, Any] = {}
    if virtual:
        options["loop_factory"] = lambda: VirtualEventLoop(deadlock_after_s=deadlock_after_s)
    return anyio.run(fn, *args, backend="asyncio", backend_options=options)


# --------------------------------------------------------------------------- threads


def monotonic() -> float:
    """Wall-clock seconds (arbitrary origin) for code outside any event loop.

    Only real-time device emulators and port-owning threads use this: a
    device emulated in real time must take the time the device takes.
    """
    return time.perf_counter()


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
