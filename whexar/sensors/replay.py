"""Recorded sensor links played back: the board's serial bytes and the IMU's I²C calls.

Theory of operation
-------------------
A recording holds what the sensor reader's link received and sent, each chunk with
the runtime time it happened at, and when the link was opened or went away
(:class:`~whexar.sensors.serial_link.TappedLink`, the reader's ``_open``); and every
call the IMU reader made on its I²C adapter, the bytes that came back, and the calls
that failed (:class:`~whexar.sensors.lsm9ds1.TappedBus`). These play them back
through the same edges:

* :class:`BoardReplay` (port ``replay:NAME``, :data:`REPLAYED_BOARD`) opens as the
  recording says — a recorded ``gone`` raises
  :class:`~whexar.errors.DeviceGoneError` with the recorded reason — and its link's
  :meth:`~ReplayLink.receive` returns each recorded chunk at its recorded time, to
  the same frame decoder, until the recorded ``gone``. What the reader sends is
  compared with what it sent on the recording, and otherwise dropped.
* :class:`I2CReplay` (device ``replay:NAME``, :data:`REPLAYED_I2C`) answers each
  call with the recorded bytes, raises the recorded ``OSError`` where the call
  failed, and says when a call differs from the recorded one.

A log recorded on a real clock (the robot) is played back *by time*: the replayed
reader's calls come at its own instants, never exactly the recorded ones, and may
be more or fewer. :class:`I2CFieldReplay` answers each call from the recorded calls
of the same kind (the same address and register) near that time: the first one
within :data:`FIELD_WINDOW_S` of it, else the last answer held; a recorded failure
fails again, a recorded unplugged link is unplugged for as long. The board needs no
such mode: its frames come at their recorded times either way.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Final

from whexar.errors import DeviceGoneError
from whexar.runtime.clock import Clock
from whexar.runtime.devices import DeviceKind
from whexar.runtime.streams import Dealer, Hand

__all__ = [
    "FIELD_WINDOW_S",
    "REPLAYED_BOARD",
    "REPLAYED_I2C",
    "BoardReplay",
    "I2CFieldReplay",
    "I2CReplay",
    "LinkMismatch",
    "ReplayLink",
]

Event = tuple[str, float, bytes]
"""A recorded link event: (direction, t, data)."""


@dataclass(frozen=True, slots=True)
class LinkMismatch:
    """Bytes the replayed code sent that differ from the recorded ones."""

    t: float
    """The recorded time (s)."""
    recorded: bytes
    written: bytes


class _Compared:
    """Counts what was sent against what the recording says was sent."""

    def __init__(self) -> None:
        self.mismatches = 0
        self.first_mismatch: LinkMismatch | None = None

    def compare(self, expected: Event | None, written: bytes) -> None:
        recorded = expected[2] if expected is not None else b""
        if expected is None or recorded != written:
            self.mismatches += 1
            if self.first_mismatch is None:
                t = expected[1] if expected is not None else math.inf
                self.first_mismatch = LinkMismatch(t, recorded, written)


def _recorded_error(text: str) -> OSError:
    """The ``OSError`` a recorded failure (``"ERRNO:message"``) raises again."""
    code, _, message = text.partition(":")
    return OSError(int(code) if code.lstrip("-").isdigit() else 5, message)


class _SMBusCalls(_Compared):
    """The three smbus2 calls the LSM9DS1 driver makes, answered by :meth:`_call` (the
    bytes recorded for the call that goes out, or ``None``)."""

    unrecorded_calls = 0

    def _call(self, out: bytes) -> bytes | None:
        raise NotImplementedError

    def read_byte_data(self, i2c_addr: int, register: int, /) -> int:
        got = self._call(bytes((i2c_addr, register)))
        if not got:
            self.unrecorded_calls += 1
            raise OSError(121, "Remote I/O error (no recorded answer)")
        return got[0]

    def write_byte_data(self, i2c_addr: int, register: int, value: int, /) -> None:
        self._call(bytes((i2c_addr, register, value)))

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int, /) -> list[int]:
        got = self._call(bytes((i2c_addr, register)))
        if got is None or len(got) < length:
            self.unrecorded_calls += 1
            raise OSError(121, "Remote I/O error (no recorded answer of that length)")
        return list(got[:length])

    def close(self) -> None:
        """Nothing to close: the recording stays for the next open."""


class BoardReplay(_Compared):
    """The recorded link to the sensor board, opened by the sensor reader as
    ``port = "replay:NAME"`` once registered (:data:`REPLAYED_BOARD`)."""

    def __init__(self, events: Iterable[Event]) -> None:
        super().__init__()
        # Read as the replay goes: an hour of recording is never held at once.
        split = Dealer(((event[0] == "tx", event) for event in events), batch=1)
        self.incoming: Hand[Event] = split.hand(False)
        """``rx``, ``open`` and ``gone``, in recorded order."""
        self.sent: Hand[Event] = split.hand(True)
        self.unrecorded_opens = 0

    def open(self, clock: Clock) -> ReplayLink:
        """Open as the recording did: the next ``open``, or raise its ``gone``."""
        incoming = self.incoming
        while (first := incoming.peek()) is not None and first[0] == "rx":
            incoming.popleft()  # bytes a closed link never read (an earlier run's end)
        if not incoming:
            self.unrecorded_opens += 1
            return ReplayLink(self, clock)  # past the recording: a link that stays silent
        direction, _, data = incoming.popleft()
        if direction == "gone":
            raise DeviceGoneError(data.decode("utf-8", "replace"))
        return ReplayLink(self, clock)


class ReplayLink:
    """A :class:`~whexar.sensors.serial_link.ByteLink` playing a :class:`BoardReplay`."""

    name = "replay"

    def __init__(self, replay: BoardReplay, clock: Clock) -> None:
        self.replay = replay
        self._clock = clock
        self.closed = False

    async def receive(self) -> bytes:
        """The next recorded chunk at its time; the recorded ``gone`` as DeviceGoneError."""
        incoming = self.replay.incoming
        first = incoming.peek()
        if self.closed or first is None or first[0] == "open":
            await self._clock.sleep(math.inf)  # nothing more was received on this link
        direction, t, data = incoming.popleft()
        await self._clock.sleep_until(t)
        if direction == "gone":
            raise DeviceGoneError(data.decode("utf-8", "replace"))
        return data

    async def send(self, data: bytes) -> None:
        """Compare ``data`` with what was sent next on the recording."""
        sent = self.replay.sent
        self.replay.compare(sent.popleft() if sent else None, bytes(data))

    async def aclose(self) -> None:
        self.closed = True


REPLAYED_BOARD: Final = DeviceKind[BoardReplay]("replayed sensor-board link", "replay")
"""Opened by :class:`~whexar.actors.sensing.SensorReader` as ``port = "replay:NAME"``."""


class I2CReplay(_SMBusCalls):
    """The recorded I²C calls of the IMU reader, opened as ``device = "replay:NAME"``
    once registered (:data:`REPLAYED_I2C`). The calls of ``smbus2.SMBus`` the driver
    makes, answered from the recording."""

    def __init__(self, events: Iterable[Event]) -> None:
        super().__init__()
        self.events: Hand[Event] = Hand.of(events)
        """Read as the replay goes: an hour of recording is never held at once."""
        self.unrecorded_calls = 0

    def open(self, now: Callable[[], float]) -> I2CReplay:
        """Open as the recording did (the clock is not needed: calls come in order)."""
        return self.opened()

    def opened(self) -> I2CReplay:
        """Open as the recording did: the next ``open``, or raise its ``gone``."""
        events = self.events
        while (first := events.peek()) is not None and first[0] not in ("open", "gone"):
            events.popleft()  # calls of a bus the recording closed before they were answered
        if events:
            direction, _, data = events.popleft()
            if direction == "gone":
                raise DeviceGoneError(data.decode("utf-8", "replace"))
        return self

    def _call(self, out: bytes) -> bytes | None:
        """Take the recorded call ``out`` and what came back; raise its recorded error."""
        events = self.events
        while (first := events.peek()) is not None and first[0] in ("open", "gone"):
            events.popleft()  # the reader reopened without our knowing: carry on
        if first is None:
            self.unrecorded_calls += 1
            raise OSError(121, "Remote I/O error (past the recording's end)")
        self.compare(events.popleft(), out)
        after = events.peek()
        if after is not None and after[0] == "error":
            raise _recorded_error(events.popleft()[2].decode("utf-8", "replace"))
        if after is not None and after[0] == "rx":
            return events.popleft()[2]
        return None


FIELD_WINDOW_S: Final = 0.05
"""How far apart in time a replayed call and a recorded one of the same kind may be and
still be the same call: a few of the IMU's sample periods at its default 119 Hz, well
under the 0.3 s after which the reader calls the link stale."""


class I2CFieldReplay(_SMBusCalls):
    """The recorded I²C calls of the IMU reader played back by time (module docstring),
    opened as ``device = "replay:NAME"``. :attr:`now` is the runtime's clock, which the
    reader gives it as it opens; ``window_s`` how far a call may be from its recorded one."""

    def __init__(self, events: Iterable[Event], *, window_s: float = FIELD_WINDOW_S) -> None:
        super().__init__()
        self.events: Hand[Event] = Hand.of(events)
        """Read as the replay goes, up to a window ahead of the clock."""
        self.window_s = window_s
        self.now: Callable[[], float] = lambda: 0.0
        self._calls: dict[bytes, deque[tuple[float, bytes | None, str | None]]] = {}
        """Per call (address, register[, value]): (t, answer, error) recorded, not yet taken."""
        self._held: dict[bytes, bytes | None] = {}
        self._out: bytes | None = None
        """The call read last, awaiting its answer in the recording."""
        self._down: deque[tuple[float, float, str]] = deque()
        """Recorded spells of an unplugged link: (from, to, why)."""
        self._gone_at: tuple[float, str] | None = None
        self.unrecorded_calls = 0
        """Calls of a kind the recording never made."""
        self.held_calls = 0
        """Calls answered with the last answer held (none recorded near their time)."""
        self.skipped_calls = 0
        """Recorded calls no replayed call came near."""

    def _read_to(self, t: float) -> None:
        """Take the recorded events up to ``t``."""
        events = self.events
        while (first := events.peek()) is not None and first[1] <= t:
            direction, at, data = events.popleft()
            if direction == "tx":
                self._out = bytes(data)
                self._calls.setdefault(self._out, deque()).append((at, None, None))
            elif direction in ("rx", "error") and self._out is not None:
                queue = self._calls[self._out]
                t0, _, _ = queue[-1]
                if direction == "rx":
                    queue[-1] = (t0, bytes(data), None)
                else:
                    queue[-1] = (t0, None, data.decode("utf-8", "replace"))
            elif direction == "gone":
                self._gone_at = (at, data.decode("utf-8", "replace"))
            elif direction == "open" and self._gone_at is not None:
                self._down.append((*self._gone_at[:1], at, self._gone_at[1]))
                self._gone_at = None

    def _unplugged(self, t: float) -> str | None:
        """Why the link was down at ``t`` on the recording, or ``None``."""
        while self._down and self._down[0][1] <= t:
            self._down.popleft()
        if self._down and self._down[0][0] <= t:
            return self._down[0][2]
        if self._gone_at is not None and self._gone_at[0] <= t:
            return self._gone_at[1]
        return None

    def open(self, now: Callable[[], float]) -> I2CFieldReplay:
        """Open on the runtime's clock ``now``, as the recording had the link at this time."""
        self.now = now
        return self.opened()

    def opened(self) -> I2CFieldReplay:
        """Open as the recording had it open at this time: unplugged, raise its reason."""
        t = self.now()
        self._read_to(t + self.window_s)
        why = self._unplugged(t)
        if why is not None:
            raise DeviceGoneError(why)
        return self

    def _call(self, out: bytes) -> bytes | None:
        t = self.now()
        self._read_to(t + self.window_s)
        why = self._unplugged(t)
        if why is not None:
            raise OSError(19, f"No such device (recorded: {why})")
        queue = self._calls.get(out)
        if queue is None and out not in self._held:
            self.unrecorded_calls += 1
            self.compare(None, out)
            raise OSError(121, "Remote I/O error (a call the recording never made)")
        while queue and queue[0][0] < t - self.window_s:
            queue.popleft()
            self.skipped_calls += 1
        if not queue:
            self.held_calls += 1
            return self._held.get(out)
        _, answer, error = queue.popleft()
        if error is not None:
            raise _recorded_error(error)
        self._held[out] = answer
        return answer

    def write_byte_data(self, i2c_addr: int, register: int, value: int, /) -> None:
        out = bytes((i2c_addr, register, value))
        if out not in self._calls and out not in self._held:
            # A setting the recording never wrote (a changed configuration): the chip
            # takes it; the replay says it differs.
            self.compare(None, out)
            self._held[out] = None
            return
        self._call(out)


REPLAYED_I2C: Final = DeviceKind[I2CReplay | I2CFieldReplay]("replayed I²C bus", "replay")
"""Opened by :class:`~whexar.actors.sensing.ImuReader` as ``device = "replay:NAME"``."""
