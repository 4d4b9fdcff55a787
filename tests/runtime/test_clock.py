"""The clock and the virtual-time event loop: exact jumps, cancellation, deadlock detection."""

from __future__ import annotations

import asyncio
import math

import anyio
import pytest

from whexar.runtime.clock import Clock, VirtualEventLoop, VirtualTimeDeadlockError, run


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
