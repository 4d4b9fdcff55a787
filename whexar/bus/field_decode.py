"""A recorded servo bus decoded into facts: what each servo answered, when it was silent,
what was written to it (for :mod:`whexar.bus.field`).

A packet written that expects an answer (e-manual, Protocol 2.0, "Status Packet": not
a Sync or Bulk Write; to the broadcast ID only Ping and the group reads) opens a
request; the bytes read until the next one answer it, and are decoded together once
its exchange is over. Each status packet is an :class:`Answered` fact: the servo, its
ERR byte (bit 7, Alert: Hardware Error Status is non-zero) and the register span it
carries — a Read's, each servo's of a Sync or Bulk Read, each servo's part of a Fast
one (:func:`~whexar.bus.protocol.split_fast_status`), a Ping's Model Number (address 0)
and Firmware Version (6) — stamped when the reply was all there. Where the SDK gave up
waiting (a recorded ``timeout``), the servo it waited for — a Ping's or a Read's, the
first of a Sync Read's that had not answered, since the SDK reads them in the order it
asked — is :class:`Silent`. Every write (Write, Sync Write, Bulk Write, Reboot…) is a
:class:`Written` fact per servo.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Final, NamedTuple

from whexar.bus.protocol import (
    BROADCAST_ANSWERED,
    BROADCAST_ID,
    HEADER,
    NO_REPLY,
    Instruction,
    Packet,
    PacketDecoder,
    PacketError,
    crc16,
    parse_bulk_read_params,
    parse_bulk_write_params,
    parse_read_params,
    parse_sync_read_params,
    parse_sync_write_params,
    parse_write_params,
    split_fast_status,
    unstuff,
)

_MUST_ANSWER: Final = frozenset(
    {
        Instruction.PING,
        Instruction.READ,
        Instruction.SYNC_READ,
        Instruction.BULK_READ,
    }
)
"""Requests a live servo always answers (Ping whatever its Status Return Level; the reads
unless it is 0, which the scheduler never sets): a timeout on one names a silent servo.
Not the writes: at Status Return Level 1 a live servo leaves them unanswered."""
_FAST: Final = frozenset({Instruction.FAST_SYNC_READ, Instruction.FAST_BULK_READ})
_READS: Final = _FAST | {Instruction.READ, Instruction.SYNC_READ, Instruction.BULK_READ}
WRITES: Final = frozenset(
    {Instruction.WRITE, Instruction.REG_WRITE, Instruction.SYNC_WRITE, Instruction.BULK_WRITE}
)
OTHER_WRITES: Final = {
    Instruction.REBOOT: "reboot",
    Instruction.FACTORY_RESET: "factory_reset",
    Instruction.CLEAR: "clear",
}
"""Instructions compared like writes, under these names (their value: 1)."""
OTHER_NAMES: Final[Mapping[int, str]] = {int(k): v for k, v in OTHER_WRITES.items()}

MEASURED: Final = ((70, 71), (120, 147))
"""Hardware Error Status (70) and the present values (120–146: Realtime Tick to Present
Temperature): what the servo measures, which goes stale (e-manual, MX (2.0) control table)."""


@dataclass(slots=True)
class Recorded:
    """A recorded write of one register to one servo, as the replay compares it."""

    t: float
    value: int
    met: bool = False
    """A replayed write of the same servo and register fell within its window."""


# --------------------------------------------------------------------------- facts


class Answered(NamedTuple):
    """A status packet from ``servo_id`` at ``t``: its ERR byte and the spans it carries.

    The facts are named tuples: some forty of them are decoded per cycle of the robot."""

    t: float
    servo_id: int
    error: int
    spans: tuple[tuple[int, bytes], ...] = ()
    """``(start address, bytes)`` of the registers it answered; none for an acknowledgement."""
    fast: bool = False
    """It was a servo's part of a Fast Sync/Bulk Read."""


class Silent(NamedTuple):
    """The SDK waited for ``servo_id`` until ``t`` and no status came (a recorded timeout)."""

    t: float
    servo_id: int


class Written(NamedTuple):
    """A packet written at ``t`` that changes ``servo_id``: its instruction and, for the
    writes, ``data`` at address ``start`` (``servo_id`` is the broadcast ID for a
    broadcast Write: every servo)."""

    t: float
    servo_id: int
    instruction: int
    start: int = 0
    data: bytes = b""


Fact = Answered | Silent | Written


@dataclass(frozen=True, slots=True)
class _Asked:
    """What a recorded request asked: each servo's span, in the order asked."""

    instruction: int
    id: int
    order: tuple[tuple[int, int, int], ...]
    """(servo, start, length) in the order asked (a ping or a write: its one servo, 0, 0)."""
    spans: Mapping[int, tuple[int, int]]
    """Servo → (start, length)."""
    must_answer: bool
    """A live servo answers it (:data:`_MUST_ANSWER`): a timeout names the one waited for."""
    measured: bool
    """It reads only what the servos measure (or a Ping): replayed at the same moment, it
    is answered as it was on the recording (:meth:`FieldBus.pace`)."""


@dataclass(slots=True)
class _Request:
    """A recorded packet that expects an answer, and what answered it so far."""

    asked: _Asked
    answered: set[int] = field(default_factory=set)
    """Servos that answered, or were found silent."""


def _asked(p: Packet) -> _Asked:
    inst = p.instruction
    order: tuple[tuple[int, int, int], ...] = ()
    try:
        if inst == Instruction.READ:
            order = ((p.id, *parse_read_params(p.params)),)
        elif inst in (Instruction.SYNC_READ, Instruction.FAST_SYNC_READ):
            start, length, ids = parse_sync_read_params(p.params)
            order = tuple((sid, start, length) for sid in ids)
        elif inst in (Instruction.BULK_READ, Instruction.FAST_BULK_READ):
            order = tuple(parse_bulk_read_params(p.params))
        else:
            order = ((p.id, 0, 0),)
    except PacketError:
        pass
    spans = {sid: (start, length) for sid, start, length in order}
    measured = inst == Instruction.PING or (
        inst in _READS
        and bool(order)
        and all(
            length > 0 and any(a <= start and start + length <= b for a, b in MEASURED)
            for _, start, length in order
        )
    )
    return _Asked(inst, p.id, order, spans, inst in _MUST_ANSWER, measured)


def packet_writes(packet: Packet) -> list[tuple[int, int, bytes]]:
    """``(servo, start, data)`` of each servo's share of a write packet (the broadcast ID
    for a broadcast Write); ``(servo, -1, b"")`` for a Reboot, Factory Reset or Clear;
    none for any other instruction or malformed parameters."""
    inst = packet.instruction
    try:
        if inst in (Instruction.WRITE, Instruction.REG_WRITE):
            start, data = parse_write_params(packet.params)
            return [(packet.id, start, data)]
        if inst == Instruction.SYNC_WRITE:
            start, _, entries = parse_sync_write_params(packet.params)
            return [(sid, start, data) for sid, data in entries]
        if inst == Instruction.BULK_WRITE:
            return parse_bulk_write_params(packet.params)
    except PacketError:
        return []
    if inst in OTHER_WRITES:
        return [(packet.id, -1, b"")]
    return []


def expects_answer(packet: Packet) -> bool:
    """Whether a servo answers instruction ``packet`` (e-manual, "Status Packet": not a
    Sync or Bulk Write, and to the broadcast ID only Ping and the group reads)."""
    inst = packet.instruction
    if inst in NO_REPLY:
        return False
    return packet.id != BROADCAST_ID or inst in BROADCAST_ANSWERED


@dataclass(slots=True)
class Exchange:
    """A recorded packet written, and when its exchange was over (its reply read, or the
    wait for it given up; a packet nothing answers: when it was written)."""

    t: float
    data: bytes
    end: float
    after: float
    """When the exchange before it was over: it began no earlier."""
    first_read: float | None = None
    """When the first of its reply was read. At :attr:`t` itself, the packet was stamped
    once its whole exchange was over — an emulated port's way; a real one stamps a
    packet as it goes out (:func:`~whexar.bus.sdk.tap_port`)."""
    read: int = 0
    """Bytes of its reply read."""
    writes: list[tuple[tuple[int, str], Recorded]] = field(default_factory=list)
    """The registers it writes, as :class:`FieldBus` keeps them for comparison."""
    began: float | None = None
    """When it began (:meth:`FieldBus.pace` works it out once)."""
    asked: _Asked | None = None
    """What it asked, if it expects an answer."""
    reply: bytes | None = None
    """Every byte read for it."""
    timed_out: bool = False
    """The SDK gave up waiting for some of its reply."""


WriteSink = Callable[[float, int, list[tuple[int, int, bytes]]], None]
"""``(t, instruction, [(servo, start, data)])``: a packet written (:func:`packet_writes`)."""


class BusDecoder:
    """Turns a bus link's recorded events, fed in order, into :data:`Fact` s (module doc);
    each packet written also into an :class:`Exchange` in ``exchanges``, if given, and
    the writes to ``on_write`` instead of the facts, if given.

    The bytes read for one request are decoded together, once its exchange is over (the
    next request, a timeout, :meth:`close`), and its answers are stamped with the time the
    reply was all there (:attr:`Exchange.end`): the SDK reads a status packet in two or
    three pieces, and a goal write riding on a read (:meth:`whexar.bus.sdk.DxlBus.sync_read`)
    goes out once the reply is complete, before the SDK has read it all out."""

    def __init__(
        self, exchanges: deque[Exchange] | None = None, on_write: WriteSink | None = None
    ) -> None:
        self._tx = PacketDecoder(max_length=0xFFFF)
        self.on_write = on_write
        """Where the writes go, if not into the facts as :class:`Written`."""
        self._rx = PacketDecoder(max_length=0xFFFF)
        self._chunks: list[bytes] = []
        """Bytes read for the current request, not yet decoded."""
        self._request: _Request | None = None
        self._statuses: dict[bytes, _Status] = {}
        """Status packets checked (:func:`_statuses`)."""
        self._asked: dict[bytes, _Asked] = {}
        """Requests decoded, by their bytes: a cycle sends the same ones again and again."""
        self.exchanges = exchanges
        self._exchange: Exchange | None = None
        """The exchange of the last packet that expects an answer."""
        self.last: Exchange | None = None
        """The exchange of the last packet written."""
        self._reading = False
        """The last packet written expects an answer: what is read ends its exchange."""
        self.packets = 0
        """Packets written (``tx``) decoded."""
        self.strays = 0
        """Status packets that answer nothing asked (another ID, or no request)."""

    def feed(self, direction: str, t: float, data: bytes, out: list[Fact]) -> None:
        """Decode one recorded event, appending the facts it completes to ``out``."""
        if direction == "rx":
            self._chunks.append(data)
            exchange = self._exchange
            # What is read after a packet written mid-reply (a goal write riding on the
            # read) was all there already: the SDK reading it out does not end the exchange.
            if self._reading and exchange is not None:
                if exchange.first_read is None:
                    exchange.first_read = t
                exchange.read += len(data)
                if t > exchange.end:
                    exchange.end = t
        elif direction == "tx":
            self._sent(t, data if data.__class__ is bytes else bytes(data), out)
        elif direction == "timeout":
            self._flush(out)
            self._timed_out(t, out)
            exchange = self._exchange
            if exchange is not None:
                exchange.timed_out = True
                if t > exchange.end:
                    exchange.end = t

    def close(self, out: list[Fact]) -> None:
        """The events are over: decode what was read for the last request."""
        self._flush(out)

    def _sent(self, t: float, data: bytes, out: list[Fact]) -> None:
        opened: _Asked | None = None
        for p in self._tx.feed(data):
            if p.is_status:
                continue
            self.packets += 1
            inst = p.instruction
            if inst in WRITES or inst in OTHER_WRITES:
                if self.on_write is not None:
                    self.on_write(t, inst, packet_writes(p))
                else:
                    out.extend(
                        Written(t, sid, inst, start, span) for sid, start, span in packet_writes(p)
                    )
            if not expects_answer(p):
                continue  # nothing answers it: a reply still being read is the last request's
            self._flush(out)
            # The SDK clears its input before a transmit that expects an answer.
            self._rx.reset()
            key = data if len(self._asked) < 1024 else b""
            asked = self._asked.get(key) if key else None
            if asked is None:
                asked = _asked(p)
                if key:
                    self._asked[key] = asked
            self._request = _Request(asked)
            opened = asked
        if self._tx.pending:
            self._tx.reset()
        last = self.last
        exchange = Exchange(t, data, t, t if last is None else min(t, last.end))
        self.last = exchange
        if self.exchanges is not None:
            self.exchanges.append(exchange)
        if opened is not None:
            exchange.asked = opened
            self._exchange = exchange
        self._reading = opened is not None

    def _flush(self, out: list[Fact]) -> None:
        chunks = self._chunks
        if not chunks:
            return
        data = chunks[0] if len(chunks) == 1 else b"".join(chunks)
        chunks.clear()
        request = self._request
        if request is None:
            self.strays += 1
            return
        exchange = self._exchange
        t = -math.inf
        if exchange is not None:
            t = exchange.end
            exchange.reply = data
        statuses = _statuses(data, self._statuses)
        if statuses is None:  # not whole packets back to back: the decoder's patient way
            statuses = [(p.id, p.error or 0, p.params) for p in self._rx.feed(data) if p.is_status]
        for sid, error, params in statuses:
            self._answer(request, sid, error, params, t, out)

    def _answer(
        self, request: _Request, sid: int, error: int, params: bytes, t: float, out: list[Fact]
    ) -> None:
        asked = request.asked
        inst = asked.instruction
        if inst in _FAST:
            if sid != BROADCAST_ID:
                self.strays += 1
                return
            try:
                lengths = [length for _, _, length in asked.order]
                parts = split_fast_status(Packet(sid, _STATUS, params, error), lengths)
            except PacketError:
                return  # a servo left its part out: the packet names no one reliably
            for (err, one, data), (wanted, start, _) in zip(parts, asked.order, strict=True):
                if one == wanted:
                    request.answered.add(one)
                    out.append(Answered(t, one, err, self._spans(err, start, data), True))
            return
        span = asked.spans.get(sid)
        if span is None and inst == Instruction.PING and asked.id == BROADCAST_ID:
            span = (0, 0)  # a broadcast Ping: every servo answers it
        if span is None:
            self.strays += 1
            return
        request.answered.add(sid)
        start, length = span
        if inst == Instruction.PING:
            spans = ((0, params[0:2]), (6, params[2:3])) if len(params) == 3 else ()
            out.append(Answered(t, sid, error, spans))
        elif length and len(params) == length:
            out.append(Answered(t, sid, error, self._spans(error, start, params)))
        else:
            out.append(Answered(t, sid, error))

    @staticmethod
    def _spans(error: int, start: int, data: bytes) -> tuple[tuple[int, bytes], ...]:
        # An error number (bits 0–6) means the data is not the registers' (e-manual, "Error").
        return () if error & 0x7F or not data else ((start, bytes(data)),)

    def _timed_out(self, t: float, out: list[Fact]) -> None:
        request = self._request
        if request is None or not request.asked.must_answer:
            return
        # The SDK reads the statuses in the order it asked for them: the wait that timed
        # out was for the first servo that had not answered.
        for sid, _, _ in request.asked.order:
            if sid not in request.answered and sid != BROADCAST_ID:
                request.answered.add(sid)
                out.append(Silent(t, sid))
                return


_STATUS: Final = int(Instruction.STATUS)
_STUFFED: Final = b"\xff\xff\xfd\xfd"


_Status = tuple[int, int, bytes]
"""A status packet's ID, ERR byte and parameters."""
_KNOWN_STATUSES: Final = 4096
"""Status packets kept once checked (:func:`_statuses`): a servo standing still, a supply
steady, answer the same bytes again and again (two recorded statuses in three repeat one
before them, on a walk)."""


def _statuses(data: bytes, known: dict[bytes, _Status]) -> list[_Status] | None:
    """``(id, error, params)`` of each status packet of ``data``, if it is status packets
    back to back, each whole and its CRC right (what a reply nearly always is); else
    ``None``. Packet layout and stuffing: e-manual, Protocol 2.0 (as
    :class:`~whexar.bus.protocol.PacketDecoder`, without its hunt for a header).
    ``known``: packets checked before, by their bytes (filled here)."""
    out: list[_Status] = []
    at, n = 0, len(data)
    while at < n:
        if n - at < 11:
            return None
        end = at + 7 + (data[at + 5] | data[at + 6] << 8)
        packet = data[at:end]
        status = known.get(packet)
        if status is None:
            if end > n or end - at < 11 or packet[:4] != HEADER or packet[7] != _STATUS:
                return None
            if crc16(packet[:-2]) != packet[-2] | packet[-1] << 8:
                return None
            sid = packet[4]
            body = packet[7:-2]  # INST, ERR, params
            if sid != BROADCAST_ID and _STUFFED in body:  # a fast status packet is not stuffed
                body = unstuff(body)
            status = (sid, body[1], body[2:])
            if len(known) >= _KNOWN_STATUSES:
                known.clear()
            known[packet] = status
        out.append(status)
        at = end
    return out


def decode(events: Iterable[tuple[str, float, bytes]]) -> Iterator[Fact]:
    """The facts of a bus link's recorded events (``(direction, t, data)``, in recorded order)."""
    decoder = BusDecoder()
    out: list[Fact] = []
    for direction, t, data in events:
        decoder.feed(direction, t, data, out)
        yield from out
        out.clear()
    decoder.close(out)
    yield from out
