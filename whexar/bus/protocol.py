"""Dynamixel Protocol 2.0 packets: a sans-IO codec (bytes in, packets out; no port, no clock).

Theory of operation
-------------------
A packet on the wire is ``FF FF FD 00 | ID | LEN_L LEN_H | INST | params | CRC_L CRC_H``;
a status packet has INST 0x55 and an ERR byte first among its parameters
(ROBOTIS e-manual, "Protocol 2.0"). LEN counts INST, parameters and CRC.

* **Byte stuffing.** Inside INST and parameters every ``FF FF FD`` gets an
  extra ``FD`` so that no header can appear in a body; LEN and CRC are
  computed over the stuffed bytes, and a receiver checks the CRC before
  unstuffing (e-manual, "Packet Process").
* **CRC.** CRC-16 with polynomial 0x8005, no reflection, initial value 0 —
  the table ``dynamixel_sdk``'s ``updateCRC`` uses, over every byte from the
  header up to the CRC.
* **Fast Sync/Bulk Read.** One status packet from 0xFE carries every
  servo's ``ERR ID data CRC`` in turn. It is *not* stuffed; each servo's CRC
  is the running CRC of the whole packet from its header up to that point
  (the e-manual's worked example checks out only that way), so the last one
  is the packet's own CRC and a host need check only that.

:class:`PacketDecoder` is a streaming receiver: feed it whatever bytes
arrive, in pieces of any size, and it returns each complete packet whose CRC
matches. It hunts for ``FF FF FD 00``, skips garbage (counted), refuses
lengths beyond a bound (so a corrupted LEN cannot make it wait for ever),
keeps half a packet until the rest arrives, and unstuffs. A status packet
from 0xFE can only be a Fast Sync/Bulk Read reply, so it is left unstuffed;
:func:`split_fast_status` cuts it into per-servo entries.
"""

from __future__ import annotations

import struct
from array import array
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from enum import IntEnum
from typing import Final

from whexar.bus import wire
from whexar.errors import DeviceError, UsageError

HEADER: Final = b"\xff\xff\xfd\x00"
"""Header and reserved byte that open every Protocol 2.0 packet (e-manual)."""
BROADCAST_ID: Final = 0xFE
"""Packet ID every device executes; only Ping and the (Fast) Sync/Bulk Reads answer it."""
MAX_ID: Final = 0xFC
"""Highest device ID (252); 0xFD and 0xFF never appear as IDs (e-manual, Packet ID)."""
ALERT: Final = 0x80
"""Bit 7 of a status packet's ERR byte: Hardware Error Status is non-zero (e-manual)."""
MAX_LENGTH: Final = 1024
"""Largest LEN the decoder accepts by default: dynamixel-sdk's ``RXPACKET_MAX_LEN``."""
INSTRUCTION_OVERHEAD: Final = 10
"""Bytes of an instruction packet besides its parameters (header 4, ID, LEN 2, INST, CRC 2)."""
STATUS_OVERHEAD: Final = 11
"""Bytes of a status packet besides its parameters (an instruction packet's 10 + ERR)."""

_STUFF_FROM: Final = b"\xff\xff\xfd"
_STUFF_TO: Final = b"\xff\xff\xfd\xfd"


class Instruction(IntEnum):
    """Instruction byte values (e-manual, Protocol 2.0, "Instruction")."""

    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    FACTORY_RESET = 0x06
    REBOOT = 0x08
    CLEAR = 0x10
    STATUS = 0x55
    SYNC_READ = 0x82
    SYNC_WRITE = 0x83
    FAST_SYNC_READ = 0x8A
    BULK_READ = 0x92
    BULK_WRITE = 0x93
    FAST_BULK_READ = 0x9A


_STATUS: Final = int(Instruction.STATUS)
"""The status instruction as a plain int: cheaper than the enum member on hot paths."""


NO_REPLY: Final = frozenset({Instruction.SYNC_WRITE, Instruction.BULK_WRITE})
"""Instructions no servo answers (e-manual, "Status Packet")."""
BROADCAST_ANSWERED: Final = frozenset(
    {
        Instruction.PING,
        Instruction.SYNC_READ,
        Instruction.FAST_SYNC_READ,
        Instruction.BULK_READ,
        Instruction.FAST_BULK_READ,
    }
)
"""Instructions sent to the broadcast ID that the servos answer (e-manual, "Status Packet")."""


class StatusError(IntEnum):
    """Error numbers in bits 0–6 of a status packet's ERR byte (e-manual, "Error")."""

    RESULT_FAIL = 1
    INSTRUCTION = 2
    CRC = 3
    DATA_RANGE = 4
    DATA_LENGTH = 5
    DATA_LIMIT = 6
    ACCESS = 7


class PacketError(DeviceError):
    """Bytes that do not form the packet or parameters they claim to be."""


# --------------------------------------------------------------------------- CRC & stuffing


def _crc_table() -> tuple[int, ...]:
    # MSB-first CRC-16, polynomial 0x8005; reproduces dynamixel_sdk's literal table.
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return tuple(table)


_CRC_TABLE: Final = _crc_table()

# Two bytes per step: feeding the big-endian word w to register r gives _WORD_TABLE[r ^ w]
# (16 input bits shift the whole register out). The CRC is linear, so entry (h << 8) | l is
# the entry for h << 8 xor _CRC_TABLE[l]. Built on first use, not at import (it takes
# milliseconds). An array (128 KiB), not a list of int objects (2.3 MiB, more than a core's
# L2 cache): nearly as fast in a tight loop, and without the cache misses once a cycle's
# other work evicts it.
_WORD_TABLE: Final = array("H")
_WORD_UNPACKERS: dict[int, Callable[..., tuple[int, ...]]] = {}
"""``unpack_from`` of n big-endian 16-bit words, by n (each made once)."""
_CACHED_UNPACKERS: Final = 2048
"""Word counts beyond this (packets over 4 KiB) get a fresh unpacker: the cache stays small."""


def _word_unpacker(words: int) -> Callable[..., tuple[int, ...]]:
    """Make (and cache) the unpacker of ``words`` words; builds the word table on first use.

    Every CRC goes through an unpacker, and one is cached only once the table is whole, so the
    hot paths need no check of their own (a rebuild by two threads at once is harmless).
    """
    if not _WORD_TABLE:
        row = [((t & 0xFF) << 8) ^ _CRC_TABLE[t >> 8] for t in _CRC_TABLE]
        _WORD_TABLE[:] = array("H", [high ^ low for high in row for low in _CRC_TABLE])
    unpack = struct.Struct(f">{words}H").unpack_from
    if words <= _CACHED_UNPACKERS:
        _WORD_UNPACKERS[words] = unpack
    return unpack


def _crc_byte(crc: int, byte: int) -> int:
    return ((crc << 8) & 0xFFFF) ^ _CRC_TABLE[(crc >> 8) ^ byte]


_CRC_FF_FF_FD: Final = _crc_byte(_crc_byte(_crc_byte(0, 0xFF), 0xFF), 0xFD)
_CRC_HEADER: Final = _crc_byte(_CRC_FF_FF_FD, 0x00)
"""Running CRCs after ``FF FF FD`` and after the whole header: every packet starts so."""


def crc16_py(data: bytes | bytearray | memoryview, crc: int = 0) -> int:
    """CRC-16 (poly 0x8005) of ``data`` continuing from ``crc`` (16-bit); equals the SDK's
    ``updateCRC``, byte for byte its table loop, but two bytes per step. The pure-Python
    path of :func:`crc16`."""
    n = len(data)
    words = n >> 1
    unpack = _WORD_UNPACKERS.get(words) or _word_unpacker(words)
    table = _WORD_TABLE
    for word in unpack(data):
        crc = table[crc ^ word]
    if n & 1:
        crc = ((crc << 8) & 0xFFFF) ^ _CRC_TABLE[(crc >> 8) ^ data[n - 1]]
    return crc


def _packet_crc_py(packet: bytes | bytearray, end: int) -> int:
    """CRC of ``packet[:end]``, a packet that starts with :data:`HEADER`, copying nothing.

    Starts from the header's constant CRC after 3 or 4 of its bytes, whichever leaves
    whole words: no odd byte to finish with.
    """
    if end & 1:
        crc, at = _CRC_FF_FF_FD, 3
    else:
        crc, at = _CRC_HEADER, 4
    words = (end - at) >> 1
    unpack = _WORD_UNPACKERS.get(words) or _word_unpacker(words)
    table = _WORD_TABLE
    for word in unpack(packet, at):
        crc = table[crc ^ word]
    return crc


if wire.NATIVE is not None:  # the same CRC compiled (tests/bus/test_wire.py: equal)
    _crc_c: Callable[..., int] = wire.NATIVE.crc16

    def crc16(data: bytes | bytearray | memoryview, crc: int = 0) -> int:
        """CRC-16 (poly 0x8005) of ``data`` continuing from ``crc`` (16-bit): the SDK's
        ``updateCRC``, compiled (:mod:`whexar.bus.wire`; :func:`crc16_py` where it is not
        built)."""
        return _crc_c(data, crc)

    def _packet_crc(packet: bytes | bytearray, end: int) -> int:
        return _crc_c(memoryview(packet)[:end])

else:  # pragma: no cover — where the compiled path is not built
    crc16 = crc16_py
    _packet_crc = _packet_crc_py


def stuff(body: bytes | bytearray) -> bytes:
    """Instruction + parameters with an ``FD`` added after every ``FF FF FD``."""
    # Occurrences of FF FF FD cannot overlap (FD is not FF), so a plain replace
    # is exactly the e-manual's left-to-right rule.
    return bytes(body).replace(_STUFF_FROM, _STUFF_TO)


def unstuff(body: bytes | bytearray) -> bytes:
    """Undo :func:`stuff`: every ``FF FF FD FD`` becomes ``FF FF FD``."""
    return bytes(body).replace(_STUFF_TO, _STUFF_FROM)


# --------------------------------------------------------------------------- packets


@dataclass(frozen=True, slots=True)
class Packet:
    """One decoded packet; ``error`` is the ERR byte of a status packet, else ``None``.

    ``params`` never include the ERR byte, and are unstuffed (except in a fast
    status packet, which is never stuffed).
    """

    id: int
    instruction: int
    params: bytes
    error: int | None = None

    @property
    def is_status(self) -> bool:
        """Whether this is a status (reply) packet."""
        return self.instruction == _STATUS

    def encode(self) -> bytes:
        """The packet's bytes on the wire (a fast status packet cannot be re-encoded this way)."""
        if self.error is not None:
            return encode_status(self.id, self.error, self.params)
        return encode_instruction(self.id, self.instruction, self.params)


def _check_byte(name: str, value: int, hi: int = 0xFF) -> None:
    if not 0 <= value <= hi:
        raise UsageError(f"{name} = {value!r}: expected 0–{hi}")


_HEAD: Final = struct.Struct("<4sBH")
"""Header, ID and LEN of a packet."""
_CRC_BYTES: Final = struct.Struct("<H").pack


def _frame(packet_id: int, body: bytes) -> bytes:
    length = len(body) + 2
    if length > 0xFFFF:
        raise UsageError(f"packet body of {len(body)} bytes does not fit a 16-bit LEN")
    packet = _HEAD.pack(HEADER, packet_id, length) + body
    return packet + _CRC_BYTES(_packet_crc(packet, len(packet)))


def encode_instruction(id: int, instruction: int, params: bytes | bytearray = b"") -> bytes:
    """An instruction packet: stuffed, LEN after stuffing, CRC over the result."""
    _check_byte("id", id, BROADCAST_ID)
    _check_byte("instruction", instruction)
    if type(params) is not bytes:
        params = bytes(params)
    return _frame(id, (bytes((instruction,)) + params).replace(_STUFF_FROM, _STUFF_TO))


def encode_status(id: int, error: int, params: bytes | bytearray = b"") -> bytes:
    """A status packet from ``id`` with ERR byte ``error`` (stuffed, like an instruction)."""
    if not (0 <= id <= MAX_ID and 0 <= error <= 0xFF):  # one test on the emulator's hot path
        _check_byte("id", id, MAX_ID)
        _check_byte("error", error)
    if type(params) is not bytes:
        params = bytes(params)
    return _frame(id, (bytes((_STATUS, error)) + params).replace(_STUFF_FROM, _STUFF_TO))


def encode_fast_status(entries: Sequence[tuple[int, int, bytes]]) -> bytes:
    """The one Fast Sync/Bulk Read status packet for ``(error, id, data)`` per servo, in order.

    Not stuffed; after each servo's data comes the running CRC of every byte
    before it, header included (e-manual, Fast Sync Read example), so the
    last servo's CRC is the packet CRC.
    """
    if not entries:
        raise UsageError("a fast status packet needs at least one servo")
    length = 1 + sum(len(data) + 4 for _, _, data in entries)
    if length > 0xFFFF:
        raise UsageError(f"fast status of {length} bytes does not fit a 16-bit LEN")
    out = bytearray(HEADER)
    out += bytes((BROADCAST_ID, length & 0xFF, length >> 8, Instruction.STATUS))
    crc = crc16(out)
    for error, servo, data in entries:
        _check_byte("error", error)
        _check_byte("id", servo, MAX_ID)
        part = bytes((error, servo)) + bytes(data)
        crc = crc16(part, crc)
        out += part
        out += bytes((crc & 0xFF, crc >> 8))
        crc = crc16(out[-2:], crc)
    return bytes(out)


def fast_status_parts(entries: Sequence[tuple[int, int, bytes]]) -> list[bytes]:
    """:func:`encode_fast_status` cut where each servo's contribution ends.

    The first part holds the header; a servo that stays silent leaves a gap
    (an emulator drops its part, and the host sees a broken packet).
    """
    whole = encode_fast_status(entries)
    parts: list[bytes] = []
    start = 0
    end = 8
    for _, _, data in entries:
        end += len(data) + 4
        parts.append(whole[start:end])
        start = end
    return parts


# --------------------------------------------------------------------------- parameters


def _u16(value: int) -> bytes:
    _check_byte("16-bit value", value, 0xFFFF)
    return bytes((value & 0xFF, value >> 8))


def read_params(start: int, length: int) -> bytes:
    """Parameters of READ: start address and data length."""
    return _u16(start) + _u16(length)


def write_params(start: int, data: bytes) -> bytes:
    """Parameters of WRITE and REG_WRITE: start address, then the data."""
    return _u16(start) + bytes(data)


def sync_read_bytes(n: int, data_bytes: int, *, fast: bool = False) -> tuple[int, int]:
    """(request, response) bytes of a (Fast) Sync Read of ``data_bytes`` from ``n`` servos.

    Request 14 + N; response N·(11 + X) status packets, or one Fast Sync Read
    packet of 8 + N·(X + 4) (e-manual, Protocol 2.0; the notes' table).
    """
    response = 8 + n * (data_bytes + 4) if fast else n * (11 + data_bytes)
    return 14 + n, response


def sync_write_bytes(n: int, data_bytes: int) -> int:
    """Bytes of a Sync Write of ``data_bytes`` to each of ``n`` servos: 14 + N·(1 + X)."""
    return 14 + n * (1 + data_bytes)


def sync_read_params(start: int, length: int, ids: Iterable[int]) -> bytes:
    """Parameters of (Fast) SYNC_READ: start, length, then one ID per servo."""
    id_list = list(ids)
    for servo in id_list:
        _check_byte("id", servo, MAX_ID)
    return _u16(start) + _u16(length) + bytes(id_list)


def sync_write_params(start: int, length: int, data: Mapping[int, bytes]) -> bytes:
    """Parameters of SYNC_WRITE: start, length, then ID and ``length`` bytes per servo."""
    out = bytearray(_u16(start) + _u16(length))
    for servo, chunk in data.items():
        _check_byte("id", servo, MAX_ID)
        if len(chunk) != length:
            raise UsageError(f"sync write to ID {servo}: {len(chunk)} bytes, expected {length}")
        out.append(servo)
        out += chunk
    return bytes(out)


def bulk_read_params(entries: Iterable[tuple[int, int, int]]) -> bytes:
    """Parameters of (Fast) BULK_READ: ``(id, start, length)`` per servo."""
    out = bytearray()
    for servo, start, length in entries:
        _check_byte("id", servo, MAX_ID)
        out.append(servo)
        out += _u16(start) + _u16(length)
    return bytes(out)


def bulk_write_params(entries: Iterable[tuple[int, int, bytes]]) -> bytes:
    """Parameters of BULK_WRITE: ``(id, start, data)`` per servo."""
    out = bytearray()
    for servo, start, data in entries:
        _check_byte("id", servo, MAX_ID)
        out.append(servo)
        out += _u16(start) + _u16(len(data)) + bytes(data)
    return bytes(out)


def _word(params: bytes, at: int) -> int:
    return params[at] | (params[at + 1] << 8)


def parse_read_params(params: bytes) -> tuple[int, int]:
    """``(start, length)`` of READ parameters; :class:`PacketError` unless 4 bytes."""
    if len(params) != 4:
        raise PacketError(f"READ needs 4 parameter bytes, got {len(params)}")
    return _word(params, 0), _word(params, 2)


def parse_write_params(params: bytes) -> tuple[int, bytes]:
    """``(start, data)`` of WRITE/REG_WRITE parameters."""
    if len(params) < 3:
        raise PacketError(f"WRITE needs an address and data, got {len(params)} bytes")
    return _word(params, 0), params[2:]


def parse_sync_read_params(params: bytes) -> tuple[int, int, list[int]]:
    """``(start, length, ids)`` of (Fast) SYNC_READ parameters."""
    if len(params) < 5:
        raise PacketError(f"SYNC_READ needs start, length and an ID, got {len(params)} bytes")
    return _word(params, 0), _word(params, 2), list(params[4:])


def parse_sync_write_params(params: bytes) -> tuple[int, int, list[tuple[int, bytes]]]:
    """``(start, length, [(id, data)])`` of SYNC_WRITE parameters."""
    if len(params) < 4:
        raise PacketError(f"SYNC_WRITE needs start and length, got {len(params)} bytes")
    start, length = _word(params, 0), _word(params, 2)
    body = params[4:]
    step = length + 1
    if length == 0 or not body or len(body) % step:
        raise PacketError(f"SYNC_WRITE body of {len(body)} bytes is not whole (ID + {length})")
    return start, length, [(body[i], body[i + 1 : i + step]) for i in range(0, len(body), step)]


def parse_bulk_read_params(params: bytes) -> list[tuple[int, int, int]]:
    """``[(id, start, length)]`` of (Fast) BULK_READ parameters."""
    if not params or len(params) % 5:
        raise PacketError(f"BULK_READ needs 5 bytes per servo, got {len(params)}")
    return [
        (params[i], _word(params, i + 1), _word(params, i + 3)) for i in range(0, len(params), 5)
    ]


def parse_bulk_write_params(params: bytes) -> list[tuple[int, int, bytes]]:
    """``[(id, start, data)]`` of BULK_WRITE parameters."""
    out: list[tuple[int, int, bytes]] = []
    i = 0
    while i < len(params):
        if i + 5 > len(params):
            raise PacketError("BULK_WRITE entry cut short")
        length = _word(params, i + 3)
        end = i + 5 + length
        if end > len(params):
            raise PacketError(f"BULK_WRITE entry for ID {params[i]} cut short")
        out.append((params[i], _word(params, i + 1), params[i + 5 : end]))
        i = end
    if not out:
        raise PacketError("BULK_WRITE without entries")
    return out


def split_fast_status(packet: Packet, lengths: int | Sequence[int]) -> list[tuple[int, int, bytes]]:
    """``(error, id, data)`` per servo of a decoded fast status packet.

    ``lengths`` is the data length of every servo (Fast Sync Read) or one per
    servo in request order (Fast Bulk Read). The intermediate CRCs are
    skipped: the decoder has checked the packet CRC, which covers them.
    """
    if packet.error is None or packet.id != BROADCAST_ID:
        raise PacketError(f"not a fast status packet: ID {packet.id}, error {packet.error}")
    body = bytes((packet.error,)) + packet.params + b"\0\0"  # the stripped packet CRC
    if isinstance(lengths, int):
        if lengths < 0 or len(body) % (lengths + 4):
            raise PacketError(f"fast status of {len(body)} bytes is not whole for {lengths} each")
        sizes: Sequence[int] = [lengths] * (len(body) // (lengths + 4))
    else:
        sizes = lengths
    if sum(n + 4 for n in sizes) != len(body):
        raise PacketError(f"fast status of {len(body)} bytes does not match lengths {sizes}")
    out: list[tuple[int, int, bytes]] = []
    at = 0
    for n in sizes:
        out.append((body[at], body[at + 1], body[at + 2 : at + 2 + n]))
        at += n + 4
    return out


# --------------------------------------------------------------------------- decoder


class PacketDecoder:
    """Streaming Protocol 2.0 receiver: :meth:`feed` bytes, get complete, CRC-checked packets.

    Counters: ``garbage_bytes`` (skipped while hunting for a header),
    ``crc_errors`` (packets whose CRC did not match; their bytes are then
    rescanned for a header) and ``packets`` (returned).
    """

    def __init__(self, *, max_length: int = MAX_LENGTH) -> None:
        self.max_length = max_length
        self._buf = bytearray()
        self.garbage_bytes = 0
        self.crc_errors = 0
        self.packets = 0

    @property
    def pending(self) -> int:
        """Bytes kept for a packet not yet complete (or a header not yet whole)."""
        return len(self._buf)

    def reset(self) -> None:
        """Forget buffered bytes (counted as garbage), e.g. after an inter-byte timeout."""
        self.garbage_bytes += len(self._buf)
        self._buf.clear()

    def feed(self, data: bytes | bytearray | memoryview) -> list[Packet]:
        """Add ``data`` and return every packet it completes, in order."""
        buf = self._buf
        buf += data
        out: list[Packet] = []
        while buf:
            at = buf.find(HEADER)
            if at < 0:
                # Keep a possible partial header at the end.
                keep = 0
                for k in (3, 2, 1):
                    if len(buf) >= k and buf.endswith(HEADER[:k]):
                        keep = k
                        break
                self.garbage_bytes += len(buf) - keep
                del buf[: len(buf) - keep]
                return out
            if at:
                self.garbage_bytes += at
                del buf[:at]
            if len(buf) < 7:
                return out
            packet_id = buf[4]
            length = buf[5] | (buf[6] << 8)
            if packet_id in (0xFD, 0xFF) or length < 3 or length > self.max_length:
                self.garbage_bytes += 1
                del buf[:1]
                continue
            total = 7 + length
            if len(buf) < total:
                return out
            if _packet_crc(buf, total - 2) != buf[total - 2] | (buf[total - 1] << 8):
                self.crc_errors += 1
                self.garbage_bytes += 1
                del buf[:1]
                continue
            body = bytes(buf[7 : total - 2])
            del buf[:total]
            instruction = body[0]
            if instruction == _STATUS:
                if len(body) < 2:
                    self.garbage_bytes += total
                    continue
                if packet_id != BROADCAST_ID:  # a fast status packet is not stuffed
                    body = body.replace(_STUFF_TO, _STUFF_FROM)
                packet = Packet(packet_id, instruction, body[2:], body[1])
            else:
                body = body.replace(_STUFF_TO, _STUFF_FROM)
                packet = Packet(packet_id, instruction, body[1:])
            self.packets += 1
            out.append(packet)
        return out
