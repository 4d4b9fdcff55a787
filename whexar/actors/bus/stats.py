"""The bus's statistics: what the cycles cost and what went wrong.

Each core counts what it decides (the goal policy its clamps and failed
writes, the health machine its failed reads); :class:`BusCounters` counts
the cycles and what the port did, and makes :class:`BusStats` over the
window since the last one. :class:`NominalCycle` keeps what a cycle costs
when nothing goes wrong, which bounds the waits out of the cycle. No I/O,
no clock: the shell measures, these keep the books.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Final

from whexar.actors.messages import BusStats

NOMINAL_SMOOTHING: Final = 0.1
"""Weight of the newest healthy cycle in the nominal cycle time (an exponential mean)."""
DEFAULT_NOMINAL_S: Final = 0.02
"""The nominal cycle time before the first healthy cycle was measured."""
MIN_CYCLE_S: Final = 0.005
"""Shortest cycle after a lost servo, while the robot sits down (a measured nominal cycle
of zero bus time, as a replay past its recording's answers has, would stop the clock)."""
MIN_PROBE_TIMEOUT_MS: Final = 1.0
"""Shortest wait for a probed servo's status: a servo answers in ~0.1 ms plus its Return
Delay Time at 1 Mbps, and a USB adapter adds its latency timer (1 ms when set right)."""


class NominalCycle:
    """The nominal cycle time: an exponential mean of the healthy cycles' durations."""

    def __init__(self) -> None:
        self.s = DEFAULT_NOMINAL_S
        self.measured = False

    def healthy(self, took: float) -> None:
        """A cycle with no failure, no retry and no recovery took ``took`` seconds."""
        w = NOMINAL_SMOOTHING if self.measured else 1.0
        self.s += w * (took - self.s)
        self.measured = True

    @property
    def probe_timeout_ms(self) -> float:
        """A probe's wait: within one nominal cycle, so a cycle takes at most two."""
        return max(MIN_PROBE_TIMEOUT_MS, 0.8 * self.s * 1000.0)

    @property
    def paced_s(self) -> float:
        """The shortest cycle while the robot sits down after a lost servo."""
        return max(self.s, MIN_CYCLE_S)


class BusCounters:
    """Cycles, retries and bytes so far; the window of the last :class:`BusStats`."""

    def __init__(self, source: str) -> None:
        self.source = source
        self.cycles = 0
        self.retries = 0
        self.bytes = 0
        self._since_t = 0.0
        self._since_cycles = 0
        self._since_bytes = 0

    def cycled(self, retries: int, nbytes: int) -> None:
        """One more cycle, with the port's ``retries`` and the bytes it moved."""
        self.cycles += 1
        self.retries += retries
        self.bytes += nbytes

    def start(self, now: float) -> None:
        """The first window starts at ``now``, with no cycles."""
        self._since_t, self._since_cycles, self._since_bytes = now, 0, 0

    def report(
        self,
        now: float,
        *,
        read_mode: str,
        timeouts: int,
        corrupt: int,
        clamped: int,
        write_failures: int,
        degraded: Iterable[int],
    ) -> BusStats | None:
        """The statistics of the window ending at ``now`` (``None`` for an empty window),
        and a new window from there."""
        window = now - self._since_t
        if window <= 0:
            return None
        cycles = self.cycles - self._since_cycles
        stats = BusStats(
            t=now,
            source=self.source,
            cycles=self.cycles,
            rate_hz=cycles / window,
            bytes_per_cycle=(self.bytes - self._since_bytes) / max(1, cycles),
            read_mode=read_mode,
            retries=self.retries,
            timeouts=timeouts,
            corrupt=corrupt,
            clamped=clamped,
            degraded=tuple(sorted(degraded)),
            write_failures=write_failures,
        )
        self._since_t, self._since_cycles, self._since_bytes = now, self.cycles, self.bytes
        return stats
