"""A recorded servo bus played back to dynamixel-sdk: the bytes of a run, at their times.

Theory of operation
-------------------
A recording holds every byte the SDK wrote to its port and read from it, each with
the bus time it happened at (:func:`whexar.bus.sdk.tap_port`): ``tx`` stamped once
written (on the emulator, the end of its transaction), ``rx`` per read, and
``timeout`` where the SDK's wait for a reply gave up. :class:`ReplayPort` is the
duck-typed ``PortHandler`` that plays them back, so the SDK parses the recorded
replies exactly as it parsed them live, and the bus scheduler above it runs
unchanged (port ``replay:NAME``, :data:`REPLAYED_BUS`).

The recording is cut into transactions: each packet written, and after each one
that expects an answer (anything but a Sync or Bulk Write, or a broadcast write)
every ``rx`` and ``timeout`` up to the next one that does. Packets that expect no
answer can go out while a reply is still being read (the scheduler's goal writes
ride on the cycle's last read, :meth:`whexar.bus.sdk.DxlBus.sync_read`), so their
bytes belong to the read before them.

* A write takes the next recorded packet, whatever it is, and says whether it is
  the same (:attr:`ReplayPort.mismatches`); a packet that expects an answer then
  makes its recorded reply readable, up to its first recorded timeout.
* Time: every recorded event the replay passes moves bus time on to at least its
  stamp (the port's ``elapsed_s``, charged by
  :class:`~whexar.bus.sdk.InlinePortOwner` as an emulated port's), so the cycle
  ends when it ended on the recording.
* ``isPacketTimeout()`` is true when nothing readable is left: then the recorded
  timeout is taken (its time charged, the bytes after it made readable); with none
  recorded the replayed code waits for bytes the robot never sent, which is
  counted (:attr:`ReplayPort.unrecorded_timeouts`) and answered at once.
* Past the recording's end, writes go nowhere and nothing answers.

The events are read as the replay goes, a transaction ahead of the SDK
(:meth:`BusReplay.take`), so a long recording is never held in memory at once.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Final

from whexar.bus.protocol import BROADCAST_ANSWERED, BROADCAST_ID, NO_REPLY
from whexar.runtime.devices import DeviceKind
from whexar.runtime.streams import Hand

__all__ = ["REPLAYED_BUS", "BusReplay", "Mismatch", "ReplayPort", "expects_reply"]


def expects_reply(packet: bytes) -> bool:
    """Whether a servo answers instruction packet ``packet`` (Protocol 2.0 header:
    ``FF FF FD 00 ID LEN_L LEN_H INST``; e-manual, "Status Packet": a broadcast is
    answered only by Ping and the group reads, a Sync or Bulk Write never)."""
    if len(packet) < 8:
        return True  # not a packet the SDK builds: let the recording say what came back
    instruction = packet[7]
    if instruction in NO_REPLY:
        return False
    return packet[4] != BROADCAST_ID or instruction in BROADCAST_ANSWERED


@dataclass(slots=True)
class _Exchange:
    """One recorded packet and what came back after it."""

    t: float
    packet: bytes
    answered: bool
    replies: list[tuple[float, bytes | None]] = field(default_factory=list)
    """``(t, bytes)`` read, ``(t, None)`` a timeout, in recorded order."""


@dataclass(frozen=True, slots=True)
class Mismatch:
    """A packet the replayed code wrote that differs from the recorded one."""

    t: float
    """Its recorded time (s)."""
    recorded: bytes
    written: bytes


class BusReplay:
    """The recorded bus of one run (events ``(dir, t, data)`` in recorded order), opened
    by the bus scheduler as port ``replay:NAME`` once registered (:data:`REPLAYED_BUS`)."""

    def __init__(self, events: Iterable[tuple[str, float, bytes]], *, baudrate: int) -> None:
        self.baudrate = baudrate
        self._events = Hand.of(events)
        """Read as the replay goes (an hour of recording is never held at once)."""
        self._ahead: deque[_Exchange] = deque()
        """Exchanges read and not yet written."""
        self._answered_ahead = 0
        self._answering: _Exchange | None = None
        self.port: ReplayPort | None = None

    def _read_more(self) -> bool:
        """Read the recorded events dealt so far (at least one); ``False`` at the end."""
        queue = self._events.queue
        if not queue and not self._events.fill():
            return False
        ahead, answering = self._ahead, self._answering
        while queue:
            direction, t, data = queue.popleft()
            if direction == "tx":
                ex = _Exchange(t, bytes(data), expects_reply(data))
                ahead.append(ex)
                if ex.answered:
                    self._answered_ahead += 1
                if ex.answered or answering is None:
                    answering = ex
            elif answering is not None and direction in ("rx", "timeout"):
                answering.replies.append((t, bytes(data) if direction == "rx" else None))
        self._answering = answering
        return True

    def take(self) -> _Exchange | None:
        """The next recorded packet and, if it was answered, all of its reply (read up
        to the next answered packet); ``None`` past the recording's end."""
        ahead = self._ahead
        while not ahead or (ahead[0].answered and self._answered_ahead < 2):
            if not self._read_more():
                break
        if not ahead:
            return None
        ex = ahead.popleft()
        if ex.answered:
            self._answered_ahead -= 1
        return ex

    def left(self) -> int:
        """How many recorded packets were not taken (the rest of the events is read)."""
        left = len(self._ahead)
        for direction, _, _ in self._events:  # what is dealt, and the rest
            left += direction == "tx"
        self._ahead.clear()
        return left

    def open(self, now: Callable[[], float]) -> ReplayPort:
        """The port the SDK talks to (one per run: the recording is played once)."""
        if self.port is None:
            self.port = ReplayPort(self, now)
        else:
            self.port.now = now  # a restarted scheduler carries on where the last one left
        return self.port


REPLAYED_BUS: Final = DeviceKind[BusReplay]("replayed servo bus", "replay")
"""Opened by :class:`~whexar.actors.bus.BusScheduler` as ``port = "replay:NAME"``."""


class ReplayPort:
    """Duck-typed port for dynamixel-sdk that plays a :class:`BusReplay` back (module doc).

    The surface is :class:`~whexar.bus.emulator.port.EmulatedPort`'s: the SDK's
    ``PortHandler`` calls, ``take_elapsed()`` for the port owner, ``peek()``.
    """

    def __init__(self, replay: BusReplay, now: Callable[[], float]) -> None:
        self.replay = replay
        self.now = now
        self.is_open = True
        self.is_using = False
        self.timeout_cap_ms: float | None = None
        self.port_name = "replay"
        self.baudrate = replay.baudrate
        self.elapsed_s = 0.0
        self.next = 0
        """Recorded packets written so far."""
        self.written = 0
        self.mismatches = 0
        self.first_mismatch: Mismatch | None = None
        self.unrecorded_timeouts = 0
        self.past_end = 0
        """Packets written after the recording's last."""
        self._rx = b""
        self._rx_at = 0
        self._marks: list[tuple[int, float]] = []
        """(end offset in ``_rx``, recorded time) of each readable chunk not yet passed."""
        self._replies: list[tuple[float, bytes | None]] = []
        self._reply_at = 0

    # ------------------------------------------------------------------ time

    def _reach(self, t: float) -> None:
        """Move bus time on to recorded time ``t`` (never back)."""
        gap = t - self.now() - self.elapsed_s
        if gap > 0.0:
            self.elapsed_s += gap

    def take_elapsed(self) -> float:
        """Return the bus time the calls since the last take cost, and reset it."""
        elapsed = self.elapsed_s
        self.elapsed_s = 0.0
        return elapsed

    @property
    def tx_time_per_byte(self) -> float:
        """Milliseconds per byte at the port's baud rate (``PortHandler``'s attribute)."""
        return 1000.0 / self.baudrate * 10.0

    # ------------------------------------------------------------------ the SDK's calls

    def openPort(self) -> bool:  # noqa: N802 — the SDK's names
        self.is_open = True
        return True

    def closePort(self) -> None:  # noqa: N802
        self.is_open = False

    def setPortName(self, port_name: str) -> None:  # noqa: N802
        self.port_name = port_name

    def getPortName(self) -> str:  # noqa: N802
        return self.port_name

    def setBaudRate(self, baudrate: int) -> bool:  # noqa: N802
        self.baudrate = baudrate
        return True

    def getBaudRate(self) -> int:  # noqa: N802
        return self.baudrate

    def setPacketTimeout(self, packet_length: int) -> None:  # noqa: N802
        """Nothing to arm: a wait ends where the recorded one did."""

    def setPacketTimeoutMillis(self, msec: float) -> None:  # noqa: N802
        """Nothing to arm: a wait ends where the recorded one did."""

    def clearPort(self) -> None:  # noqa: N802
        """Drop the readable bytes not yet read (the SDK does this before a transmit)."""
        self._rx = b""
        self._rx_at = 0
        self._marks.clear()

    def getBytesAvailable(self) -> int:  # noqa: N802
        return len(self._rx) - self._rx_at

    def peek(self) -> bytes:
        """The readable bytes not yet read."""
        return self._rx[self._rx_at :]

    def writePort(self, packet: bytes | Iterable[int]) -> int:  # noqa: N802
        """Take the next recorded packet (module doc); its reply becomes readable."""
        data = bytes(packet)
        self.written += 1
        ex = self.replay.take()
        if ex is None:
            self.past_end += 1
            return len(data)
        self.next += 1
        if ex.packet != data:
            self.mismatches += 1
            if self.first_mismatch is None:
                self.first_mismatch = Mismatch(ex.t, ex.packet, data)
        self._reach(ex.t)
        if ex.answered:
            self._replies = ex.replies
            self._reply_at = 0
            self._readable()
        return len(data)

    def _readable(self) -> None:
        """Make the recorded reply readable up to its next timeout."""
        replies = self._replies
        k = self._reply_at
        parts = [self._rx[self._rx_at :]]
        size = len(parts[0])
        marks = [(end - self._rx_at, t) for end, t in self._marks]
        while k < len(replies):
            t, chunk = replies[k]
            if chunk is None:  # a timeout: what follows waits for it
                break
            parts.append(chunk)
            size += len(chunk)
            marks.append((size, t))
            k += 1
        self._reply_at = k
        self._rx = b"".join(parts)
        self._rx_at = 0
        self._marks = marks

    def readPort(self, length: int) -> bytes:  # noqa: N802
        """Up to ``length`` readable bytes; bus time moves on to when they were read."""
        at = self._rx_at
        data = self._rx[at : at + length] if length >= 0 else self._rx[at:][:length]
        self._rx_at = at = at + len(data)
        marks = self._marks
        while marks and marks[0][0] <= at:
            self._reach(marks.pop(0)[1])
        if marks and data:
            self._reach(marks[0][1])  # part of a chunk: it had arrived
        return data

    def isPacketTimeout(self) -> bool:  # noqa: N802
        """True once nothing readable is left (module doc)."""
        if self._rx_at < len(self._rx):
            return False
        replies, k = self._replies, self._reply_at
        if k < len(replies):  # the recorded timeout (only a timeout stops _readable)
            self._reach(replies[k][0])
            self._reply_at = k + 1
            self._readable()
        else:
            self.unrecorded_timeouts += 1
        return True
