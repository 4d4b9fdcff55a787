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

Disks: every recording keeps a budget (:mod:`whexar.record.budget`): checked before the
file is made and between writes, it deletes older recordings, and stops the recording
when it cannot be kept (:meth:`HandOver.keep_budget`, which :meth:`~HandOver.run` calls;
each deletion and a stop is an event; the folder is listed and files deleted elsewhere,
never in the control loop: a recording process, or a thread). A write that fails (a full
disk) stops the recording too: the file is written unbuffered, so the recorder knows
where its last whole record ends; it cuts the file back there and ends it as fully as
the disk lets (:meth:`_McapFile.salvage`): every message of a whole chunk stays
readable. Either way the hand-over lets go of what follows, and the robot runs on.

What a recording holds
----------------------
* metadata ``whexar`` (the whexar version, the encoding), ``run`` (what the caller
  passes: robot name, command line …), attachments (configuration, wiring, URDF …);
* ``/{channel}``: every message of runtime channel ``channel``, JSON with its type's
  JSON Schema (schema name = class name); a channel carrying several types has one
  MCAP channel per type. Log and publish time are ``msg.t`` in ns (1 at the least);
* ``/links/{link}``: the raw bytes of a device link (``whexar.LinkBytes``);
* ``/joint_states``, ``/log``, ``/tf``: Foxglove's views (:mod:`whexar.record.foxglove`).

``whexar sim`` and ``whexar run`` run this recorder in a process of its own
(:mod:`whexar.record.sidecar`), fed over a pipe: the runtime then only hands over and
packs. In-process, as below, it serves a live view and the tests.

Defaults, and why
-----------------
docs/recording.md has what each costs, measured with ``whexar bench record`` and on
captured runs.

* handing over (``__call__``, :meth:`~Recorder.link_bytes`) appends a reference, no
  more: it runs inside the control cycle;
* the file is written by :class:`_McapFile`, not ``mcap.writer.Writer``: that one spends
  Python work on every message and builds its message indexes record by record; here a
  message is one ``struct`` pack and two appends, a chunk's indexes one ``array`` each;
* JSON by msgspec (:func:`whexar.record.encoding.dumps`), and ``/joint_states`` at most
  every :data:`JOINT_STATES_PERIOD_S`: enough for Foxglove's 3D view, while
  ``/servo-state`` keeps every reading;
* in-process, writing costs the runtime more than the 5 % the issue allows: hence the
  recording process (:mod:`whexar.record.sidecar`). A binary encoding (CDR or protobuf)
  of the high-rate types (``LegState``, ``JointGoals``, ``ServoStates``) would shrink
  the cost further;
* ``compression="zstd"`` (default): smaller files than lz4, for compressing time that is
  small beside the rest of the writing;
* ``chunk_size=32 KiB``: a chunk's close (compression, CRC, indexes) is the longest part
  of a write; written every 10 ms, at most :data:`WRITE_BUDGET_S` at a time, the writes
  between cycles stay well under the 1 ms a cycle may wait;
* ``flush_period_s=0.5``: after SIGKILL the file reads up to its last flush, so at most
  one flush period plus the time since the last :meth:`~Recorder.write_pending` is
  lost (``tests/record/test_sigkill.py`` kills a recording process just before a flush).
"""

from __future__ import annotations

import contextlib
import json
import os
import struct
import sys
import zlib
from array import array
from collections import deque
from collections.abc import Awaitable, Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import IO, TYPE_CHECKING, Any, Final, Protocol, Self

import lz4.frame  # type: ignore[import-untyped]  # no type hints
import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Attachment,
    AttachmentIndex,
    Channel,
    ChunkIndex,
    DataEnd,
    Header,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)
from mcap.writer import LIBRARY_IDENTIFIER

from whexar import __version__
from whexar.actors.messages import RecordingDeleted, RecordingStopped, ServoStates
from whexar.record import foxglove
from whexar.record.budget import BudgetGuard, GuardThread, Plan
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
from whexar.runtime.wiring import EVENTS_CHANNEL

if TYPE_CHECKING:
    from whexar.runtime.supervisor import Runtime

__all__ = [
    "CONFIG_ATTACHMENT",
    "EFFECTIVE_CONFIG_ATTACHMENT",
    "FORMAT",
    "RECORDER",
    "RECORDER_EVENTS",
    "URDF_ATTACHMENT",
    "HandOver",
    "Recorder",
    "RecorderStats",
]

WRITE_PERIOD_S: Final = 0.01
"""How often :meth:`Recorder.run` writes what is pending: about once per bus cycle."""
WRITE_BUDGET_S: Final = 0.0003
"""The longest :meth:`Recorder.run` writes at a time: the issue lets recording delay a
control cycle by 1 ms at most, and one entry (a servo state and its joint-state view)
or a chunk's close can overrun the budget by about as much again (docs/recording.md);
what is left is written after the actors have had their turn."""
JOINT_STATES_PERIOD_S: Final = 1 / 30
"""``/joint_states`` are written at most this often (log time): about 27 Hz from servo
states at 109 Hz, plenty for Foxglove's 3D view; every servo state is recorded whole."""
_JOINT_STATES_PERIOD_NS: Final = round(JOINT_STATES_PERIOD_S * 1e9)
FORMAT: Final = "whexar-mcap/1"
RECORDER: Final = "recorder"
"""The ``source`` of the recorder's events and the name of its ``/log`` entries."""
RECORDER_EVENTS: Final = (RecordingDeleted, RecordingStopped)
"""The recorder's events: about the disk, not the robot (a replay leaves them out)."""
URDF_ATTACHMENT: Final = "robot.urdf"
"""The robot's URDF (a simulation's recording)."""
CONFIG_ATTACHMENT: Final = "config.toml"
"""The configuration file the recorded run read, if it read one."""
EFFECTIVE_CONFIG_ATTACHMENT: Final = "robot-config.json"
"""Every value of the recorded run's robot configuration (defaults included), as JSON:
a replay finds out whether they changed (:mod:`whexar.record.replay`)."""
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

_COMPRESSION: Final = ("zstd", "lz4", "none")
_MEDIA_TYPES = {
    ".toml": "application/toml",
    ".json": "application/json",
    ".urdf": "application/xml",
    ".xml": "application/xml",
    ".yaml": "application/yaml",
}

# MCAP records (https://mcap.dev/spec): opcode (uint8) and length (uint64), then fields.
MAGIC: Final = b"\x89MCAP0\r\n"
_OP_FOOTER, _OP_MESSAGE, _OP_CHUNK, _OP_MESSAGE_INDEX = 0x02, 0x05, 0x06, 0x07
_MESSAGE_HEAD: Final = struct.Struct("<BQHIQQ")  # channel id, sequence, log, publish time
_CHUNK_HEAD: Final = struct.Struct("<BQQQQI")  # start, end, uncompressed size, CRC
_INDEX_HEAD: Final = struct.Struct("<BQHI")  # channel id, byte length of the pairs
_FOOTER_HEAD: Final = struct.Struct("<BQQQ")  # summary start, summary offset start
_STRING_LENGTH: Final = struct.Struct("<I")
_LENGTH: Final = struct.Struct("<Q")
_CRC: Final = struct.Struct("<I")
_BIG_ENDIAN: Final = sys.byteorder == "big"

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
    process_cpu_s: float = 0.0
    """CPU seconds of the recording process, for a recorder in a process of its own
    (:class:`~whexar.record.sidecar.RecorderProcess`, once closed); 0 otherwise."""


class HandOver:
    """The O(1) hand-over both recorders share: (kind, …) tuples appended to a deque of
    at most ``max_pending`` entries, the oldest dropped and counted past it."""

    period_s: float = WRITE_PERIOD_S
    """How often :meth:`run` writes (each recorder's own)."""
    max_pending: int
    _pending: deque[tuple[Any, ...]]
    _append: Callable[[tuple[Any, ...]], None]
    _dropped: int
    _closed: bool
    _broken: str | None
    _max_pending: int

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

    def _drop_oldest(self) -> None:
        try:
            self._pending.popleft()
        except IndexError:  # drained by the writer meanwhile
            return
        self._dropped += 1

    def write_pending(self, budget_s: float | None = None) -> int:
        """Write what is pending (each recorder says how); returns how many entries."""
        raise NotImplementedError

    def _writable(self) -> bool:
        """A write's start: note the buffer's high-water mark; ``False`` once closed or
        stopped, or once the recording broke (what is buffered is then dropped and
        counted)."""
        if self._closed:
            return False
        pending = self._pending
        self._max_pending = max(self._max_pending, len(pending))
        if self._broken is not None or self._stopped is not None:
            self._dropped += len(pending)
            pending.clear()
            return False
        return True

    def close(self) -> RecorderStats:
        """End the recording (each recorder says how)."""
        raise NotImplementedError

    # ------------------------------------------------------------------ the budget, stopping

    _guard: BudgetGuard | None
    _checks: GuardThread | None
    _stopped: str | None
    _reported: bool
    _plans: list[Plan]
    _now: float
    events: list[Event]
    """What this recorder reported: :class:`~whexar.actors.messages.RecordingDeleted`
    and :class:`~whexar.actors.messages.RecordingStopped`, in order."""
    path: Path

    def _start_budget(self, guard: BudgetGuard | None) -> None:
        """The first check of the budget (:mod:`whexar.record.budget`), before the file
        exists: old recordings go before anything is written (here, before the runtime
        runs); :meth:`run` reports it. The later checks run on a thread of their own
        (:class:`~whexar.record.budget.GuardThread`): never in the control loop."""
        self._guard = guard
        self._stopped = None
        self._reported = False
        self._now = 0.0
        self.events = []
        self._plans = [] if guard is None else [guard.check()]
        self._checks = None if guard is None else GuardThread(guard)

    def _take_plans(self) -> list[Plan]:
        """The budget's plans not yet reported (the first check's, then the thread's;
        a recording process's, told over its pipe); never waits."""
        plans, self._plans = self._plans, []
        if self._checks is not None:
            plans += self._checks.poll()
        return plans

    def _last_checks(self) -> None:
        """At the end (:meth:`close`): the check under way finished, and what it and any
        not yet reported did, as events handed to this recorder only (the runtime has
        ended): so the file tells of every deletion, a stop ends it all the same."""
        plans, self._plans = self._plans, []
        if self._checks is not None:
            plans += self._checks.finish()
        if self._stopped is None:
            self._report_plans(None, plans)

    @property
    def failure(self) -> str | None:
        """Why the file could not be written any more (a full disk, the recording
        process gone), or ``None``."""
        return self._broken

    @property
    def stopped(self) -> str | None:
        """Why the recording stopped before :meth:`close` (its budget, a failure), or
        ``None``."""
        return self._stopped

    def stop(self, reason: str) -> None:
        """End the recording now, cleanly, for ``reason``: what is buffered is written
        and the file ended; what is handed over from now on is let go (each recorder
        says how)."""
        raise NotImplementedError

    @property
    def _ended(self) -> bool:
        """Nothing more to write: the file is ended (:meth:`run` returns)."""
        return self._stopped is not None

    def _let_go(self) -> None:
        """From now on, the hand-over keeps nothing (the recording has stopped)."""
        self._append = _discard
        self._pending.clear()

    def keep_budget(self, runtime: Runtime | None = None) -> None:
        """Report what the budget's checks did, start the next check when due (elsewhere:
        never waits on the disk), and stop the recording when it cannot be kept or the
        file cannot be written any more; each deletion and a stop is an event on
        ``runtime``'s ``events`` channel (without a runtime, handed to this recorder
        only). :meth:`run` calls it after every write."""
        if runtime is not None:
            try:
                self._now = runtime.clock.now()
            except RuntimeError:  # not running yet: report once it is
                return
        if self._stopped is not None:
            return
        self._report_plans(runtime, self._take_plans())
        if self._broken is not None and self._stopped is None:  # a full disk, the process gone
            self._stopped = self._broken
            self._reported = True
            self._let_go()
            self._emit(runtime, RecordingStopped, reason=f"cannot write: {self._broken}")

    def _report_plans(self, runtime: Runtime | None, plans: list[Plan]) -> None:
        """Each deletion an event; a stop an event, then the recording stopped."""
        for found in plans:
            if self._stopped is not None:
                return
            for d in found.deletions:
                self._emit(
                    runtime,
                    RecordingDeleted,
                    path=str(d.file.path),
                    size_bytes=d.file.size,
                    reason=d.reason,
                )
            if found.stop is not None and self._broken is None:
                # Emitted first, so that it is the recording's last message.
                self._emit(runtime, RecordingStopped, reason=found.stop)
                self.stop(found.stop)

    def _emit(self, runtime: Runtime | None, kind: type[Event], **fields: Any) -> None:
        if kind is RecordingStopped:
            fields["path"] = str(self.path)
        event = kind(t=self._now, source=RECORDER, **fields)
        self.events.append(event)
        if runtime is not None:
            runtime.emit(event)  # which hands it to this recorder too, as its observer
        else:
            self(EVENTS_CHANNEL, event)

    def __call__(self, channel: str, msg: Message) -> None:
        """The runtime's observer (each recorder's own)."""
        raise NotImplementedError

    async def run(
        self,
        sleep: Callable[[float], Awaitable[object]],
        period_s: float | None = None,
        budget_s: float | None = WRITE_BUDGET_S,
        *,
        runtime: Runtime | None = None,
    ) -> None:
        """Write pending entries every ``period_s`` (the recorder's :attr:`period_s` by
        default), at most ``budget_s`` at a time (``sleep`` is the owner's: the runtime
        clock's, anyio's …), and keep the budget (:meth:`keep_budget`, its events on
        ``runtime``), until cancelled or the recording stops; :meth:`close` stays the
        owner's."""
        period = self.period_s if period_s is None else period_s
        while not self._closed:
            self.write_pending(budget_s)
            self.keep_budget(runtime)
            if self._ended:
                return
            # More left: let the actors run, then go on (no cycle waits longer than one
            # budget, and the recorder still keeps up however much there is).
            await sleep(0.0 if self._pending else period)

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


class Recorder(HandOver):
    """Records a run into the MCAP file ``path``; a runtime observer (see the module).

    ``metadata`` (short strings: robot name, command line …) is stored as MCAP metadata
    ``run``; ``attachments`` (name → text or bytes: configuration, wiring …) as MCAP
    attachments, their media type guessed from the name's suffix. ``max_pending``
    bounds the buffer between :meth:`write_pending` calls. ``joint_states`` and
    ``event_log`` write Foxglove's ``/joint_states`` and ``/log`` views. ``guard``
    keeps the recordings folder within its budget (:mod:`whexar.record.budget`);
    ``opener`` opens the file, unbuffered (a test's full disk; default
    ``open(path, "wb", buffering=0)``).

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
        guard: BudgetGuard | None = None,
        opener: Callable[[Path], IO[bytes]] | None = None,
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
        self._pending: deque[tuple[Any, ...]] = deque()
        self._append = self._pending.append
        self._schemas: dict[str, int] = {}
        self._schema_texts: dict[int, tuple[str, bytes]] = {}
        self._routes: dict[tuple[str, type], tuple[int, MessageCodec[Any]]] = {}
        self._topics: dict[str, int] = {}
        self._failed_types: set[tuple[str, str]] = set()
        self._messages = self._links = 0
        self._dropped = self._dropped_logged = self._errors = 0
        self._max_pending = 0
        self._write_s = 0.0
        self._flushes = 0
        self._next_joint_states = 0
        self._closed = False
        self._broken: str | None = None
        self._start_budget(guard)  # before the file exists: old recordings go first

        try:
            self._file: IO[bytes] = (opener or _open_unbuffered)(self.path)
        except OSError as exc:
            raise RecordingError(f"cannot record to {self.path}: {exc.strerror or exc}") from None
        self._mcap = _McapFile(self._file, chunk_size, compression)
        try:
            self._mcap.start(library=f"whexar {__version__}; {LIBRARY_IDENTIFIER}")
            self._mcap.metadata(
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
                self._mcap.metadata("run", {str(k): str(v) for k, v in metadata.items()})
            for name, content in (attachments or {}).items():
                if isinstance(content, str):
                    data = content.encode("utf-8")
                    media = _MEDIA_TYPES.get(Path(name).suffix.lower(), "text/plain")
                else:
                    data = bytes(content)
                    media = _MEDIA_TYPES.get(Path(name).suffix.lower(), "application/octet-stream")
                self._mcap.attachment(name, media, data)
            self._file.flush()
        except OSError as exc:  # a full disk from the start: the robot runs all the same
            self._break(exc)
        self._last_flush = monotonic()

        # Compile the codec of every registered type now, so that no write between two
        # control cycles pays for a type's first message.
        for cls in list(MESSAGE_TYPES.values()):
            with contextlib.suppress(RecordingError):
                codec(cls)

    # ------------------------------------------------------------------ hand-over (O(1))

    def __call__(self, channel: str, msg: Message) -> None:
        """The runtime's observer: buffer ``msg``, published on ``channel``."""
        if len(self._pending) >= self.max_pending:
            self._drop_oldest()
        self._append((_MESSAGE, channel, msg))

    def robot_description(self, urdf: str) -> None:
        """Write the robot's URDF on :data:`ROBOT_DESCRIPTION` (``{"data": URDF}``, as
        ROS's ``robot_description``), at the start: Foxglove's URDF layer can read it
        from that topic. Call it once, before the run."""
        self._add(self._topic(ROBOT_DESCRIPTION), 1, json.dumps({"data": urdf}).encode())

    # ------------------------------------------------------------------ writing

    def write_pending(self, budget_s: float | None = None) -> int:
        """Encode and write everything buffered, in order; returns how many entries.

        With ``budget_s``, stop after about that many wall seconds and leave the rest
        for the next call. Closes the chunk and flushes the file when ``flush_period_s``
        has passed since the last flush. Never raises for a message it cannot encode
        (it is counted and logged on ``/log``); a file that cannot be written any more
        (a full disk) ends the recording: the file ends at its last whole record
        (:meth:`_break`), what is buffered is dropped and counted, what follows is let
        go, and the robot runs on.
        """
        start = monotonic()
        if not self._writable():
            return 0
        pending = self._pending
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
                    if entry[2] == "rx":
                        link, t = entry[1], entry[3]
                        while pending:
                            after = pending[0]
                            if (
                                after[0] != _LINK
                                or after[3] != t
                                or after[2] != "rx"
                                or after[1] != link
                            ):
                                break
                            data += pending.popleft()[4]
                    self._write_link(entry[1], entry[2], entry[3], data)
                else:
                    self._write_transform(*entry[1:])
                done += 1
                if budget_s is not None and monotonic() - start > budget_s:
                    break
            now = monotonic()
            if now - self._last_flush >= self.flush_period_s:
                self._mcap.flush()
                self._last_flush = now
                self._flushes += 1
        except OSError as exc:
            self._break(exc)
        self._write_s += monotonic() - start
        return done

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
        if cls is ServoStates and self._joint_states and ns >= self._next_joint_states:
            assert isinstance(msg, ServoStates)
            self._next_joint_states = ns + _JOINT_STATES_PERIOD_NS
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
        channel_id = self._mcap.channel(topic, MESSAGE_ENCODING, schema_id, metadata)
        if self._live is not None:
            name, schema = self._schema_texts[schema_id]
            self._live.add_channel(channel_id, topic, name, schema)
        return channel_id

    def _add(self, channel_id: int, ns: int, data: bytes) -> None:
        self._mcap.message(channel_id, ns, data)
        if self._live is not None:
            self._live.log(channel_id, ns, data)

    def _schema(self, name: str, schema: Mapping[str, Any] | bytes) -> int:
        known = self._schemas.get(name)
        if known is None:
            data = schema if isinstance(schema, bytes) else json.dumps(schema).encode()
            known = self._mcap.schema(name, SCHEMA_ENCODING, data)
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

    def not_recorded(self, channel: str, type_name: str, t: float, reason: str) -> None:
        """Count a message of ``type_name`` on ``channel`` at ``t`` that could not be
        recorded; the first of each (channel, type) is logged on ``/log`` with ``reason``.
        (The recording process's way to report what its runtime could not hand over.)"""
        self._not_recorded(channel, type_name, time_ns(t), reason)

    @property
    def last_t(self) -> float:
        """The runtime-clock time of the last record written (0 before any)."""
        return self._mcap.last_ns / 1e9 if self._mcap.last_ns > 1 else 0.0

    def dropped_elsewhere(self, count: int) -> None:
        """Count ``count`` entries dropped before they reached this recorder (a recording
        process's runtime found its pipe full); logged and stored as :meth:`close` does
        its own."""
        self._dropped += count

    def _encoding_failed(self, channel: str, cls: type, ns: int, exc: Exception) -> None:
        self._not_recorded(channel, cls.__name__, ns, str(exc))

    def _not_recorded(self, channel: str, type_name: str, ns: int, reason: str) -> None:
        self._errors += 1
        if (channel, type_name) in self._failed_types:
            return
        self._failed_types.add((channel, type_name))
        text = f"recorder: cannot encode {type_name} on /{channel} (not recorded): {reason}"
        self._add(self._topic("/log"), ns, foxglove.log_entry(ns, 4, text, RECORDER))

    def _log_dropped(self) -> None:
        count = self._dropped - self._dropped_logged
        self._dropped_logged = self._dropped
        text = (
            f"recorder: {count} entries dropped (the pending buffer of {self.max_pending} "
            "was full: write_pending() was not called often enough)"
        )
        ns = self._mcap.last_ns
        self._add(self._topic("/log"), ns, foxglove.log_entry(ns, 4, text, RECORDER))

    def _break(self, exc: OSError) -> None:
        """The file cannot be written any more (a full disk): nothing more is taken, and
        the file ends at its last whole record, as fully as the disk lets it
        (:meth:`_McapFile.salvage`): every message written before stays readable."""
        self._broken = f"{exc.strerror or exc}"
        self._dropped += len(self._pending)
        self._let_go()
        with contextlib.suppress(OSError):
            self._mcap.salvage("whexar.end", lambda: self._end_values(self._broken))
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
            records=self._mcap.records,
            file_bytes=size,
            dropped=self._dropped,
            errors=self._errors,
            pending=len(self._pending),
            max_pending=self._max_pending,
            write_s=self._write_s,
            flushes=self._flushes,
        )

    def _end_values(self, stopped: str | None, since: float | None = None) -> dict[str, str]:
        """The statistics stored as metadata ``whexar.end``; ``stopped``: why the
        recording stopped before the run's end."""
        stats = self.stats
        write_s = stats.write_s + (0.0 if since is None else monotonic() - since)
        values = {
            "messages": str(stats.messages),
            "link_chunks": str(stats.link_chunks),
            "records": str(stats.records),
            "dropped": str(stats.dropped),
            "errors": str(stats.errors),
            "max_pending": str(stats.max_pending),
            "write_s": f"{write_s:.3f}",
        }
        if stopped is not None:
            values["stopped"] = stopped
        return values

    def _end_file(self, stopped: str | None) -> None:
        """The statistics, MCAP's summary and footer; the file closed."""
        start = monotonic()
        try:
            if self._dropped > self._dropped_logged:
                self._log_dropped()
            self._mcap.close_chunk()  # the statistics come after the last message
            self._mcap.metadata("whexar.end", self._end_values(stopped, start))
            self._mcap.finish()
            self._file.close()
        except OSError as exc:
            self._break(exc)
        self._write_s += monotonic() - start

    def stop(self, reason: str) -> None:
        """End the recording now for ``reason`` (its budget): everything buffered is
        written, then the statistics (``whexar.end`` says why it stopped) and the
        summary; what is handed over from now on is let go. :meth:`close` then only
        returns the statistics."""
        if self._closed or self._stopped is not None:
            return
        self.write_pending()
        self._stopped = reason
        self._let_go()
        self._closed = True
        if self._broken is None:
            self._end_file(reason)

    def close(self) -> RecorderStats:
        """Write everything pending, the statistics and the summary; close the file.

        Idempotent; returns the final :attr:`stats`. Raises :class:`RecordingError` if
        the file could not be written (the robot ran on; the file reads up to its last
        whole record), unless :meth:`keep_budget` reported that as a
        :class:`~whexar.actors.messages.RecordingStopped` event.
        """
        self._last_checks()  # which may stop the recording
        if self._closed:
            return self.stats
        self.write_pending()
        self._closed = True
        if self._broken is None:
            self._end_file(None)
        if self._broken is not None and not self._reported:
            raise RecordingError(f"recording {self.path} failed: {self._broken}")
        return self.stats


def _discard(entry: tuple[Any, ...]) -> None:
    """The hand-over of a recording that has stopped: keeps nothing."""


def _open_unbuffered(path: Path) -> IO[bytes]:
    # Unbuffered: every write is the recorder's own (a chunk at a time), so after a
    # failed one it knows exactly what the file holds (_McapFile.salvage).
    return open(path, "wb", buffering=0)  # closed by Recorder.close()


# --------------------------------------------------------------------------- the file


class _McapFile:
    """A chunked, indexed MCAP file, written with a cheap path for messages.

    ``mcap.writer.Writer`` spends Python work on every message and builds its message
    indexes record by record as a chunk closes: most of what recording cost
    (docs/recording.md). Here a message is one ``struct`` pack and two
    ``bytearray`` appends, and a channel's message index is its (log time, offset) list
    packed at once as a chunk closes. The layout follows the MCAP specification
    (https://mcap.dev/spec, "Records"): magic, Header, Metadata and Attachments, then
    Schema and Channel records (top level, each before the first chunk that uses it) and
    Chunks, each followed by one Message Index per channel it holds; at the end Data End,
    the summary (Schemas, Channels, Statistics, Chunk, Attachment and Metadata Indexes,
    Summary Offsets), Footer and magic. The records written once (all but Message, Chunk
    and Message Index) are ``mcap.records``' own.
    """

    def __init__(self, stream: IO[bytes], chunk_size: int, compression: str) -> None:
        self._stream = stream
        self._offset = 0
        """Bytes written to ``stream`` so far (no ``tell()``: a system call)."""
        self._good = 0
        """Where the last whole record (a chunk: with its message indexes) ends: what
        the file holds for sure after a failed write (:meth:`salvage`)."""
        self._chunk_size = chunk_size
        self._compression = "" if compression == "none" else compression
        self._compression_field = _STRING_LENGTH.pack(len(self._compression)) + (
            self._compression.encode()
        )
        if compression == "zstd":
            self._compress: Callable[[bytes], bytes] = zstandard.ZstdCompressor().compress
        elif compression == "lz4":
            self._compress = lz4.frame.compress
        else:
            self._compress = bytes
        self._builder = RecordBuilder()
        self._chunk = bytearray()
        """The records of the current chunk, uncompressed: messages only."""
        self._index: list[list[int]] = [[]]
        """By channel id: log time, offset, log time, offset … of the current chunk."""
        self._counts: list[int] = [0]
        """Messages written, by channel id (those in the current chunk not yet)."""
        self._schemas: list[Schema] = []
        self._channels: list[Channel] = []
        self._chunk_indexes: list[ChunkIndex] = []
        self._attachment_indexes: list[AttachmentIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self._start_ns: int | None = None
        self._end_ns = 0
        self.sequence = 0
        """The last message's sequence number (MCAP's is a uint32: it wraps)."""
        self.last_ns = 1
        """The last message's log time."""

    @property
    def records(self) -> int:
        """Messages written so far."""
        return sum(self._counts) + sum(len(index) for index in self._index) // 2

    # ------------------------------------------------------------------ once-only records

    def _write(self, data: bytes | bytearray | memoryview) -> None:
        # An unbuffered file may take part of it (a disk filling up), then raise.
        written = self._stream.write(data)
        if written is not None and written < len(data):
            view = memoryview(data)[written:]
            while view:
                written = self._stream.write(view) or 0
                view = view[written:]
        self._offset += len(data)

    def _record(self, record: Any) -> tuple[int, int]:
        """Write a record of ``mcap.records``; returns its offset and length."""
        record.write(self._builder)
        data: bytes = self._builder.end()  # type: ignore[no-untyped-call]
        offset = self._offset
        self._write(data)
        self._good = self._offset
        return offset, len(data)

    def start(self, library: str) -> None:
        """Magic and the Header record (profile ``""``: no well-known profile)."""
        self._write(MAGIC)
        self._record(Header(profile="", library=library))

    def metadata(self, name: str, values: Mapping[str, str]) -> None:
        """A Metadata record, indexed."""
        offset, length = self._record(Metadata(name=name, metadata=dict(values)))
        self._metadata_indexes.append(MetadataIndex(offset=offset, length=length, name=name))

    def attachment(self, name: str, media_type: str, data: bytes) -> None:
        """An Attachment record (times 0), indexed."""
        offset, length = self._record(
            Attachment(create_time=0, log_time=0, name=name, media_type=media_type, data=data)
        )
        self._attachment_indexes.append(
            AttachmentIndex(
                offset=offset,
                length=length,
                create_time=0,
                log_time=0,
                data_size=len(data),
                name=name,
                media_type=media_type,
            )
        )

    def schema(self, name: str, encoding: str, data: bytes) -> int:
        """A Schema record; returns its id (from 1)."""
        schema = Schema(id=len(self._schemas) + 1, name=name, encoding=encoding, data=data)
        self._record(schema)
        self._schemas.append(schema)  # once written: the summary lists what the file holds
        return schema.id

    def channel(
        self, topic: str, message_encoding: str, schema_id: int, metadata: Mapping[str, str]
    ) -> int:
        """A Channel record; returns its id (from 1)."""
        channel = Channel(
            id=len(self._channels) + 1,
            topic=topic,
            message_encoding=message_encoding,
            schema_id=schema_id,
            metadata=dict(metadata),
        )
        self._record(channel)
        self._channels.append(channel)
        self._index.append([])
        self._counts.append(0)
        return channel.id

    # ------------------------------------------------------------------ messages

    def message(self, channel_id: int, ns: int, data: bytes) -> None:
        """A Message record (log and publish time ``ns``) into the current chunk."""
        chunk = self._chunk
        index = self._index[channel_id]
        index.append(ns)
        index.append(len(chunk))
        self.sequence = sequence = (self.sequence + 1) & 0xFFFFFFFF
        chunk += _MESSAGE_HEAD.pack(_OP_MESSAGE, 22 + len(data), channel_id, sequence, ns, ns)
        chunk += data
        self.last_ns = ns
        if len(chunk) >= self._chunk_size:
            self.close_chunk()

    def close_chunk(self) -> None:
        """Compress the current chunk and write it with its message indexes (if it holds
        anything). Nothing is counted until all of it is written."""
        chunk = self._chunk
        if not chunk:
            return
        records = bytes(chunk)
        compressed = self._compress(records)
        used = [(cid, index) for cid, index in enumerate(self._index) if index]
        start = min(min(index[0::2]) for _, index in used)
        end = max(max(index[0::2]) for _, index in used)
        field = self._compression_field
        # Chunk: opcode, length; start, end, uncompressed size, CRC; compression; records.
        head = _CHUNK_HEAD.pack(
            _OP_CHUNK,
            8 + 8 + 8 + 4 + len(field) + 8 + len(compressed),
            start,
            end,
            len(records),
            zlib.crc32(records),
        )
        chunk_offset = self._offset
        self._write(head + field + _LENGTH.pack(len(compressed)))
        self._write(compressed)
        chunk_length = self._offset - chunk_offset
        # One Message Index per channel: its (log time, offset) pairs packed at once.
        offsets: dict[int, int] = {}
        pieces = []
        index_offset = position = self._offset
        for cid, index in used:
            pairs = array("Q", index)
            if _BIG_ENDIAN:
                pairs.byteswap()
            body = pairs.tobytes()
            offsets[cid] = position
            pieces.append(_INDEX_HEAD.pack(_OP_MESSAGE_INDEX, 6 + len(body), cid, len(body)))
            pieces.append(body)
            position += _INDEX_HEAD.size + len(body)
        self._write(b"".join(pieces))
        self._good = self._offset
        self._chunk = bytearray()
        for cid, index in used:
            self._counts[cid] += len(index) // 2
            index.clear()
        self._chunk_indexes.append(
            ChunkIndex(
                message_start_time=start,
                message_end_time=end,
                chunk_start_offset=chunk_offset,
                chunk_length=chunk_length,
                message_index_offsets=offsets,
                message_index_length=self._offset - index_offset,
                compression=self._compression,
                compressed_size=len(compressed),
                uncompressed_size=len(records),
            )
        )
        self._start_ns = start if self._start_ns is None else min(self._start_ns, start)
        self._end_ns = max(self._end_ns, end)

    def flush(self) -> None:
        """Close the current chunk and hand everything to the operating system."""
        self.close_chunk()
        self._stream.flush()

    def finish(self) -> None:
        """The last chunk, Data End, the summary, the Footer and the closing magic."""
        self.close_chunk()
        end = self._good
        try:
            self._finish()
        except OSError:
            self._good = end  # the data section's end: what a salvage cuts back to
            raise

    def _finish(self) -> None:
        self._record(DataEnd(data_section_crc=0))  # 0: not computed (optional)
        summary_start = self._offset
        builder = RecordBuilder()
        groups: list[SummaryOffset] = []

        def group(opcode: Opcode, records: Sequence[Any]) -> None:
            start = builder.count
            for record in records:
                record.write(builder)
            groups.append(SummaryOffset(opcode, summary_start + start, builder.count - start))

        statistics = Statistics(
            message_count=sum(self._counts),
            schema_count=len(self._schemas),
            channel_count=len(self._channels),
            attachment_count=len(self._attachment_indexes),
            metadata_count=len(self._metadata_indexes),
            chunk_count=len(self._chunk_indexes),
            message_start_time=self._start_ns or 0,
            message_end_time=self._end_ns,
            channel_message_counts={cid: count for cid, count in enumerate(self._counts) if count},
        )
        group(Opcode.SCHEMA, self._schemas)
        group(Opcode.CHANNEL, self._channels)
        group(Opcode.STATISTICS, [statistics])
        group(Opcode.CHUNK_INDEX, self._chunk_indexes)
        group(Opcode.ATTACHMENT_INDEX, self._attachment_indexes)
        group(Opcode.METADATA_INDEX, self._metadata_indexes)
        offsets_start = summary_start + builder.count
        for offset in groups:
            offset.write(builder)
        summary: bytes = builder.end()  # type: ignore[no-untyped-call]
        # The Footer's CRC covers the summary and the Footer's own fields before it.
        footer = _FOOTER_HEAD.pack(_OP_FOOTER, 20, summary_start, offsets_start)
        crc = zlib.crc32(footer, zlib.crc32(summary))
        self._write(summary)
        self._write(footer)
        self._write(_CRC.pack(crc))
        self._write(MAGIC)
        self._good = self._offset
        self._stream.flush()

    def finish_bare(self) -> None:
        """Data End and a Footer with no summary (summary start 0, CRC 0: "not
        available", which the specification allows): the least that ends a file."""
        end = self._good
        try:
            self._record(DataEnd(data_section_crc=0))
            self._write(_FOOTER_HEAD.pack(_OP_FOOTER, 20, 0, 0) + _CRC.pack(0) + MAGIC)
        except OSError:
            self._good = end
            raise
        self._good = self._offset
        self._stream.flush()

    def salvage(self, name: str, values: Callable[[], Mapping[str, str]]) -> bool:
        """After a failed write (a full disk): cut the file back to its last whole record,
        losing the chunk that was being written, and end it there as fully as the disk
        lets: metadata ``name`` (``values()``, once cut back) and the summary; else a
        bare footer (:meth:`finish_bare`); else nothing more, and the file ends at a
        whole record (readers read every message, and say that the footer is missing).
        Returns whether it has a footer; raises :class:`OSError` if it cannot even be
        cut back."""
        self._cut(self._good)
        mark = self._good
        try:
            self.metadata(name, values())
            self.finish()
            return True
        except OSError:
            self._cut(mark)
        try:
            self.finish_bare()
            return True
        except OSError:
            self._cut(mark)
        return False

    def _cut(self, offset: int) -> None:
        """The file cut back to ``offset``; the chunk being filled forgotten."""
        self._chunk = bytearray()
        for index in self._index:
            index.clear()
        self._stream.truncate(offset)
        self._stream.seek(offset)
        self._offset = self._good = offset


def _unencodable(msg: Any) -> Any:
    raise RecordingError(f"type {type(msg).__name__} cannot be recorded")


_UNENCODABLE: MessageCodec[Any] = MessageCodec(
    cls=Message, schema={}, schema_data=b"{}", to_json=_unencodable, from_json=_unencodable
)
"""Stands in for the codec of a type that cannot be encoded: every message fails."""
