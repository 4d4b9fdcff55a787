"""The sensor board's text frames: a sans-IO decoder and an encoder.

Theory of operation
-------------------
The ATmega2560 board sends ``key=value`` fields separated by ``;`` and
terminated by ``#`` (Žák 2023, 5.4), extended with ``seq`` first and a
CRC-16 ``crc`` last (``firmware/PROTOCOL.md`` is the grammar). Bytes go in
through :meth:`FrameDecoder.feed`, decoded :class:`Frame` and
:class:`Rejected` items come out; no I/O and no clock inside.

A frame is the bytes since the previous ``#``. Resynchronisation needs no
state machine: if those bytes contain ``seq=``, the frame starts at the last
``seq=`` and whatever precedes it is garbage (a frame whose ``#`` was lost,
or the tail of one cut off when the port opened). So a frame that arrives
intact after any corruption is always recovered, and a corrupted frame is
never published: in ``checked`` mode every frame must carry a sequence
number and a correct checksum; in ``thesis`` mode a frame may carry neither,
but one that carries ``seq`` must carry its checksum too (``seq`` only ever
comes with ``crc``, so a ``seq`` without one is a checked frame cut short by
a lost byte or a corrupted ``#``, whose missing groups would otherwise pass
unnoticed); and every frame, checked or not, must match the grammar, have
complete groups and in-range values.

Bytes without a ``#`` are kept up to :data:`MAX_FRAME_BYTES`; older ones are
dropped as garbage, so memory stays bounded whatever arrives. A port opened
while the board was sending starts in the middle of a frame: that tail, up
to the first ``#``, is dropped quietly when the reader says so
(:meth:`FrameDecoder.clear` with ``tail_expected``).
"""

from __future__ import annotations

import binascii
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Final, Literal, cast

from whexar.kinematics.sensing import ADC_MAX

Mode = Literal["checked", "thesis"]

TERMINATOR: Final = b"#"
"""Ends every frame (5.4)."""
MAX_FRAME_BYTES: Final = 192
"""Longest frame before its ``#`` (PROTOCOL.md "Limits"); a full checked frame is ~125."""
SEQ_MODULO: Final = 1 << 16
"""``seq`` counts 0 … 65535 and wraps (PROTOCOL.md)."""
CRC_INIT: Final = 0xFFFF
"""CRC-16/CCITT-FALSE: polynomial 0x1021, initial value 0xFFFF (``binascii.crc_hqx``)."""

IR_KEYS: Final = ("ir1", "ir2")
ACC_KEYS: Final = ("accx", "accy", "accz")
FSR_KEYS: Final = ("fsr0", "fsr1", "fsr2", "fsr3", "fsr4", "fsr5")
_SLOTS: Final = {key.encode(): i for i, key in enumerate(("seq", *IR_KEYS, *ACC_KEYS, *FSR_KEYS))}
_IGNORED: Final = b" \t\r\n\x00"
"""Bytes allowed between frames (a terminal user's newline, a NUL at a board reset)."""
_BODY: Final = re.compile(rb"[a-z][a-z0-9]*=-?[0-9]{1,5}(?:;[a-z][a-z0-9]*=-?[0-9]{1,5})*")
_CRC_TEXT: Final = re.compile(rb"[0-9A-F]{4}")
_SEQ: Final = b"seq="
_IR1: Final = b"ir1="
_CRC: Final = b";crc="


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE of ``data`` (check value 0x29B1 for ``b"123456789"``)."""
    return binascii.crc_hqx(data, CRC_INIT)


@dataclass(frozen=True, slots=True)
class Frame:
    """A decoded frame: raw ADC counts per group (``None`` when absent).

    ``checked``: it carried a correct ``crc``. ``missed``: frames lost just
    before it, by its sequence number; ``restarted``: its ``seq`` shows the
    board reset (0 unexpectedly, or a jump backwards).
    """

    seq: int | None
    ir: tuple[int, int] | None
    acc: tuple[int, int, int] | None
    fsr: tuple[int, int, int, int, int, int] | None
    checked: bool
    unknown_keys: int = 0
    missed: int = 0
    restarted: bool = False
    expected_seq: int | None = None


@dataclass(frozen=True, slots=True)
class Rejected:
    """Bytes that were discarded: why, how many, and how they began."""

    reason: str
    size: int
    excerpt: str


@dataclass(slots=True)
class DecoderStats:
    """Counters since the decoder was made."""

    frames: int = 0
    rejected: int = 0
    missed: int = 0
    restarts: int = 0
    unknown_keys: int = 0
    garbage_bytes: int = 0


def _excerpt(data: bytes, limit: int = 32) -> str:
    shown = data[:limit].decode("ascii", "backslashreplace")
    shown = shown.encode("unicode_escape").decode("ascii")
    return shown + ("…" if len(data) > limit else "")


class FrameError(ValueError):
    """Why a candidate frame is not a frame (internal: becomes a :class:`Rejected`)."""


@dataclass(slots=True)
class FrameDecoder:
    """Turns the board's byte stream into frames; see the module docstring.

    ``mode`` is ``sensor_board.protocol``: ``checked`` requires ``seq`` and
    ``crc``; ``thesis`` accepts the plain frame of 5.4 too (a ``crc`` that is
    present is verified, and a ``seq`` needs one).
    """

    mode: Mode = "checked"
    stats: DecoderStats = field(default_factory=DecoderStats)
    _buf: bytearray = field(default_factory=bytearray)
    _last_seq: int | None = None
    _overflowed: int = 0
    _tail_expected: bool = False

    def reset_sequence(self) -> None:
        """Forget the last sequence number (a new connection: the first frame has no gap)."""
        self._last_seq = None

    def clear(self, *, tail_expected: bool = False) -> None:
        """Drop any partial frame (the port was closed); counters are kept.

        ``tail_expected``: a port was just opened on a board that may be
        sending already (a USB adapter without the Mega's reset, a pty), so
        the bytes up to its first ``#`` may be the tail of a frame on its way.
        If they are not a frame they are dropped quietly (counted as garbage
        bytes), not reported as a rejected frame; everything after them is.
        """
        self._buf.clear()
        self._overflowed = 0
        self._last_seq = None
        self._tail_expected = tail_expected

    def feed(self, data: bytes) -> list[Frame | Rejected]:
        """Decode every frame that ``data`` completes, in order."""
        buf = self._buf
        buf += data
        out: list[Frame | Rejected] = []
        start = 0
        while (end := buf.find(TERMINATOR, start)) >= 0:
            candidate = bytes(buf[start:end])
            start = end + 1
            if self._overflowed:
                dropped, self._overflowed = self._overflowed, 0
                out.append(self._reject(f"no '#' within {MAX_FRAME_BYTES} bytes", dropped, b""))
            self._candidate(candidate, out)
        if start:
            del buf[:start]
        if len(buf) > MAX_FRAME_BYTES:
            # No terminator in sight: keep the newest bytes, which may yet
            # begin a frame, and drop the rest as garbage.
            excess = len(buf) - MAX_FRAME_BYTES
            del buf[:excess]
            self._overflowed += excess
            self.stats.garbage_bytes += excess
        return out

    # ------------------------------------------------------------------ parsing

    def _candidate(self, data: bytes, out: list[Frame | Rejected]) -> None:
        if self._tail_expected and data.strip(_IGNORED):
            # The first bytes since the port opened: if they hold no frame, they
            # are the tail of one cut off by the opening; drop them quietly.
            self._tail_expected = False
            found: list[Frame | Rejected] = []
            self._decode(data, found)
            if any(isinstance(item, Frame) for item in found):
                out.extend(found)
            else:
                self.stats.rejected -= len(found)  # garbage bytes, not rejected frames
            return
        self._decode(data, out)

    def _decode(self, data: bytes, out: list[Frame | Rejected]) -> None:
        begin = data.rfind(_SEQ)
        if begin < 0 and self.mode == "thesis":
            begin = data.rfind(_IR1)  # a plain thesis frame has no seq; it begins with ir1 (5.4)
        if begin > 0:
            head = data[:begin]
            if head.strip(_IGNORED):
                out.append(self._reject("garbage before a frame (a lost '#'?)", begin, head))
            data = data[begin:]
        elif begin < 0:
            data = data.lstrip(_IGNORED)
            if not data:
                return
        try:
            frame = self._parse(data)
        except FrameError as error:
            out.append(self._reject(str(error), len(data) + 1, data))
            return
        out.append(frame)

    def _reject(self, reason: str, size: int, data: bytes) -> Rejected:
        self.stats.rejected += 1
        self.stats.garbage_bytes += size
        return Rejected(reason, size, _excerpt(data))

    def _parse(self, data: bytes) -> Frame:
        if len(data) > MAX_FRAME_BYTES:
            raise FrameError(f"{len(data)} bytes, longer than {MAX_FRAME_BYTES}")
        body = data
        checked = False
        at = data.rfind(_CRC)
        if at >= 0:
            text = data[at + len(_CRC) :]
            if not _CRC_TEXT.fullmatch(text):
                raise FrameError("malformed checksum (4 upper-case hex digits expected)")
            if int(text, 16) != crc16(data[: at + 1]):
                raise FrameError("checksum mismatch")
            body = data[:at]
            checked = True
        elif self.mode == "checked":
            raise FrameError("no checksum (sensor_board.protocol is 'checked')")
        if not _BODY.fullmatch(body):
            raise FrameError("not key=value fields separated by ';'")
        values: list[int | None] = [None] * 12
        unknown = 0
        for item in body.split(b";"):
            key, _, text = item.partition(b"=")
            slot = _SLOTS.get(key)
            if slot is None:
                unknown += 1
                continue
            if values[slot] is not None:
                raise FrameError(f"key {key.decode()!r} repeated")
            value = int(text)
            if slot == 0:
                if not 0 <= value < SEQ_MODULO:
                    raise FrameError(f"seq = {value} out of range 0…{SEQ_MODULO - 1}")
            elif not 0 <= value <= ADC_MAX:
                raise FrameError(f"{key.decode()} = {value} out of range 0…{ADC_MAX}")
            values[slot] = value
        seq = values[0]
        if seq is None and self.mode == "checked":
            raise FrameError("no sequence number (sensor_board.protocol is 'checked')")
        if seq is not None and not checked:
            # Only a checked frame carries seq (PROTOCOL.md), so this is one whose
            # tail was lost: a byte turned '#' mid-frame, or the line cut out.
            raise FrameError("seq but no checksum (a checked frame cut short?)")
        ir = cast("tuple[int, int] | None", _group(values, 1, 3, IR_KEYS))
        acc = cast("tuple[int, int, int] | None", _group(values, 3, 6, ACC_KEYS))
        fsr = cast("tuple[int, int, int, int, int, int] | None", _group(values, 6, 12, FSR_KEYS))
        if ir is None and acc is None and fsr is None:
            raise FrameError("no sensor values (no ir, acc or fsr group)")
        missed, restarted, expected = self._sequence(seq)
        stats = self.stats
        stats.frames += 1
        stats.unknown_keys += unknown
        stats.missed += missed
        stats.restarts += restarted
        return Frame(seq, ir, acc, fsr, checked, unknown, missed, restarted, expected)

    def _sequence(self, seq: int | None) -> tuple[int, bool, int | None]:
        if seq is None:
            return 0, False, None
        last, self._last_seq = self._last_seq, seq
        if last is None:
            return 0, False, None
        expected = (last + 1) % SEQ_MODULO
        if seq == expected:
            return 0, False, expected
        jump = (seq - expected) % SEQ_MODULO
        if seq == 0 or jump >= SEQ_MODULO // 2:
            return 0, True, expected
        return jump, False, expected


def _group(
    values: list[int | None], lo: int, hi: int, keys: tuple[str, ...]
) -> tuple[int, ...] | None:
    part = values[lo:hi]
    present = [v for v in part if v is not None]
    if not present:
        return None
    if len(present) != len(part):
        missing = [k for k, v in zip(keys, part, strict=True) if v is None]
        raise FrameError(f"incomplete group: {', '.join(missing)} missing")
    return tuple(present)


def encode_frame(
    *,
    seq: int | None = None,
    ir: Iterable[int] | None = None,
    acc: Iterable[int] | None = None,
    fsr: Iterable[int] | None = None,
    extra: Iterable[tuple[str, int]] = (),
    checksum: bool = True,
) -> bytes:
    """A frame as the firmware writes it: ``seq``, ir, acc, fsr, extras, then ``crc``.

    Groups given as ``None`` are left out; ``checksum=False`` with ``seq=None``
    gives the plain thesis frame of 5.4. Values are not range-checked here,
    so tests can build bad frames on purpose.
    """
    parts: list[str] = []
    if seq is not None:
        parts.append(f"seq={seq}")
    for keys, group in ((IR_KEYS, ir), (ACC_KEYS, acc), (FSR_KEYS, fsr)):
        if group is not None:
            parts.extend(f"{k}={v}" for k, v in zip(keys, group, strict=True))
    parts.extend(f"{k}={v}" for k, v in extra)
    text = ";".join(parts).encode("ascii")
    if not checksum:
        return text + TERMINATOR
    covered = text + b";"
    return covered + b"crc=%04X" % crc16(covered) + TERMINATOR


__all__ = [
    "MAX_FRAME_BYTES",
    "DecoderStats",
    "Frame",
    "FrameDecoder",
    "Mode",
    "Rejected",
    "crc16",
    "encode_frame",
]
