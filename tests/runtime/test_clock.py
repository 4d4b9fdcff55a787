"""The clock and the virtual-time event loop: exact jumps at any magnitude, cancellation,
deadlock detection, real I/O refused; the wall alarm."""

from __future__ import annotations

import asyncio
import math
import os
import signal
import threading

import anyio
import anyio.to_thread
import pytest

from whexar.errors import UsageError
from whexar.runtime.clock import (
    Clock,
    VirtualEventLoop,
    VirtualTimeDeadlockError,
    VirtualTimeRealIOError,
    WallAlarm,
    run,
)
from whexar.runtime.messages import Event
from whexar.runtime.ticker import Ticker


def test_virtual_time_jumps_exactly_to_each_deadline() -> None:
    async def main() -> tuple[list[float], float]:
        clock = Clock()
        assert clock.virtual
        assert clock.now() == 0.0
        seen: list[float] = []
        for deadline in (0.1, 0.3, 123.456, 1e6 + 0.001):
            await clock.sleep_until(deadline)
            seen.append(clock.now())
        return seen, asyncio.get_running_loop().time()

    seen, loop_time = run(main, virtual=True)
    assert seen == [0.1, 0.3, 123.456, 1e6 + 0.001]
    assert loop_time == 1e6 + 0.001


def test_concurrent_sleepers_wake_in_deadline_order_at_their_own_times() -> None:
    async def main() -> list[tuple[str, float]]:
        clock = Clock()
        woke: list[tuple[str, float]] = []

        async def sleeper(name: str, t: float) -> None:
            await clock.sleep_until(t)
            woke.append((name, clock.now()))

        async with anyio.create_task_group() as tg:
            tg.start_soon(sleeper, "late", 2.5)
            tg.start_soon(sleeper, "early", 0.7)
            tg.start_soon(sleeper, "middle", 1.9)
        return woke

    assert run(main, virtual=True) == [("early", 0.7), ("middle", 1.9), ("late", 2.5)]


def test_sleep_until_a_past_time_returns_without_moving_time() -> None:
    async def main() -> list[float]:
        clock = Clock()
        await clock.sleep_until(5.0)
        await clock.sleep_until(1.0)  # already past
        after_past = clock.now()
        await clock.sleep(-3.0)  # negative durations do not wait either
        after_negative = clock.now()
        await clock.sleep(0.25)
        return [after_past, after_negative, clock.now()]

    assert run(main, virtual=True) == [5.0, 5.0, 5.25]


def test_clock_deadlines_are_loop_times() -> None:
    async def main() -> None:
        loop = asyncio.get_running_loop()
        await Clock().sleep_until(2.0)  # a first clock moves the loop to 2 s
        clock = Clock()  # made at loop time 2: its zero is there
        assert clock.now() == 0.0
        assert clock.loop_time(0.5) == 2.5
        assert clock.deadline(1.5) == loop.time() + 1.5 == 3.5
        assert clock.deadline(math.inf) == math.inf
        await clock.sleep_until(0.5)
        assert loop.time() == 2.5
        assert clock.now() == 0.5

    run(main, virtual=True)


def test_anyio_move_on_after_cancels_a_clock_sleep_on_virtual_time() -> None:
    async def main() -> tuple[bool, float, float]:
        clock = Clock()
        with anyio.move_on_after(1.5) as scope:
            await clock.sleep(10.0)
        cut_at = clock.now()
        # The cancelled 10 s timer is gone: the next sleep is not stretched to it.
        await clock.sleep(0.5)
        return scope.cancelled_caught, cut_at, clock.now()

    assert run(main, virtual=True) == (True, 1.5, 2.0)


def test_a_cancel_scope_deadline_from_the_clock_cuts_a_sleep_at_that_time() -> None:
    async def main() -> float:
        clock = Clock()
        with anyio.CancelScope(deadline=clock.deadline(0.75)):
            await clock.sleep_until(3.0)
        return clock.now()

    assert run(main, virtual=True) == 0.75


def test_a_loop_with_nothing_to_wake_it_raises_virtual_time_deadlock() -> None:
    async def main() -> None:
        await anyio.Event().wait()  # nobody will ever set it, and no timer is pending

    with pytest.raises(VirtualTimeDeadlockError, match="every task is waiting"):
        run(main, virtual=True, deadlock_after_s=0.01)


def test_virtual_event_loop_reports_its_settings() -> None:
    loop = VirtualEventLoop(deadlock_after_s=0.5)
    try:
        assert loop.deadlock_after_s == 0.5
        assert loop.time() == 0.0
    finally:
        loop.close()


def test_run_passes_arguments_and_returns_the_result() -> None:
    async def add(a: int, b: int) -> int:
        await Clock().sleep(1.0)
        return a + b

    assert run(add, 2, 3, virtual=True) == 5


async def test_real_time_clock_on_a_stock_loop() -> None:
    clock = Clock()
    assert not clock.virtual
    await clock.sleep(0.01)
    # asyncio may wake a timer up to its clock resolution early; never much earlier.
    assert clock.now() >= 0.01 - 1e-3


# --------------------------------------------------------------------------- any magnitude

EPOCH = 1.8e9
"""Seconds since 1970 in 2027: where replayed logs put their timestamps."""


@pytest.mark.usefixtures("hang_guard")
def test_a_virtual_sleep_at_epoch_seconds_wakes_exactly_on_its_deadline() -> None:
    # With asyncio's fixed 1 ns resolution the loop spun in place past ~1.7e7 s
    # (now + 1e-9 == now there, so the timer at now was never due).
    async def main() -> list[float]:
        clock = Clock()
        woke = []
        for deadline in (EPOCH, EPOCH + 0.01, EPOCH + 0.25, 3.2e10):
            await clock.sleep_until(deadline)
            woke.append(clock.now())
        return woke

    assert run(main, virtual=True, deadlock_after_s=1.0) == [
        EPOCH,
        EPOCH + 0.01,
        EPOCH + 0.25,
        3.2e10,
    ]


@pytest.mark.usefixtures("hang_guard")
def test_a_100_hz_ticker_at_epoch_seconds_wakes_on_its_grid() -> None:
    async def main() -> tuple[list[tuple[float, float]], list[Event]]:
        clock = Clock()
        events: list[Event] = []
        ticker = Ticker(clock, 0.01, actor="replay", emit=events.append, start=EPOCH)
        woke: list[tuple[float, float]] = []
        async for tick in ticker:
            woke.append((tick.t, clock.now()))
            if len(woke) == 3000:
                break
        return woke, events

    woke, events = run(main, virtual=True, deadlock_after_s=1.0)
    assert [t for t, _ in woke] == [EPOCH + k * 0.01 for k in range(3000)]
    assert all(now == t for t, now in woke)
    assert events == []  # no overrun: a float ulp (0.24 µs here) is not lateness


@pytest.mark.usefixtures("hang_guard")
def test_anyio_timeouts_and_sleeps_work_at_epoch_seconds() -> None:
    async def main() -> tuple[float, bool, float]:
        clock = Clock()
        await clock.sleep_until(EPOCH)
        await anyio.sleep(0.5)
        slept = clock.now()
        with anyio.move_on_after(0.25) as scope:
            await clock.sleep(10.0)
        return slept, scope.cancelled_caught, clock.now()

    assert run(main, virtual=True, deadlock_after_s=1.0) == (EPOCH + 0.5, True, EPOCH + 0.75)


def test_a_timer_is_due_at_its_own_time_not_within_a_resolution_of_it() -> None:
    # The next float after 1.0 is 2.2e-16 later: it must wake there, not at 1.0
    # with the timer before it (asyncio's 1 ns resolution ran both at 1.0).
    later = math.nextafter(1.0, 2.0)

    async def main() -> list[tuple[str, float]]:
        clock = Clock()
        woke: list[tuple[str, float]] = []

        async def sleeper(name: str, t: float) -> None:
            await clock.sleep_until(t)
            woke.append((name, clock.now()))

        async with anyio.create_task_group() as tg:
            tg.start_soon(sleeper, "later", later)
            tg.start_soon(sleeper, "first", 1.0)
        return woke

    assert run(main, virtual=True, deadlock_after_s=1.0) == [("first", 1.0), ("later", later)]


@pytest.mark.usefixtures("hang_guard")
def test_a_timer_at_infinity_is_a_deadlock_not_a_jump() -> None:
    async def main() -> None:
        await Clock().sleep_until(math.inf)

    with pytest.raises(VirtualTimeDeadlockError, match="every task is waiting"):
        run(main, virtual=True, deadlock_after_s=0.01)


def test_sleep_until_nan_is_refused() -> None:
    async def main() -> None:
        await Clock().sleep_until(math.nan)

    with pytest.raises(UsageError, match="not NaN"):
        run(main, virtual=True)


# --------------------------------------------------------------------------- real I/O


@pytest.mark.usefixtures("hang_guard")
def test_a_descriptor_watched_on_virtual_time_is_refused_naming_it() -> None:
    master, slave = os.openpty()

    async def main() -> None:
        await anyio.wait_readable(master)  # nothing will arrive: time would run away

    try:
        with pytest.raises(VirtualTimeRealIOError) as refused:
            run(main, virtual=True, deadlock_after_s=1.0)
    finally:
        os.close(master)
        os.close(slave)
    message = str(refused.value)
    assert f"file descriptor {master} (/dev/ptmx) watched for reading" in message
    assert "real_io_on_virtual_time = true" in message


@pytest.mark.usefixtures("hang_guard")
def test_work_in_a_thread_on_virtual_time_is_refused() -> None:
    async def main() -> float:
        clock = Clock()
        await anyio.to_thread.run_sync(os.getpid)
        return clock.now()

    with pytest.raises(VirtualTimeRealIOError, match="thread 'AnyIO worker thread'"):
        run(main, virtual=True, deadlock_after_s=1.0)


def test_run_in_executor_on_virtual_time_is_refused_before_the_thread_runs() -> None:
    async def main() -> None:
        await asyncio.get_running_loop().run_in_executor(None, os.getpid)

    with pytest.raises(VirtualTimeRealIOError, match=r"getpid handed to a worker thread"):
        run(main, virtual=True, deadlock_after_s=1.0)


def test_real_io_allowed_explicitly_runs_on_virtual_time() -> None:
    read, write = os.pipe()

    async def main() -> tuple[int, bytes]:
        pid = await anyio.to_thread.run_sync(os.getpid)
        os.write(write, b"x")
        await anyio.wait_readable(read)
        return pid, os.read(read, 1)

    try:
        assert run(main, virtual=True, real_io=True, deadlock_after_s=1.0) == (os.getpid(), b"x")
    finally:
        os.close(read)
        os.close(write)


def test_uses_real_io_refuses_at_once_naming_the_device_and_allows_on_real_time() -> None:
    async def main() -> tuple[bool, bool]:
        clock = Clock()
        before = clock.real_io
        with pytest.raises(VirtualTimeRealIOError, match="servo port /dev/ttyUSB0"):
            clock.uses_real_io("servo port /dev/ttyUSB0")
        clock.allow_real_io()
        clock.uses_real_io("servo port /dev/ttyUSB0")  # now it may
        return before, clock.real_io

    assert run(main, virtual=True) == (False, True)

    async def real() -> bool:
        clock = Clock()
        clock.uses_real_io("servo port /dev/ttyUSB0")
        return clock.real_io

    assert run(real) is True


def test_the_loops_own_wakeup_pipe_and_signals_are_not_real_io() -> None:
    async def main() -> float:
        clock = Clock()
        with anyio.open_signal_receiver(signal.SIGUSR1):  # the loop's wake-up fd only
            await clock.sleep(1.0)
        return clock.now()

    assert run(main, virtual=True, deadlock_after_s=1.0) == 1.0


# --------------------------------------------------------------------------- wall alarm
# Real time is the point here: the alarm is a thread on the wall clock.


def test_a_wall_alarm_fires_once_its_earliest_deadline_passes() -> None:
    fired = threading.Event()
    alarm = WallAlarm(fired.set)
    try:
        alarm.arm(30.0)
        alarm.arm(0.05)  # the earliest wins
        alarm.arm(20.0)
        assert fired.wait(timeout=5.0)
    finally:
        alarm.close()


def test_a_closed_wall_alarm_never_fires() -> None:
    fired = threading.Event()
    alarm = WallAlarm(fired.set)
    alarm.arm(0.05)
    alarm.close()
    alarm.arm(0.0)  # after close: ignored, never written to a reused descriptor
    assert not fired.wait(timeout=0.2)
    alarm.close()  # idempotent
