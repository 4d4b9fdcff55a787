"""Reading a recording back: metadata, attachments and every record in log-time order,
also from a file that was cut short.

Theory of operation
-------------------
Opening a :class:`Recording` walks the file's top-level MCAP records once, reading
only their headers: a chunk's header holds its time range, and its compressed body is
skipped, so opening costs one seek per chunk. The walk notes the
metadata, the attachments, where each chunk lies, and where the readable part ends:
at the footer for a complete file, else at the first record that is cut off or
malformed. A process killed with SIGKILL leaves no footer, and perhaps a last record
half written; a copy cut anywhere looks the same. The ``mcap`` package's own readers
either read the summary first (and find nothing) or raise at the cut; this one keeps
what is whole and says where it stopped (:class:`Damage`).

:meth:`Recording.records` then decompresses the chunks in file order, so a channel's
definition always comes before its messages, and yields messages in log-time order
through a heap: a message leaves the heap once no later chunk can hold an earlier one
(every chunk's start time is known from the walk; MCAP's indexed readers merge the same
way). Memory holds the chunks whose time ranges overlap, not the file. A chunk that
does not decompress or fails its CRC ends the readable part there; everything before
it is still yielded, in order.

Values: a whexar message comes back as the same typed message
(:mod:`whexar.record.encoding`), device-link bytes as
:class:`~whexar.record.encoding.LinkBytes`, other JSON (Foxglove's views) as a dict,
anything else as bytes. :meth:`Recording.check_compatible` refuses a recording of
another whexar major.minor version, whose message types may differ.
"""

from __future__ import annotations

import heapq
import io
import os
import struct
import zlib
from collections.abc import Callable, Collection, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, Final

import lz4.frame  # type: ignore[import-untyped]  # no type hints
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Attachment as McapAttachment
from mcap.records import Channel, Chunk, Footer, Header, Metadata, Schema
from mcap.records import Message as McapMessage
from mcap.stream_reader import CRCValidationError, breakup_chunk
from mcap.writer import CompressionType, Writer

from whexar import __version__
from whexar.record.encoding import (
    LINK_SCHEMA_NAME,
    EncodingError,
    RecordingError,
    codec_by_name,
    decode_link,
    loads,
)
from whexar.runtime.messages import MESSAGE_TYPES, Message

__all__ = [
    "Attachment",
    "Damage",
    "Record",
    "Recording",
    "RecoveryReport",
    "recover",
]

MAGIC: Final = b"\x89MCAP0\r\n"
_HEAD = struct.Struct("<BQ")
_CHANNEL_ID = struct.Struct("<H")  # the start of a Message Index record
_CHUNK_HEAD = struct.Struct("<QQQII")  # start, end, uncompressed size, crc, len(compression)
_FOOTER_SIZE = 9 + 20  # opcode, length; summary start, summary offset start, crc


@dataclass(frozen=True, slots=True)
class Record:
    """One message of a recording."""

    topic: str
    """The MCAP topic: ``/{channel}`` for a runtime channel, ``/links/{link}``, ``/log`` …"""
    schema: str
    """The schema name: a message's class name, ``whexar.LinkBytes``, ``foxglove.Log`` …"""
    log_time: int
    """Log time in ns (a runtime message's ``t`` × 1e9)."""
    value: Any
    """The typed message, :class:`~whexar.record.encoding.LinkBytes`, a dict for other
    JSON, the bytes otherwise; ``None`` when read with ``decode=False``."""
    data: bytes = field(repr=False)
    """The message's bytes as recorded."""

    @property
    def t(self) -> float:
        """Log time in seconds."""
        return self.log_time / 1e9

    @property
    def channel(self) -> str | None:
        """The runtime channel of a whexar message, else ``None``."""
        return self.topic[1:] if isinstance(self.value, Message) else None


@dataclass(frozen=True, slots=True)
class Attachment:
    """A file stored in the recording (configuration, wiring …)."""

    name: str
    media_type: str
    data: bytes = field(repr=False)

    @property
    def text(self) -> str:
        """The content as UTF-8 text."""
        return self.data.decode("utf-8", errors="replace")


@dataclass(frozen=True, slots=True)
class Damage:
    """Where the readable part of an incomplete recording ends, and why."""

    offset: int
    """Bytes readable from the start of the file (the rest is lost)."""
    size: int
    """The file's size."""
    last_ns: int | None
    """Log time of the last readable message, ``None`` if none is readable."""
    reason: str

    def describe(self, path: str | os.PathLike[str]) -> str:
        """One clear sentence: where the recording ends and why."""
        pct = 100.0 * self.offset / self.size if self.size else 0.0
        last = (
            "no message is readable"
            if self.last_ns is None
            else f"the last message at t = {self.last_ns / 1e9:.3f} s"
        )
        return (
            f"{path}: the recording ends early: readable up to byte {self.offset:,} of "
            f"{self.size:,} ({pct:.1f} %), {last}; {self.reason}"
        )


@dataclass(slots=True)
class _Unit:
    """What the walk found in the data section, in file order: a chunk to decompress,
    or a bare schema, channel or message record."""

    offset: int
    length: int
    start: int
    end: int
    record: Schema | Channel | McapMessage | None = None
    """A bare record; ``None`` for a chunk (read again when iterated)."""
    channels: set[int] | None = None
    """A chunk's channel ids, from the Message Index records after it (``None``: none
    seen, as where a file was cut): a chunk that holds none wanted is not read."""


@dataclass(slots=True)
class _Channel:
    topic: str
    schema: str
    decode: Callable[[bytes], Any]


class Recording:
    """An MCAP recording opened for reading (see the module docstring).

    Raises :class:`~whexar.record.encoding.RecordingError` for a file that cannot be
    opened or is not MCAP at all. A file cut short opens; :attr:`damage` says where its
    readable part ends.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        try:
            self.size = self.path.stat().st_size
            with open(self.path, "rb") as f:
                magic = f.read(len(MAGIC))
        except OSError as exc:
            raise RecordingError(f"cannot read {self.path}: {exc.strerror or exc}") from None
        if magic != MAGIC:
            what = "empty" if not magic else "not an MCAP file"
            raise RecordingError(f"{self.path} is {what} (no MCAP magic at its start)")
        self.library = ""
        """The writer named in the MCAP header."""
        self.metadata: dict[str, dict[str, str]] = {}
        """MCAP metadata records by name: ``whexar``, ``run``, ``whexar.end`` …"""
        self.attachments: dict[str, Attachment] = {}
        self.complete = False
        """The file ends with MCAP's footer: it was closed properly."""
        self.damage: Damage | None = None
        """Where the readable part ends, for a file that was cut short or is damaged."""
        self._units: list[_Unit] = []
        self._top_schemas: set[int] = set()
        self._top_channels: set[int] = set()
        self._skippable = True
        """No chunk defines a channel a message needs: every channel with messages, and
        its schema, is a record of its own before the chunks that use it (whexar's
        writer); a chunk none of whose channels is wanted can then be left unread."""
        self._compressions: set[str] = set()
        self._walk()

    # ------------------------------------------------------------------ the walk

    def _walk(self) -> None:
        size = self.size
        pos = len(MAGIC)
        last_ns: int | None = None
        with open(self.path, "rb") as f:
            f.seek(pos)
            in_data = True
            while True:
                head = f.read(_HEAD.size)
                if not head:
                    self._damaged(pos, last_ns, _NO_FOOTER if in_data else _NO_SUMMARY_END)
                    return
                if len(head) < _HEAD.size:
                    self._damaged(pos, last_ns, "the last record is cut off in its header")
                    return
                opcode, length = _HEAD.unpack(head)
                end = pos + _HEAD.size + length
                name = _opcode_name(opcode)
                if opcode not in _OPCODES and (opcode < _PRIVATE or "whexar" in self.metadata):
                    # No MCAP record starts with this byte (0x80 on are private records,
                    # which whexar never writes): not a cut, the bytes are wrong.
                    self._damaged(
                        pos, last_ns, f"no record starts here (opcode {opcode:#04x}): corrupted"
                    )
                    return
                if end > size:
                    have = size - pos - _HEAD.size
                    why = (
                        "the file was not closed (a killed process, a full disk) or was "
                        "copied while recording"
                        if in_data
                        else "only the index after the data is lost: every message is readable"
                    )
                    self._damaged(
                        pos,
                        last_ns,
                        f"a {name} record is cut off ({have:,} of its {length:,} bytes are "
                        f"there): {why}",
                    )
                    return
                try:
                    if opcode == Opcode.CHUNK and in_data:
                        start, stop, _, _, n = _CHUNK_HEAD.unpack(f.read(_CHUNK_HEAD.size))
                        self._compressions.add(f.read(n).decode("utf-8"))
                        self._units.append(_Unit(pos, end - pos, start, stop))
                        last_ns = stop if last_ns is None else max(last_ns, stop)
                    elif opcode == Opcode.FOOTER:
                        Footer.read(_stream(f.read(length)))
                        self.complete = f.read(len(MAGIC)) == MAGIC
                        if not self.complete:
                            self._damaged(end, last_ns, "the footer is not followed by MCAP magic")
                        return
                    elif opcode == Opcode.MESSAGE_INDEX and in_data and self._units:
                        chunk = self._units[-1]
                        if chunk.record is None and end - pos >= _HEAD.size + 2:
                            (channel_id,) = _CHANNEL_ID.unpack(f.read(2))
                            if chunk.channels is None:
                                chunk.channels = set()
                            chunk.channels.add(channel_id)
                            if channel_id not in self._top_channels:
                                self._skippable = False  # defined in a chunk
                    elif opcode == Opcode.DATA_END:
                        in_data = False  # the summary follows: it repeats what we have
                    elif in_data and opcode in _READ:
                        record = _READ[opcode](f.read(length))
                        last_ns = self._note(record, pos, end - pos, last_ns)
                except (McapError, struct.error, UnicodeDecodeError, ValueError) as exc:
                    self._damaged(pos, last_ns, f"a {name} record is malformed ({exc})")
                    return
                pos = end
                f.seek(pos)

    def _note(self, record: Any, offset: int, length: int, last_ns: int | None) -> int | None:
        if isinstance(record, Header):
            self.library = record.library
        elif isinstance(record, Metadata):
            self.metadata[record.name] = dict(record.metadata)
        elif isinstance(record, McapAttachment):
            self.attachments[record.name] = Attachment(
                record.name, record.media_type, bytes(record.data)
            )
        elif isinstance(record, McapMessage):
            t = record.log_time
            self._units.append(_Unit(offset, length, t, t, record))
            return t if last_ns is None else max(last_ns, t)
        elif isinstance(record, Schema):
            self._top_schemas.add(record.id)
            self._units.append(_Unit(offset, length, _NEVER, _NEVER, record))
        elif isinstance(record, Channel):
            self._top_channels.add(record.id)
            if record.schema_id != 0 and record.schema_id not in self._top_schemas:
                self._skippable = False  # its schema is defined in a chunk
            self._units.append(_Unit(offset, length, _NEVER, _NEVER, record))
        return last_ns

    def _damaged(self, offset: int, last_ns: int | None, reason: str) -> None:
        self.damage = Damage(offset, self.size, last_ns, reason)
        if self._units and self._units[-1].record is None:
            self._units[-1].channels = None  # its indexes may be cut: it is read

    # ------------------------------------------------------------------ what it holds

    @property
    def version(self) -> str | None:
        """The whexar version that recorded the file (``None``: not a whexar recording)."""
        return self.metadata.get("whexar", {}).get("version")

    @property
    def last_ns(self) -> int | None:
        """Log time (ns) of the last readable message, from the chunks' headers (no
        chunk is decompressed); ``None`` with none."""
        return max((u.end for u in self._units if u.end != _NEVER), default=None)

    @property
    def compression(self) -> str:
        """The chunks' compression (``zstd``, ``lz4``, ``""`` for none)."""
        return sorted(self._compressions)[0] if self._compressions else ""

    def check_compatible(self, version: str = __version__) -> None:
        """Raise :class:`RecordingError` unless a whexar of ``version``'s major.minor
        recorded this file: other versions may have other message types."""
        recorded = self.version
        if recorded is None:
            raise RecordingError(
                f"{self.path} is not a whexar recording (it has no 'whexar' metadata; "
                f"written by {self.library or 'an unknown writer'})"
            )
        if _major_minor(recorded) != _major_minor(version):
            raise RecordingError(
                f"{self.path} was recorded by whexar {recorded}; this is whexar {version}. "
                "Recordings are read by the same major.minor version (message types may "
                f"have changed): use whexar {'.'.join(_major_minor(recorded))}.x to read it"
            )

    def describe_end(self) -> str:
        """``complete`` or where and why the readable part ends."""
        if self.damage is not None:
            return self.damage.describe(self.path)
        return f"{self.path}: complete"

    # ------------------------------------------------------------------ records

    def records(
        self,
        topics: Collection[str] | None = None,
        *,
        decode: bool = True,
        file_order: bool = False,
    ) -> Iterator[Record]:
        """Every readable message (of ``topics``, if given), in log-time order.

        Messages with equal log times come in the order they were written;
        ``file_order`` yields every message in the order it was written instead (the
        order the runtime published them: an actor may stamp a message earlier than one
        published before it). If a chunk
        turns out damaged, iteration ends after everything before it and
        :attr:`damage` says where. Raises :class:`RecordingError` for a message that
        does not fit its type (a recording of another version: see
        :meth:`check_compatible`).
        """
        units = self._units
        # Earliest start of any unit from i on: what may still come before a message.
        later = [_NEVER] * (len(units) + 1)
        for i in range(len(units) - 1, -1, -1):
            later[i] = min(units[i].start, later[i + 1])
        schemas: dict[int, Schema] = {}
        channels: dict[int, _Channel | None] = {}
        heap: list[tuple[int, int, int, bytes]] = []
        seq = 0
        wanted = None if topics is None else set(topics)
        # Messages of channels not wanted are skipped in the chunk, unread.
        keep: dict[int, bool] = {}
        for i, records in self._readable(keep, wanted):
            for record in records:
                if type(record) is tuple:
                    item = (record[0], seq, record[1], record[2])
                    seq += 1
                    if file_order:
                        made = self._made(item, channels, decode)
                        if made is not None:
                            yield made
                        continue
                    heapq.heappush(heap, item)
                elif isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.id] = self._channel(record, schemas, wanted, decode)
            bound = later[i + 1]
            while heap and heap[0][0] <= bound:
                made = self._made(heapq.heappop(heap), channels, decode)
                if made is not None:
                    yield made
        while heap:
            made = self._made(heapq.heappop(heap), channels, decode)
            if made is not None:
                yield made

    def _readable(
        self, keep: dict[int, bool] | None = None, wanted: set[str] | None = None
    ) -> Iterator[tuple[int, list[Any]]]:
        """Each unit's records (with its index), in file order, up to the first that
        cannot be read: that one ends the readable part (:attr:`damage`).

        With ``keep`` (channel id → wanted, filled as channels are read), messages come
        as ``(log_time, channel_id, data)`` tuples (:func:`_chunk_records`), only those
        of channels whose topic is in ``wanted`` (all with ``None``).
        """
        last_ns: int | None = None
        with open(self.path, "rb") as f:
            for i, unit in enumerate(self._units):
                try:
                    records = self._unit_records(f, unit, keep, wanted)
                except Exception as exc:  # zstd, lz4, CRC, struct: each has its own error
                    self._damaged(unit.offset, last_ns, f"a chunk cannot be read ({_why(exc)})")
                    return
                yield i, records
                last_ns = max(last_ns or 0, unit.end) if unit.end != _NEVER else last_ns

    def _unit_records(
        self,
        f: IO[bytes],
        unit: _Unit,
        keep: dict[int, bool] | None = None,
        wanted: set[str] | None = None,
    ) -> list[Any]:
        record = unit.record
        if record is not None:
            if keep is None:
                return [record]
            if isinstance(record, Channel):
                keep[record.id] = wanted is None or record.topic in wanted
            elif isinstance(record, McapMessage):  # as _chunk_records gives a message
                if not keep.get(record.channel_id, True):
                    return []
                return [(record.log_time, record.channel_id, record.data)]
            return [record]
        # A chunk none of whose channels is wanted is left unread (where no chunk
        # defines a channel: ``_skippable``).
        channels = unit.channels
        if (
            keep is not None
            and channels is not None
            and self._skippable
            and not any(keep.get(c, True) for c in channels)
        ):
            return []
        f.seek(unit.offset + _HEAD.size)
        body = f.read(unit.length - _HEAD.size)
        chunk = Chunk.read(_stream(body))
        if keep is None:
            return breakup_chunk(chunk, validate_crc=True)
        return _chunk_records(chunk, keep, wanted)

    def _channel(
        self,
        record: Channel,
        schemas: dict[int, Schema],
        wanted: set[str] | None,
        decode: bool,
    ) -> _Channel | None:
        if wanted is not None and record.topic not in wanted:
            return None
        schema = schemas.get(record.schema_id)
        name = schema.name if schema is not None else ""
        return _Channel(record.topic, name, _decoder(record, name) if decode else _raw)

    def _made(
        self,
        item: tuple[int, int, int, bytes],
        channels: dict[int, _Channel | None],
        decode: bool,
    ) -> Record | None:
        log_time, _, channel_id, data = item
        channel = channels.get(channel_id)
        if channel is None:
            return None  # not wanted, or a message of a channel never defined
        try:
            value = channel.decode(data) if decode else None
        except EncodingError as exc:
            raise RecordingError(
                f"{self.path}: a message on {channel.topic} at t = {log_time / 1e9:.6f} s: "
                f"{exc}. {self._version_hint()}"
            ) from None
        return Record(channel.topic, channel.schema, log_time, value, data)

    def _version_hint(self) -> str:
        recorded = self.version
        if recorded is not None and _major_minor(recorded) != _major_minor(__version__):
            return f"It was recorded by whexar {recorded}; this is {__version__}."
        return "The recording may be damaged."


_NEVER: Final = 2**64
"""A start time after every log time: units that hold no message."""
_NO_FOOTER = (
    "the file ends without MCAP's footer: the recording was not closed (the process "
    "was killed, or is still recording); `whexar log recover` makes it a complete file"
)

_NO_SUMMARY_END = "the index after the data ends early, but every message is readable"

_READ: dict[int, Callable[[bytes], Any]] = {
    Opcode.HEADER: lambda b: Header.read(_stream(b)),
    Opcode.METADATA: lambda b: Metadata.read(_stream(b)),
    Opcode.ATTACHMENT: lambda b: McapAttachment.read(_stream(b)),
    Opcode.SCHEMA: lambda b: Schema.read(_stream(b)),
    Opcode.CHANNEL: lambda b: Channel.read(_stream(b)),
    Opcode.MESSAGE: lambda b: McapMessage.read(_stream(b), len(b)),
}


_MESSAGE: Final = struct.Struct("<HIQ")
"""A Message record's start: channel id, sequence, log time; publish time (8) follows,
then the data (MCAP spec, "Message")."""
_MESSAGE_DATA: Final = _MESSAGE.size + 8


def _chunk_records(chunk: Chunk, keep: dict[int, bool], wanted: set[str] | None) -> list[Any]:
    """A chunk's records for :meth:`Recording.records`: schemas and channels as the
    ``mcap`` library reads them, each message of a kept channel as ``(log_time,
    channel_id, data)``, the others skipped unread.

    ``breakup_chunk`` builds a ``Message`` through a byte stream for every record, which
    costs more than everything else a replay does with the file; this walks the same
    records with ``struct`` (the same decompression and CRC check, from the library).
    """
    data = _decompressed(chunk)
    size = len(data)
    out: list[Any] = []
    head, message = _HEAD.unpack_from, _MESSAGE.unpack_from
    pos = 0
    while pos < size:
        opcode, length = head(data, pos)
        start = pos + _HEAD.size
        pos = start + length
        if pos > size:
            raise McapError(f"a record runs {pos - size} bytes past the end of its chunk")
        if opcode == Opcode.MESSAGE:
            if length < _MESSAGE_DATA:
                raise McapError(f"a message record of {length} bytes")
            channel_id, _, log_time = message(data, start)
            if keep.get(channel_id, True):  # a channel not read yet: _made drops it
                out.append((log_time, channel_id, data[start + _MESSAGE_DATA : pos]))
        elif opcode == Opcode.CHANNEL:
            channel = Channel.read(_stream(data[start:pos]))
            keep[channel.id] = wanted is None or channel.topic in wanted
            out.append(channel)
        elif opcode == Opcode.SCHEMA:
            out.append(Schema.read(_stream(data[start:pos])))
    return out


def _decompressed(chunk: Chunk) -> bytes:
    """A chunk's records, decompressed and checked against its CRC as
    ``mcap.stream_reader.get_chunk_data_stream`` does."""
    if chunk.compression == "zstd":
        data: bytes = zstandard.decompress(chunk.data, chunk.uncompressed_size)
    elif chunk.compression == "lz4":
        data = lz4.frame.decompress(chunk.data)
    elif chunk.compression == "":
        data = chunk.data
    else:
        raise McapError(f"unknown compression {chunk.compression!r}")
    crc = chunk.uncompressed_crc
    if crc != 0 and zlib.crc32(data) != crc:
        raise CRCValidationError(expected=crc, actual=zlib.crc32(data), record=chunk)
    return data


def _stream(data: bytes) -> ReadDataStream:
    return ReadDataStream(io.BytesIO(data))


_OPCODES: Final = frozenset(int(op) for op in Opcode)
_PRIVATE: Final = 0x80
"""Opcodes 0x80 to 0xFF are reserved for private records (MCAP spec, "Records")."""


def _opcode_name(opcode: int) -> str:
    try:
        return Opcode(opcode).name.lower().replace("_", " ")
    except ValueError:
        return f"private (opcode {opcode:#04x})"


def _why(exc: BaseException) -> str:
    text = str(exc)
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _major_minor(version: str) -> tuple[str, ...]:
    return tuple(version.split(".")[:2])


def _raw(data: bytes) -> Any:
    return None


def _decoder(channel: Channel, schema: str) -> Callable[[bytes], Any]:
    """How to turn a channel's bytes into values (see the module docstring)."""
    link = channel.metadata.get("whexar.link")
    if schema == LINK_SCHEMA_NAME and link is not None:
        return lambda data: decode_link(link, data)
    path = channel.metadata.get("whexar.type")
    if channel.message_encoding == "json" and (path is not None or schema in MESSAGE_TYPES):
        try:
            known = codec_by_name(schema, path)
        except EncodingError:
            pass  # a type this whexar does not have: read as plain JSON
        else:
            return known.decode
    if channel.message_encoding == "json":
        return _json
    return bytes


def _json(data: bytes) -> Any:
    return loads(data, "JSON message")


# --------------------------------------------------------------------------- recover


@dataclass(frozen=True, slots=True)
class RecoveryReport:
    """What :func:`recover` saved."""

    source: Path
    output: Path
    messages: int
    first_ns: int | None
    last_ns: int | None
    readable_bytes: int
    size: int
    damage: Damage | None

    def describe(self) -> str:
        """What was saved, in one paragraph."""
        if self.first_ns is None or self.last_ns is None:
            span = "no message"
        else:
            span = (
                f"t = {self.first_ns / 1e9:.3f} … {self.last_ns / 1e9:.3f} s "
                f"({(self.last_ns - self.first_ns) / 1e9:.3f} s)"
            )
        lost = self.size - self.readable_bytes
        return (
            f"recovered {self.messages:,} messages ({span}) from {self.source} into "
            f"{self.output}: {self.readable_bytes:,} of {self.size:,} bytes were readable, "
            f"{lost:,} lost"
        )


_WRITE_COMPRESSION = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4}


def recover(source: str | os.PathLike[str], output: str | os.PathLike[str]) -> RecoveryReport:
    """Rewrite the readable part of ``source`` as a complete MCAP file ``output``.

    Metadata, attachments, schemas, channels and every readable message are copied
    (messages in file order, with their times), with the same compression; a metadata
    record ``whexar.recovered`` says from what. Works on a complete file too (a copy).
    """
    recording = Recording(source)
    out = Path(output)
    if out.resolve() == recording.path.resolve():
        raise RecordingError(f"recover {recording.path}: the output must be another file")
    compression = _WRITE_COMPRESSION.get(recording.compression, CompressionType.NONE)
    messages = 0
    first: int | None = None
    last: int | None = None
    try:
        stream = open(out, "wb")  # noqa: SIM115  (closed below)
    except OSError as exc:
        raise RecordingError(f"cannot write {out}: {exc.strerror or exc}") from None
    with stream:
        writer = Writer(stream, compression=compression)
        writer.start(profile="", library=recording.library or f"whexar {__version__}")
        for name, data in recording.metadata.items():
            writer.add_metadata(name, data)
        for attachment in recording.attachments.values():
            writer.add_attachment(0, 0, attachment.name, attachment.media_type, attachment.data)
        schema_ids: dict[int, int] = {}
        channel_ids: dict[int, int] = {}
        for _, records in recording._readable():
            for record in records:
                if isinstance(record, Schema):
                    schema_ids[record.id] = writer.register_schema(
                        record.name, record.encoding, record.data
                    )
                elif isinstance(record, Channel):
                    channel_ids[record.id] = writer.register_channel(
                        record.topic,
                        record.message_encoding,
                        schema_ids.get(record.schema_id, 0),
                        dict(record.metadata),
                    )
                elif isinstance(record, McapMessage) and record.channel_id in channel_ids:
                    writer.add_message(
                        channel_ids[record.channel_id],
                        record.log_time,
                        record.data,
                        record.publish_time,
                        record.sequence,
                    )
                    messages += 1
                    t = record.log_time
                    first = t if first is None else min(first, t)
                    last = t if last is None else max(last, t)
        damage = recording.damage
        readable = damage.offset if damage is not None else recording.size
        writer.add_metadata(
            "whexar.recovered",
            {
                "source": recording.path.name,
                "messages": str(messages),
                "readable_bytes": str(readable),
                "source_bytes": str(recording.size),
                "ended": "complete" if damage is None else damage.reason,
            },
        )
        writer.finish()  # type: ignore[no-untyped-call]  # mcap: no annotations
    return RecoveryReport(
        recording.path, out, messages, first, last, readable, recording.size, damage
    )
