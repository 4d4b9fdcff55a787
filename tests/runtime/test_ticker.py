"""The deadline ticker: a fixed grid with no drift, overruns reported and skipped."""

from __future__ import annotations

from typing import Any

import pytest

from whexar.errors import UsageError
from whexar.runtime.clock import Clock, run
from whexar.runtime.messages import Event, Heartbeat, TickOverrun
from whexar.runtime.ticker import Tick, Ticker
from whexar.testing import run_actors


def run_ticker(
    period_s: float,
    cycles: int,
    *,
    work: dict[int, float] | None = None,
    start: float | None = None,
    begin_at: float = 0.0,
) -> tuple[list[tuple[Tick, float]], list[Event], int]:
    """Tick ``cycles`` times on virtual time; ``work[cycle]`` seconds are spent in that cycle.

    Returns each tick with the clock time it woke at, the emitted events, and the
    ticker's overrun count.
    """
    work = work or {}

    async def main() -> tuple[list[tuple[Tick, float]], list[Event], int]:
        clock = Clock()
        await clock.sleep_until(begin_at)
        events: list[Event] = []
        ticker = Ticker(clock, period_s, actor="ctl", emit=events.append, start=start)
        ticks: list[tuple[Tick, float]] = []
        async for tick in ticker:
            ticks.append((tick, clock.now()))
            if len(ticks) == cycles:
                break
            await clock.sleep(work.get(tick.cycle, 0.0))
        return ticks, events, ticker.overruns

    return run(main, virtual=True, deadlock_after_s=1.0)


def test_no_drift_over_many_cycles() -> None:
    ticks, events, overruns = run_ticker(0.01, 5000, begin_at=0.25)
    assert [t.cycle for t, _ in ticks] == list(range(5000))
    # Every wake-up is exactly on t0 + k·period, the last one as much as the first.
    assert all(t.t == 0.25 + t.cycle * 0.01 for t, _ in ticks)
    assert all(now == t.t for t, now in ticks)
    assert ticks[-1][1] == 0.25 + 4999 * 0.01
    # Adding the period to the previous wake-up would have drifted off the grid.
    accumulated = 0.25
    for _ in range(4999):
        accumulated += 0.01
    assert accumulated != ticks[-1][1]
    assert events == []
    assert overruns == 0


def test_the_first_tick_is_due_at_start() -> None:
    ticks, _, _ = run_ticker(0.5, 3, start=2.0)
    assert [(t.cycle, t.t, now) for t, now in ticks] == [
        (0, 2.0, 2.0),
        (1, 2.5, 2.5),
        (2, 3.0, 3.0),
    ]


def test_an_overrun_is_reported_and_missed_deadlines_are_skipped() -> None:
    # Cycle 2 works 2.5 periods: it ends at 0.25 + 0.3125 = 0.5625, past the due
    # times of cycles 3 (0.375) and 4 (0.5); the next tick is cycle 5 at 0.625.
    ticks, events, overruns = run_ticker(0.125, 6, work={2: 0.3125})
    assert [(t.cycle, now) for t, now in ticks] == [
        (0, 0.0),
        (1, 0.125),
        (2, 0.25),
        (5, 0.625),
        (6, 0.75),
        (7, 0.875),
    ]
    assert events == [
        TickOverrun(
            t=0.5625,
            source="ctl",
            actor="ctl",
            cycle=2,
            period_s=0.125,
            elapsed_s=0.3125,
            skipped=2,
        )
    ]
    assert overruns == 1


def test_a_cycle_ending_exactly_on_the_next_deadline_is_on_time() -> None:
    ticks, events, overruns = run_ticker(0.125, 4, work={1: 0.125})
    assert [(t.cycle, now) for t, now in ticks] == [(0, 0.0), (1, 0.125), (2, 0.25), (3, 0.375)]
    assert events == []
    assert overruns == 0


def test_a_cycle_ending_exactly_on_a_later_deadline_resumes_there() -> None:
    # Two whole periods of work: cycle 2's deadline passed, cycle 3's is now.
    ticks, events, _ = run_ticker(0.125, 3, work={1: 0.25})
    assert [(t.cycle, now) for t, now in ticks] == [(0, 0.0), (1, 0.125), (3, 0.375)]
    assert [(e.cycle, e.elapsed_s, e.skipped) for e in events if isinstance(e, TickOverrun)] == [
        (1, 0.25, 1)
    ]


@pytest.mark.parametrize("period", [0.0, -0.1, float("nan")])
def test_the_period_must_be_positive(period: float) -> None:
    async def main() -> None:
        Ticker(Clock(), period, actor="ctl", emit=lambda e: None)

    with pytest.raises(UsageError, match="period_s"):
        run(main, virtual=True)


def test_pulse_slow_cycles_in_a_graph_report_overruns() -> None:
    graph: dict[str, Any] = {
        "actors": [
            {
                "name": "pulse",
                "class": "whexar.testing:Pulse",
                "params": {
                    "period_s": 0.125,
                    "slow_cycles": [2, 6],
                    "slow_s": 0.375,
                    "count": 10,
                },
                "outputs": {"out": "beats"},
            },
            {"name": "sink", "class": "whexar.testing:Sink", "inputs": {"inp": "beats"}},
        ],
        "channels": {"beats": {"message": "Heartbeat", "policy": "queue"}},
    }
    result = run_actors(graph, duration=2.0)
    overruns = [(o.actor, o.cycle, o.elapsed_s, o.skipped) for o in result.events(TickOverrun)]
    # 3 periods of work end exactly on a later deadline: two are skipped each time.
    assert overruns == [("pulse", 2, 0.375, 2), ("pulse", 6, 0.375, 2)]
    beats = result.messages("beats", of=Heartbeat)
    assert [b.t / 0.125 for b in beats] == [0, 1, 2, 5, 6, 9]
    assert all(o.t == o.elapsed_s + o.cycle * 0.125 for o in result.events(TickOverrun))


def test_pulse_slow_cycle_of_exactly_one_period_is_not_an_overrun() -> None:
    graph: dict[str, Any] = {
        "actors": [
            {
                "name": "pulse",
                "class": "whexar.testing:Pulse",
                "params": {"period_s": 0.125, "slow_cycles": [1, 2, 3], "slow_s": 0.125},
                "outputs": {"out": "beats"},
            },
            {"name": "sink", "class": "whexar.testing:Sink", "inputs": {"inp": "beats"}},
        ],
        "channels": {"beats": {"message": "Heartbeat", "policy": "queue"}},
    }
    result = run_actors(graph, duration=1.0625)
    assert result.events(TickOverrun) == []
    beats = result.messages("beats", of=Heartbeat)
    assert [b.t for b in beats] == [k * 0.125 for k in range(len(beats))]
    assert len(beats) == 9  # t = 0 … 1.0, every one on the grid
