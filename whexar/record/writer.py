"""The recorder: every message and every byte of a run, into one MCAP file.

Theory of operation
-------------------
The runtime calls the :class:`Recorder` (its observer) with every message published,
and the device links call :meth:`Recorder.link_bytes` with every chunk they send or
receive. Both only append a reference to a bounded buffer: no encoding, no I/O, so a
control cycle never waits on the recorder. Between cycles its owner calls
:meth:`Recorder.write_pending`, which encodes everything buffered, in order
(:mod:`whexar.record.encoding`), into the MCAP writer's current chunk, and, at least
every ``flush_period_s`` of wall time, closes the chunk and hands it to the operating
system: a process killed with SIGKILL leaves a file readable up to its last flush.
:meth:`Recorder.close` writes what is left, the recorder's statistics (metadata
``whexar.end``) and MCAP's summary and footer. The owner decides when to write; the
recorder knows nothing of the runtime (:meth:`Recorder.run` is a loop for an owner
that has an async ``sleep``).

Nothing is dropped on the normal path. Only if the owner stops draining does the
buffer reach ``max_pending``; then the oldest entries go, each one counted: the count
is logged on ``/log`` when writing resumes and stored in ``whexar.end``.

What a recording holds
----------------------
* metadata ``whexar`` (the whexar version, the encoding), ``run`` (what the caller
  passes: robot name, command line …), attachments (configuration, wiring, URDF …);
* ``/{channel}``: every message of runtime channel ``channel``, JSON with its type's
  JSON Schema (schema name = class name); a channel carrying several types has one
  MCAP channel per type. Log and publish time are ``msg.t`` in ns (1 at the least);
* ``/links/{link}``: the raw bytes of a device link (``whexar.LinkBytes``);
* ``/joint_states``, ``/log``, ``/tf``: Foxglove's views (:mod:`whexar.record.foxglove`).

Costs and defaults (measured here: Python 3.11, 2 cores, mcap 1.6, an idle machine)
------------------------------------------------------------------------------------
* handing over (``__call__``, :meth:`~Recorder.link_bytes`): 0.2 µs;
* writing a :class:`~whexar.actors.messages.ServoStates` of 42 joints with its
  ``foxglove.JointStates``: 180 µs (86 µs its JSON, 69 µs the joint states); a small
  message 6 µs (2 µs its JSON, most of the rest ``mcap.writer.Writer.add_message``); a
  chunk of link bytes 6.5 µs. Link bytes of one link, direction and time are merged
  into one record (a sync read's 42 status packets: 8× fewer records);
* the walking graph (``config/graphs/walk.toml``) costs about 26 ms of CPU per second
  of robot time to record, against about 92 ms for the runtime itself: far above the
  5 % the recording issue asks for. Two thirds of it is the servo states' JSON and
  their joint states: a binary encoding of ``ServoStates`` is the lever;
* ``compression="zstd"`` (default): compressing a 64 KiB chunk takes 0.07 ms (lz4:
  0.05 ms), and the walking graph's file grows by 4.0 MB per minute (lz4: 6.0). Closing
  a chunk costs more than compressing it: mcap's message indexes, built in Python,
  0.76 ms for 64 KiB of small messages (0.30 without them, but Foxglove's indexed
  reader needs them), so chunks are 32 KiB. Written every 10 ms, at most
  :data:`WRITE_BUDGET_S` at a time, the writes between cycles of the course took
  0.62–0.64 ms at the 99th percentile (``whexar bench record``). The notes' 1.5–6 ms
  stalls of Zstd were 1 MiB chunks;
* ``chunk_size=32 KiB``, ``flush_period_s=0.5``: after SIGKILL the file reads up to its
  last flush, so at most one flush period plus the time since the last
  :meth:`~Recorder.write_pending` is lost (the notes: about 1 s with 1 MiB chunks and
  no flush). The tests kill a recording process just before a flush and find its last
  record 0.499 s before the kill.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections import deque
from collections.abc import Awaitable, Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import IO, Any, Final, Protocol

from mcap.writer import LIBRARY_IDENTIFIER, CompressionType, Writer

from whexar import __version__
from whexar.actors.messages import ServoStates
from whexar.record import foxglove
from whexar.record.encoding import (
    LINK_SCHEMA,
    LINK_SCHEMA_NAME,
    MESSAGE_ENCODING,
    SCHEMA_ENCODING,
    MessageCodec,
    RecordingError,
    codec,
    encode_link,
    time_ns,
    type_path,
)
from whexar.runtime.clock import monotonic
from whexar.runtime.messages import MESSAGE_TYPES, Event, Message

__all__ = ["FORMAT", "Recorder", "RecorderStats"]

WRITE_PERIOD_S: Final = 0.01
"""How often :meth:`Recorder.run` writes what is pending: about once per bus cycle."""
WRITE_BUDGET_S: Final = 0.0003
"""The longest :meth:`Recorder.run` writes at a time: the issue lets recording delay a
control cycle by 1 ms at most, and one entry (a servo state and its joint-state view)
or a chunk's close can take 0.3 ms past the budget; what is left is written after the
actors have had their turn."""
FORMAT: Final = "whexar-mcap/1"
ROBOT_DESCRIPTION: Final = "/robot_description"
"""The topic of the robot's URDF (:meth:`Recorder.robot_description`)."""
_DESCRIPTION_SCHEMA: Final = {
    "title": "whexar.RobotDescription",
    "description": "The robot's URDF, as ROS's robot_description (std_msgs/String).",
    "type": "object",
    "properties": {"data": {"type": "string", "description": "URDF XML"}},
    "required": ["data"],
}
"""The layout described in this module's docstring (metadata ``whexar``, key ``format``)."""

_COMPRESSION = {
    "lz4": CompressionType.LZ4,
    "zstd": CompressionType.ZSTD,
    "none": CompressionType.NONE,
}
_MEDIA_TYPES = {
    ".toml": "application/toml",
    ".json": "application/json",
    ".urdf": "application/xml",
    ".xml": "application/xml",
    ".yaml": "application/yaml",
}

# Kinds of pending entries: (kind, …) tuples, made in O(1) by the hand-over methods.
_MESSAGE, _LINK, _TRANSFORM = 0, 1, 2


class LiveSink(Protocol):
    """Where a recorder also sends what it writes: a live view
    (:class:`whexar.record.live.LiveView`). JSON messages with JSON Schemas."""

    def add_channel(self, channel_id: int, topic: str, schema_name: str, schema: bytes) -> None:
        """A new channel: its id (the recording's), topic and schema."""
        ...

    def log(self, channel_id: int, ns: int, data: bytes) -> None:
        """One message of channel ``channel_id`` at log time ``ns``."""
        ...


@dataclass(frozen=True, slots=True)
class RecorderStats:
    """What a :class:`Recorder` did so far."""

    messages: int
    """Runtime messages written (each also counts once in ``records``)."""
    link_chunks: int
    """Chunks of device-link bytes written."""
    records: int
    """MCAP messages written, Foxglove's views included."""
    file_bytes: int
    """Bytes in the file so far."""
    dropped: int
    """Entries dropped because the pending buffer was full (0 on the normal path)."""
    errors: int
    """Messages that could not be encoded (each logged on ``/log``)."""
    pending: int
    """Entries waiting for :meth:`Recorder.write_pending`."""
    max_pending: int
    """The most entries :meth:`Recorder.write_pending` found waiting."""
    write_s: float
    """Wall seconds spent in :meth:`Recorder.write_pending` and :meth:`Recorder.close`."""
    flushes: int
    """Chunks closed and flushed on time (``flush_period_s``)."""


class Recorder:
    """Records a run into the MCAP file ``path``; a runtime observer (see the module).

    ``metadata`` (short strings: robot name, command line …) is stored as MCAP metadata
    ``run``; ``attachments`` (name → text or bytes: configuration, wiring …) as MCAP
    attachments, their media type guessed from the name's suffix. ``max_pending``
    bounds the buffer between :meth:`write_pending` calls. ``joint_states`` and
    ``event_log`` write Foxglove's ``/joint_states`` and ``/log`` views.

    The hand-over methods (``__call__``, :meth:`link_bytes`, :meth:`transform`) may be
    called from any thread (they only append to a deque); :meth:`write_pending` and
    :meth:`close` from one thread at a time.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        metadata: Mapping[str, str] | None = None,
        attachments: Mapping[str, str | bytes] | None = None,
        chunk_size: int = 32 * 1024,
        flush_period_s: float = 0.5,
        compression: str = "zstd",
        max_pending: int = 100_000,
        joint_states: bool = True,
        event_log: bool = True,
        live: LiveSink | None = None,
    ) -> None:
        if compression not in _COMPRESSION:
            raise RecordingError(
                f"compression {compression!r}: expected one of {', '.join(_COMPRESSION)}"
            )
        if chunk_size <= 0 or max_pending <= 0 or not flush_period_s > 0:
            raise RecordingError(
                "chunk_size, max_pending and flush_period_s must be > 0 "
                f"(got {chunk_size}, {max_pending}, {flush_period_s})"
            )
        self.path = Path(path)
        self.flush_period_s = flush_period_s
        self.max_pending = max_pending
        self._joint_states = joint_states
        self._event_log = event_log
        self._live = live
        try:
            self._file: IO[bytes] = open(self.path, "wb")  # noqa: SIM115  (closed by close())
        except OSError as exc:
            raise RecordingError(f"cannot record to {self.path}: {exc.strerror or exc}") from None
        # Message indexes stay: Foxglove's indexed reader finds a chunk's messages through
        # them. mcap builds them in Python as a chunk closes, the longest part of a write
        # (0.76 ms for a 64 KiB chunk against 0.30 without, measured here): hence smaller
        # chunks than mcap's default.
        self._writer = Writer(
            self._file, chunk_size=chunk_size, compression=_COMPRESSION[compression]
        )
        self._writer.start(profile="", library=f"whexar {__version__}; {LIBRARY_IDENTIFIER}")
        self._writer.add_metadata(
            "whexar",
            {
                "version": __version__,
                "format": FORMAT,
                "message_encoding": MESSAGE_ENCODING,
                "time": "runtime clock: log time ns = t s * 1e9 (1 at the least)",
                "compression": compression,
                "chunk_size": str(chunk_size),
                "flush_period_s": repr(flush_period_s),
            },
        )
        if metadata:
            self._writer.add_metadata("run", {str(k): str(v) for k, v in metadata.items()})
        for name, content in (attachments or {}).items():
            if isinstance(content, str):
                data = content.encode("utf-8")
                media = _MEDIA_TYPES.get(Path(name).suffix.lower(), "text/plain")
            else:
                data = bytes(content)
                media = _MEDIA_TYPES.get(Path(name).suffix.lower(), "application/octet-stream")
            self._writer.add_attachment(
                create_time=0, log_time=0, name=name, media_type=media, data=data
            )
        self._file.flush()

        # Compile the codec of every registered type now (well under 1 ms each), so that
        # no write between two control cycles pays for a type's first message.
        for cls in list(MESSAGE_TYPES.values()):
            with contextlib.suppress(RecordingError):
                codec(cls)

        self._pending: deque[tuple[Any, ...]] = deque()
        self._append = self._pending.append
        self._schemas: dict[str, int] = {}
        self._schema_texts: dict[int, tuple[str, bytes]] = {}
        self._routes: dict[tuple[str, type], tuple[int, MessageCodec[Any]]] = {}
        self._topics: dict[str, int] = {}
        self._failed_types: set[tuple[str, type]] = set()
        self._seq = 0
        self._messages = self._links = self._records = 0
        self._dropped = self._dropped_logged = self._errors = 0
        self._max_pending = 0
        self._write_s = 0.0
        self._flushes = 0
        self._last_flush = monotonic()
        self._last_ns = 1
        self._closed = False
        self._broken: str | None = None

    # ------------------------------------------------------------------ hand-over (O(1))

    def __call__(self, channel: str, msg: Message) -> None:
        """The runtime's observer: buffer ``msg``, published on ``channel``."""
        if len(self._pending) >= self.max_pending:
            self._drop_oldest()
        self._append((_MESSAGE, channel, msg))

    def link_bytes(self, link: str, direction: str, t: float, data: bytes) -> None:
        """Buffer raw bytes of device link ``link`` sent (``"tx"``) or received (``"rx"``)
        at runtime-clock time ``t``; a runtime ``link_observer``."""
        if data.__class__ is not bytes:
            data = bytes(data)  # a bytearray could change before it is written
        if len(self._pending) >= self.max_pending:
            self._drop_oldest()
        self._append((_LINK, link, direction, t, data))

    def transform(
        self,
        t: float,
        parent: str,
        child: str,
        translation: Sequence[float],
        rotation_xyzw: Sequence[float],
    ) -> None:
        """Buffer the pose of frame ``child`` in ``parent`` at ``t`` for ``/tf``
        (translation in m, rotation a unit quaternion x, y, z, w)."""
        if len(self._pending) >= self.max_pending:
            self._drop_oldest()
        self._append((_TRANSFORM, t, parent, child, tuple(translation), tuple(rotation_xyzw)))

    def robot_description(self, urdf: str) -> None:
        """Write the robot's URDF on :data:`ROBOT_DESCRIPTION` (``{"data": URDF}``, as
        ROS's ``robot_description``), at the start: Foxglove's URDF layer can read it
        from that topic. Call it once, before the run."""
        self._add(self._topic(ROBOT_DESCRIPTION), 1, json.dumps({"data": urdf}).encode())

    def _drop_oldest(self) -> None:
        try:
            self._pending.popleft()
        except IndexError:  # drained by the writer meanwhile
            return
        self._dropped += 1

    # ------------------------------------------------------------------ writing

    def write_pending(self, budget_s: float | None = None) -> int:
        """Encode and write everything buffered, in order; returns how many entries.

        With ``budget_s``, stop after about that many wall seconds and leave the rest
        for the next call. Closes the chunk and flushes the file when ``flush_period_s``
        has passed since the last flush. Never raises for a message it cannot encode
        (it is counted and logged on ``/log``); a file that cannot be written any more
        (a full disk) ends the recording (``stats.dropped`` counts what follows), and
        the robot runs on.
        """
        if self._closed:
            return 0
        start = monotonic()
        pending = self._pending
        self._max_pending = max(self._max_pending, len(pending))
        if self._broken is not None:
            count = len(pending)
            pending.clear()
            self._dropped += count
            return 0
        done = 0
        try:
            if self._dropped > self._dropped_logged:
                self._log_dropped()
            while pending:
                entry = pending.popleft()
                kind = entry[0]
                if kind == _MESSAGE:
                    self._write_message(entry[1], entry[2])
                elif kind == _LINK:
                    data = entry[4]
                    # Bytes received on one link at one time are one record: a sync read
                    # arrives as a status packet per servo, stamped alike (8× fewer
                    # records). Sent packets stay apart: a replay matches them one by one.
                    while pending and pending[0][:4] == entry[:4] and entry[2] == "rx":
                        data += pending.popleft()[4]
                    self._write_link(entry[1], entry[2], entry[3], data)
                else:
                    self._write_transform(*entry[1:])
                done += 1
                if budget_s is not None and monotonic() - start > budget_s:
                    break
            now = monotonic()
            if now - self._last_flush >= self.flush_period_s:
                self._writer.flush()  # type: ignore[no-untyped-call]  # mcap: no annotations
                self._last_flush = now
                self._flushes += 1
        except OSError as exc:
            self._break(exc)
        self._write_s += monotonic() - start
        return done

    async def run(
        self,
        sleep: Callable[[float], Awaitable[object]],
        period_s: float = WRITE_PERIOD_S,
        budget_s: float | None = WRITE_BUDGET_S,
    ) -> None:
        """Write pending entries every ``period_s``, at most ``budget_s`` at a time
        (``sleep`` is the owner's: the runtime clock's, anyio's …) until cancelled;
        :meth:`close` stays the owner's."""
        while not self._closed:
            self.write_pending(budget_s)
            # More left: let the actors run, then go on (no cycle waits longer than one
            # budget, and the recorder still keeps up however much there is).
            await sleep(0.0 if self._pending else period_s)

    def _write_message(self, channel: str, msg: Message) -> None:
        cls = msg.__class__
        route = self._routes.get((channel, cls))
        if route is None:
            route = self._route(channel, cls)
        channel_id, msg_codec = route
        ns = time_ns(msg.t)
        try:
            data = msg_codec.encode(msg)
        except Exception as exc:  # a bad value must not stop the recording (or the robot)
            self._encoding_failed(channel, cls, ns, exc)
            return
        self._add(channel_id, ns, data)
        self._messages += 1
        if cls is ServoStates and self._joint_states:
            assert isinstance(msg, ServoStates)
            self._add(self._topic("/joint_states"), ns, foxglove.joint_states(msg, ns))
        elif self._event_log and isinstance(msg, Event):
            name = cls.__name__
            self._add(
                self._topic("/log"),
                ns,
                foxglove.log_entry(
                    ns, foxglove.event_level(name), foxglove.event_text(msg), msg.source
                ),
            )

    def _write_link(self, link: str, direction: str, t: float, data: bytes) -> None:
        ns = time_ns(t)
        self._add(self._topic(f"/links/{link}"), ns, encode_link(direction, t, data))
        self._links += 1

    def _write_transform(
        self,
        t: float,
        parent: str,
        child: str,
        translation: Sequence[float],
        rotation: Sequence[float],
    ) -> None:
        ns = time_ns(t)
        data = foxglove.frame_transforms(ns, parent, child, translation, rotation)
        self._add(self._topic("/tf"), ns, data)

    def _channel(self, topic: str, schema_id: int, metadata: dict[str, str]) -> int:
        """Register an MCAP channel, and the same channel on the live view if there is one."""
        channel_id: int = self._writer.register_channel(
            topic, MESSAGE_ENCODING, schema_id, metadata
        )
        if self._live is not None:
            name, schema = self._schema_texts[schema_id]
            self._live.add_channel(channel_id, topic, name, schema)
        return channel_id

    def _add(self, channel_id: int, ns: int, data: bytes) -> None:
        self._seq = (self._seq + 1) & 0xFFFFFFFF  # MCAP's sequence is a uint32
        self._writer.add_message(channel_id, ns, data, ns, self._seq)
        if self._live is not None:
            self._live.log(channel_id, ns, data)
        self._records += 1
        self._last_ns = ns

    def _schema(self, name: str, schema: Mapping[str, Any] | bytes) -> int:
        known = self._schemas.get(name)
        if known is None:
            data = schema if isinstance(schema, bytes) else json.dumps(schema).encode()
            known = self._writer.register_schema(name, SCHEMA_ENCODING, data)
            self._schemas[name] = known
            self._schema_texts[known] = (name, data)
        return known

    def _route(self, channel: str, cls: type[Message]) -> tuple[int, MessageCodec[Any]]:
        """The MCAP channel of (runtime channel, message type), registered on first use."""
        try:
            msg_codec = codec(cls)
        except RecordingError:
            # Unencodable type: its messages go through the error path, once logged.
            msg_codec = _UNENCODABLE
        schema_id = self._schema(cls.__name__, msg_codec.schema_data)
        channel_id = self._channel(
            f"/{channel}", schema_id, {"whexar.channel": channel, "whexar.type": type_path(cls)}
        )
        route = (channel_id, msg_codec)
        self._routes[(channel, cls)] = route
        return route

    def _topic(self, topic: str) -> int:
        """The MCAP channel of one of the recorder's own topics."""
        known = self._topics.get(topic)
        if known is not None:
            return known
        metadata: dict[str, str] = {}
        if topic == "/joint_states":
            name, schema = "foxglove.JointStates", foxglove.JOINT_STATES_SCHEMA
            metadata = {"effort": "servo current (A), not torque"}
        elif topic == "/log":
            name, schema = "foxglove.Log", foxglove.LOG_SCHEMA
        elif topic == "/tf":
            name, schema = "foxglove.FrameTransforms", foxglove.FRAME_TRANSFORMS_SCHEMA
        elif topic == ROBOT_DESCRIPTION:
            name, schema = "whexar.RobotDescription", _DESCRIPTION_SCHEMA
        else:
            name, schema = LINK_SCHEMA_NAME, LINK_SCHEMA
            metadata = {"whexar.link": topic.removeprefix("/links/")}
        known = self._channel(topic, self._schema(name, schema), metadata)
        self._topics[topic] = known
        return known

    def _encoding_failed(self, channel: str, cls: type, ns: int, exc: Exception) -> None:
        self._errors += 1
        if (channel, cls) in self._failed_types:
            return
        self._failed_types.add((channel, cls))
        text = f"recorder: cannot encode {cls.__name__} on /{channel} (not recorded): {exc}"
        self._add(self._topic("/log"), ns, foxglove.log_entry(ns, 4, text, "recorder"))

    def _log_dropped(self) -> None:
        count = self._dropped - self._dropped_logged
        self._dropped_logged = self._dropped
        text = (
            f"recorder: {count} entries dropped (the pending buffer of {self.max_pending} "
            "was full: write_pending() was not called often enough)"
        )
        ns = self._last_ns
        self._add(self._topic("/log"), ns, foxglove.log_entry(ns, 4, text, "recorder"))

    def _break(self, exc: OSError) -> None:
        self._broken = f"{exc.strerror or exc}"
        self._dropped += len(self._pending)
        self._pending.clear()
        with contextlib.suppress(OSError):
            self._file.close()

    # ------------------------------------------------------------------ end

    @property
    def stats(self) -> RecorderStats:
        """A snapshot of what the recorder did so far."""
        try:
            size = self.path.stat().st_size if self._file.closed else self._file.tell()
        except OSError:
            size = 0
        return RecorderStats(
            messages=self._messages,
            link_chunks=self._links,
            records=self._records,
            file_bytes=size,
            dropped=self._dropped,
            errors=self._errors,
            pending=len(self._pending),
            max_pending=self._max_pending,
            write_s=self._write_s,
            flushes=self._flushes,
        )

    @property
    def failure(self) -> str | None:
        """Why the file could not be written any more (a full disk), or ``None``."""
        return self._broken

    def close(self) -> RecorderStats:
        """Write everything pending, the statistics and the summary; close the file.

        Idempotent; returns the final :attr:`stats`. Raises :class:`RecordingError` if
        the file could not be written (the robot ran on; the file is readable up to
        its last flush).
        """
        if self._closed:
            return self.stats
        self.write_pending()
        self._closed = True
        start = monotonic()
        if self._broken is None:
            try:
                if self._dropped > self._dropped_logged:
                    self._log_dropped()
                stats = self.stats
                self._writer.add_metadata(
                    "whexar.end",
                    {
                        "messages": str(stats.messages),
                        "link_chunks": str(stats.link_chunks),
                        "records": str(stats.records),
                        "dropped": str(stats.dropped),
                        "errors": str(stats.errors),
                        "max_pending": str(stats.max_pending),
                        "write_s": f"{stats.write_s + monotonic() - start:.3f}",
                    },
                )
                self._writer.finish()  # type: ignore[no-untyped-call]
                self._file.close()
            except OSError as exc:
                self._break(exc)
        self._write_s += monotonic() - start
        if self._broken is not None:
            raise RecordingError(f"recording {self.path} failed: {self._broken}")
        return self.stats

    def __enter__(self) -> Recorder:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


def _unencodable(msg: Any) -> Any:
    raise RecordingError(f"type {type(msg).__name__} cannot be recorded")


_UNENCODABLE: MessageCodec[Any] = MessageCodec(
    cls=Message, schema={}, schema_data=b"{}", to_json=_unencodable, from_json=_unencodable
)
"""Stands in for the codec of a type that cannot be encoded: every message fails."""
