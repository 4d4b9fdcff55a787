"""How long a transaction keeps the servo bus busy: wire time plus measured host costs.

The model is fitted to the thesis's own measurements of its bus (Žák 2023,
Tables 6.1 and 6.2); :class:`~whexar.bus.emulator.chain.ServoChain` prices
every exchange with it, and the benchmarks compare read plans against it.
Nothing here reads a clock: it turns byte counts into seconds.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

from whexar.bus.protocol import sync_read_bytes, sync_write_bytes
from whexar.errors import UsageError


@dataclass(frozen=True, slots=True)
class TimingModel:
    """How long transactions keep the bus busy (wire time plus measured host costs).

    Wire time is ``bits_per_byte / baudrate`` per byte (8N1: 10 bits). A read
    also pays each status packet's Return Delay Time, one host/USB turnaround
    and a host cost per status byte received. The two host constants are a
    least-squares fit (in seconds per transaction) to the thesis's sync reads of
    42 servos at 1 Mbps with Return Delay Time 20 µs (Tables 6.1, 6.2)::

        X  status bytes 42·(11+X)  1/rate    wire(56+status)+42·20 µs   residual
        1  504                     8.4617 ms  6.4400 ms                  2.0217 ms
        2  546                     8.9928 ms  6.8600 ms                  2.1328 ms
        4  630                     9.9800 ms  7.7000 ms                  2.2800 ms

        residual = turnaround + per_status_byte · status bytes
        → turnaround = 1.0203 ms, per_status_byte = 2.008 µs

    Writes are pure wire time. ``tests/bus/test_emulator.py`` checks the rates
    of reads and writes against the thesis's (docs/sim.md, "Bus time", sets
    them side by side). The host constants come from 1 Mbps and are assumed not
    to scale with the baud rate.
    """

    baudrate: int = 1_000_000
    bits_per_byte: int = 10
    turnaround_s: float = 1.0203e-3
    per_status_byte_s: float = 2.008e-6

    def __post_init__(self) -> None:
        if self.baudrate <= 0 or self.bits_per_byte <= 0:
            raise UsageError(f"{self!r}: baudrate and bits_per_byte must be > 0")

    def wire_s(self, nbytes: int) -> float:
        """Time on the wire of ``nbytes`` bytes."""
        return nbytes * self.bits_per_byte / self.baudrate

    def read_s(
        self, request_bytes: int, status_packets: int, status_bytes: int, return_delay_s: float
    ) -> float:
        """A read transaction: wire(request + status) + return delay per status packet
        + turnaround + per-status-byte host cost. ``return_delay_s`` is per packet."""
        return (
            self.wire_s(request_bytes + status_bytes)
            + status_packets * return_delay_s
            + self.turnaround_s
            + self.per_status_byte_s * status_bytes
        )

    def write_s(self, request_bytes: int) -> float:
        """A transaction without reply: pure wire time."""
        return self.wire_s(request_bytes)

    def sync_read_s(
        self, n: int, data_bytes: int, return_delay_s: float, fast: bool = False
    ) -> float:
        """Analytic (Fast) Sync Read of ``data_bytes`` from each of ``n`` servos.

        Fast: one status packet of 8 + n·(X + 4) bytes and *one* Return Delay
        Time — the first servo waits it, every later one appends its part as
        soon as the previous part ends (that is the instruction's point: "one
        Status Packet ... as if one DYNAMIXEL has returned a single Status
        Packet", e-manual). The per-byte host cost is kept per byte received.
        """
        request, response = sync_read_bytes(n, data_bytes, fast=fast)
        return self.read_s(request, 1 if fast else n, response, return_delay_s)

    def sync_write_s(self, n: int, data_bytes: int) -> float:
        """Analytic Sync Write of ``data_bytes`` to each of ``n`` servos: 14 + n·(1 + X) bytes."""
        return self.write_s(sync_write_bytes(n, data_bytes))


DEFAULT_TIMING: Final = TimingModel()
"""The thesis's bus: 1 Mbps, host constants fitted to Tables 6.1 and 6.2."""
