"""A deadline-based ticker for control cycles.

Theory of operation
-------------------
Cycle ``k`` is due at ``t0 + k·period``: deadlines are computed from the
start, never by adding the period to the last wake-up, so the ticker cannot
drift however long it runs. A cycle that ends after the next deadline has
*overrun*: the ticker emits a :class:`~whexar.runtime.messages.TickOverrun`
event and resumes at the next deadline still ahead, skipping the missed
ones (a late control cycle is useless; a burst of catch-up cycles is
harmful). A cycle that ends exactly on the next deadline is on time.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

from whexar.runtime.checks import positive
from whexar.runtime.clock import Clock
from whexar.runtime.messages import Event, TickOverrun


class Tick(NamedTuple):
    """One control cycle: its index on the ticker's grid and its due time (clock seconds)."""

    cycle: int
    t: float


class Ticker:
    """``async for tick in Ticker(...)`` runs one body per period, on a fixed grid.

    Made by :meth:`whexar.runtime.actor.Actor.ticker`, which fills in the
    actor's clock and event stream. The first tick is due at ``start``
    (default: now).
    """

    def __init__(
        self,
        clock: Clock,
        period_s: float,
        *,
        actor: str,
        emit: Callable[[Event], None],
        start: float | None = None,
    ) -> None:
        self.period_s = positive("period_s", period_s, "s")
        self._clock = clock
        self._actor = actor
        self._emit = emit
        self._t0 = clock.now() if start is None else start
        self._cycle = -1
        self.overruns = 0

    def due(self, cycle: int) -> float:
        """The clock time cycle ``cycle`` is due."""
        return self._t0 + cycle * self.period_s

    def __aiter__(self) -> Ticker:
        return self

    async def __anext__(self) -> Tick:
        clock = self._clock
        nxt = self._cycle + 1
        if self._cycle >= 0:
            now = clock.now()
            if now > self.due(nxt):
                # First grid index not yet in the past; float error may put
                # the quotient a hair below an integer, hence the check.
                first = max(nxt + 1, math.ceil((now - self._t0) / self.period_s))
                while self.due(first) < now:
                    first += 1
                self.overruns += 1
                self._emit(
                    TickOverrun(
                        t=now,
                        source=self._actor,
                        actor=self._actor,
                        cycle=self._cycle,
                        period_s=self.period_s,
                        elapsed_s=now - self.due(self._cycle),
                        skipped=first - nxt,
                    )
                )
                nxt = first
        due = self.due(nxt)
        await clock.sleep_until(due)
        self._cycle = nxt
        return Tick(nxt, due)
