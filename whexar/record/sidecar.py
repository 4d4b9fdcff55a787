"""The recorder in a process of its own: the runtime hands over and packs, nothing more.

Theory of operation
-------------------
:class:`RecorderProcess` has the hand-over methods of :class:`~whexar.record.writer.Recorder`
(the runtime's observer ``__call__``, :meth:`~RecorderProcess.link_bytes`,
:meth:`~RecorderProcess.transform`, :meth:`~RecorderProcess.robot_description`) and its
owner's (:meth:`~RecorderProcess.write_pending`, :meth:`~RecorderProcess.run`,
:meth:`~RecorderProcess.close`, ``stats``, ``failure``), so the runtime cannot tell them
apart. The hand-over appends a reference to a bounded buffer, as in-process. Between
cycles :meth:`~RecorderProcess.write_pending` packs what is buffered into msgpack frames
(msgspec, one C call per :data:`PACK_SLICE` entries, messages as they are, dataclasses
by field name) and writes them to a pipe without waiting.

A child process (``python -m whexar.record.sidecar``) reads the frames, rebuilds each
message as its own type (msgspec decodes a frame into typed entries and each message's
fields with its own type's decoder; floats travel as IEEE doubles, so the rebuilt
message equals the original) and hands it to a :class:`Recorder` of its own,
which encodes, compresses and writes the MCAP file exactly as in-process: the file is
the same, its bytes too. The child learns a message type by its ``module:QualName``
the first time one is handed over and imports it; a type it cannot import (defined in
``__main__`` or inside a function) is counted and logged on ``/log`` as not recorded.

Why: writing in-process costs the runtime several times the 5 % of its CPU a
recording may take (``whexar bench record``; docs/recording.md has the figures), half
of it encoding, compressing and indexing, the rest its working set slowing the bus,
the emulator and the actors beside it. Here the runtime only hands over, packs and
sends; the child does the rest on another core (a Raspberry Pi 4 has four).

Crash safety: the child ignores SIGINT and SIGTERM, which a terminal or a service
manager sends to the whole process group, and ends the file (its summary and footer)
when the pipe closes, whoever closed it: a runtime killed with SIGKILL leaves a
complete file, holding everything it had written to the pipe (what it packs every
:data:`PACK_PERIOD_S`). The child itself flushes every ``flush_period_s`` as
in-process, so if both die the file reads up to its last flush.

A full disk: the child's recorder ends the file at its last whole record, as fully as
the disk lets (:class:`~whexar.record.writer.Recorder`), writes its report and exits at
once; the runtime's next send finds the pipe closed and reads why, and its
:meth:`~whexar.record.writer.HandOver.keep_budget` makes that a
:class:`~whexar.actors.messages.RecordingStopped` event.

The recordings' budget (:mod:`whexar.record.budget`) is kept by the child, so that the
control loop never lists the folder nor deletes a file: the runtime describes its guard
in the first frame; the child checks once before it opens its file (old recordings go
before anything is written), then every ``CHECK_PERIOD_S`` between frames (at most one
``flush_period_s`` late: it wakes that often), and tells each plan that acts as one JSON
line on its standard output. The runtime reads those lines without waiting in
:meth:`~RecorderProcess.keep_budget`, every :data:`PACK_PERIOD_S`, and makes them the
events, where the runtime's other events are: a deletion is reported at most one pack
period after the child made it. A stop is one more entry after that event, after which
the child ends the file saying why, and the pipe closes; the child writes on until the
entry comes (one pack period of the run more). At :meth:`~RecorderProcess.close` the
runtime asks the child for its last plans and waits for its answer: what a check did
after the runtime's last look is still reported, to this recorder and in the file.

Bounded memory: the buffer holds ``max_pending`` entries and the unsent frames
``max_unsent_bytes`` (a child that cannot keep up, or has not started yet: the pipe
itself holds a second or two of a run). Past either, what does not fit is dropped,
counted, and logged in the file.
"""

from __future__ import annotations

import contextlib
import dataclasses
import fcntl
import importlib
import json
import os
import select
import signal
import struct
import subprocess
import sys
import time
from collections import deque
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Final

import msgspec

from whexar.record.budget import BudgetGuard, Plan
from whexar.record.encoding import RecordingError, type_path
from whexar.record.writer import (
    _LINK,
    _MESSAGE,
    _TRANSFORM,
    HandOver,
    Recorder,
    RecorderStats,
)
from whexar.runtime.clock import monotonic
from whexar.runtime.messages import MESSAGE_TYPES, Message

__all__ = ["PACK_PERIOD_S", "PACK_SLICE", "AnyRecorder", "RecorderProcess"]

PACK_PERIOD_S: Final = 0.05
"""How often :meth:`RecorderProcess.run` packs and sends: each send is a system call
that wakes the child on another core (an inter-processor interrupt, dear in a virtual
machine), so five bus cycles at a time; a runtime killed with SIGKILL loses at most
this much, and a write still packs only a few hundred entries (docs/recording.md)."""
PACK_SLICE: Final = 256
"""Entries packed per frame: one C call's worth, short enough to keep a write's budget."""
PIPE_BYTES: Final = 1 << 20
"""The pipe's size asked for (Linux's default ceiling for an unprivileged process)."""
MAX_UNSENT_BYTES: Final = 64 << 20
"""Packed frames kept while the pipe is full, at most (about 100 s of the course)."""
CLOSE_TIMEOUT_S: Final = 120.0
"""How long :meth:`RecorderProcess.close` waits for the child to end the file."""
GONE_WAIT_S: Final = 1.0
"""How long a failed pipe waits for the child to end: it closed its end, so it is
ending (a full disk: its file ended as far as the disk let it, its report written)."""
NICENESS: Final = 10
"""The child's niceness: on a busy machine the runtime gets the CPU first; the child
catches up from the pipe and its bounded buffer."""
_F_SETPIPE_SZ: Final = getattr(fcntl, "F_SETPIPE_SZ", 1031)
_FRAME: Final = struct.Struct("<I")  # a frame: its length, then one msgpack array

# Kinds of entries in a frame: (kind, …) arrays; the hand-over's three, then these.
_TYPE, _DESCRIPTION, _FAILED, _DROPPED, _STOP, _QUIET = range(_TRANSFORM + 1, _TRANSFORM + 7)


class RecorderProcess(HandOver):
    """Records a run into the MCAP file ``path`` from a process of its own (module doc).

    ``metadata``, ``attachments``, ``guard`` and ``options`` (``chunk_size``,
    ``flush_period_s``, ``compression``, ``joint_states``, ``event_log``) as
    :class:`Recorder`'s; there is no live view (it needs the messages in this process:
    use :class:`Recorder`). The budget ``guard`` describes (its disk the local one) is
    kept by the recording process, which tells this one what it did: the events are
    made here, where the runtime is. ``max_pending`` bounds the buffer between
    :meth:`write_pending` calls and ``max_unsent_bytes`` the packed frames the pipe has
    not taken yet. ``opener`` (``module:name``) is the callable the recording process
    opens its file with, as :class:`Recorder`'s ``opener`` (a test's full disk).
    """

    period_s = PACK_PERIOD_S

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        metadata: Mapping[str, str] | None = None,
        attachments: Mapping[str, str | bytes] | None = None,
        max_pending: int = 100_000,
        max_unsent_bytes: int = MAX_UNSENT_BYTES,
        guard: BudgetGuard | None = None,
        opener: str | None = None,
        **options: Any,
    ) -> None:
        if max_pending <= 0 or max_unsent_bytes <= 0:
            raise RecordingError(
                f"max_pending and max_unsent_bytes must be > 0 (got {max_pending}, "
                f"{max_unsent_bytes})"
            )
        self.path = Path(path)
        self.max_pending = max_pending
        self.max_unsent_bytes = max_unsent_bytes
        self._start_budget(None)  # kept by the recording process: none of it here
        self._guard = guard
        try:
            budget = None if guard is None else guard.describe()
        except TypeError as exc:
            raise RecordingError(f"a recording process keeps no such budget: {exc}") from None
        try:  # a path that cannot be written is the caller's error, now, not the child's
            with open(self.path, "wb"):
                pass
        except OSError as exc:
            raise RecordingError(f"cannot record to {self.path}: {exc.strerror or exc}") from None
        self._encoder = msgspec.msgpack.Encoder()
        self._pending: deque[tuple[Any, ...]] = deque()
        self._append = self._pending.append
        self._names: dict[type, str] = {}
        self._declared: list[tuple[Any, ...]] = []
        self._out: deque[memoryview] = deque()
        self._unsent = 0
        self._dropped = self._dropped_sent = 0
        self._max_pending = 0
        self._write_s = 0.0
        self._closed = False
        self._broken: str | None = None
        self._final: RecorderStats | None = None
        self._report: dict[str, Any] | None = None
        """What the child said as it ended (its statistics, its failure), once read."""
        self._heard = bytearray()
        """What the child said so far, up to the end of a line not yet come."""
        self._quiet = False
        """The child said it keeps the budget no more (:meth:`_last_checks`)."""

        self._child = subprocess.Popen(
            [sys.executable, "-m", "whexar.record.sidecar"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
        )
        assert self._child.stdin is not None
        assert self._child.stdout is not None
        self._fd = self._child.stdin.fileno()
        self._said = self._child.stdout.fileno()
        os.set_blocking(self._said, False)  # read between cycles: never wait
        with contextlib.suppress(OSError):
            fcntl.fcntl(self._fd, _F_SETPIPE_SZ, PIPE_BYTES)
        os.set_blocking(self._fd, False)
        start = {
            "path": str(self.path.resolve()),
            "metadata": {str(k): str(v) for k, v in (metadata or {}).items()},
            "attachments": dict(attachments or {}),
            "options": options,
            "opener": opener,
            "budget": budget,
            # Where this process finds modules, for the message types of extensions
            # (appended by the child, after its own: nothing here shadows its start-up).
            "sys_path": [p for p in sys.path if p],
        }
        self._queue(self._encoder.encode(start))
        self._send()

    # ------------------------------------------------------------------ hand-over (O(1))

    def __call__(self, channel: str, msg: Message) -> None:
        """The runtime's observer: buffer ``msg``, published on ``channel``."""
        if len(self._pending) >= self.max_pending:
            self._drop_oldest()
        cls = msg.__class__
        name = self._names.get(cls)
        if name is None:
            name = self._declare(cls)
        self._append((_MESSAGE, channel, name, msg))

    def robot_description(self, urdf: str) -> None:
        """The robot's URDF on ``/robot_description``: as :meth:`Recorder.robot_description`."""
        self._append((_DESCRIPTION, urdf))

    def _declare(self, cls: type) -> str:
        name = cls.__name__
        self._names[cls] = name
        self._declared.append((_TYPE, name, type_path(cls)))
        return name

    # ------------------------------------------------------------------ packing

    def write_pending(self, budget_s: float | None = None) -> int:
        """Pack everything buffered and hand it to the pipe without waiting; returns how
        many entries. With ``budget_s``, stop after about that many wall seconds.
        Never raises: a child that is gone ends the recording (``failure``) and the
        robot runs on."""
        start = monotonic()
        if self._stopped is not None and not self._closed:
            self._drain()
            return 0
        if not self._writable():
            return 0
        pending = self._pending
        done = 0
        while pending or self._declared:
            if len(pending) <= PACK_SLICE:
                batch = list(pending)
                pending.clear()
            else:
                batch = [pending.popleft() for _ in range(PACK_SLICE)]
            count = len(batch)
            head = self._declared
            self._declared = []
            dropped = self._dropped - self._dropped_sent
            if dropped:
                head.append((_DROPPED, dropped))
            if head:
                batch[:0] = head
            if self._queue(self._pack(batch)):
                self._dropped_sent += dropped
            else:
                self._dropped += count
            done += count
            if budget_s is not None and monotonic() - start > budget_s:
                break
        self._send()
        self._write_s += monotonic() - start
        return done

    def _pack(self, batch: list[tuple[Any, ...]]) -> bytes:
        try:
            return self._encoder.encode(batch)
        except Exception:  # a value msgpack cannot hold: find it below
            pass
        kept: list[tuple[Any, ...]] = []
        for entry in batch:
            try:
                self._encoder.encode(entry)
            except Exception as exc:  # a bad value must not stop the robot
                if entry[0] == _MESSAGE:
                    t = getattr(entry[3], "t", 0.0)
                    reason = f"cannot be handed to the recording process: {exc}"
                    kept.append((_FAILED, entry[1], entry[2], float(t), reason))
                else:
                    self._dropped += 1
                continue
            kept.append(entry)
        return self._encoder.encode(kept)

    def _queue(self, data: bytes) -> bool:
        """Add one frame to what is to be sent, unless that would pass the bound."""
        if self._unsent + len(data) + _FRAME.size > self.max_unsent_bytes:
            return False
        self._out.append(memoryview(_FRAME.pack(len(data)) + data))
        self._unsent += len(data) + _FRAME.size
        return True

    def _send(self) -> None:
        """Write to the pipe what it takes now (all of it once the pipe blocks)."""
        out = self._out
        try:
            while out:
                view = out[0]
                sent = os.write(self._fd, view)
                self._unsent -= sent
                if sent < len(view):
                    out[0] = view[sent:]
                    return
                out.popleft()
        except BlockingIOError:
            return
        except OSError as exc:
            self._gone(exc)

    def _gone(self, exc: OSError) -> None:
        """The pipe failed: the child ended (a full disk ends it at once, its file ended
        as far as the disk let it) or was killed. Why, from its report if it left one."""
        self._dropped += len(self._pending)
        self._let_go()
        self._out.clear()
        self._unsent = 0
        self._hang_up()
        code = None
        with contextlib.suppress(subprocess.TimeoutExpired):
            code = self._child.wait(timeout=GONE_WAIT_S)  # it is ending: its pipe is closed
        if code is not None:
            self._read_report(wait=False)
        failure = (self._report or {}).get("failure")
        if failure:
            self._broken = str(failure)
        elif code is not None:
            self._broken = f"the recording process ended (exit status {code})"
        else:
            self._broken = f"the pipe to the recording process failed: {exc.strerror or exc}"

    def _hang_up(self) -> None:
        """Close this end of the pipe: the child writes what it has and ends the file."""
        stdin = self._child.stdin
        if stdin is not None:
            self._child.stdin = None  # so that communicate() does not flush it again
            with contextlib.suppress(OSError):
                stdin.close()

    def _read_report(self, *, wait: bool) -> None:
        """The child's last words (JSON on its standard output): its statistics and its
        failure; with ``wait``, after waiting up to :data:`CLOSE_TIMEOUT_S` for it to end."""
        if self._report is not None:
            return
        timeout = CLOSE_TIMEOUT_S if wait else GONE_WAIT_S
        stdout = self._child.stdout
        if stdout is not None and not stdout.closed:
            os.set_blocking(self._said, True)
        try:
            out, _ = self._child.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            self._child.kill()
            self._child.communicate()
            out = b""
            self._broken = f"the recording process did not end the file in {timeout:g} s"
        self._heard += out or b""
        found: dict[str, Any] = {}
        for said in self._lines(final=True):
            if "stats" in said or "failure" in said:
                found = said
        self._report = found
        if "stats" in found:
            stats = RecorderStats(**found["stats"])
            self._final = dataclasses.replace(
                stats,
                dropped=max(stats.dropped, self._dropped),
                pending=0,
                max_pending=max(stats.max_pending, self._max_pending),
            )

    # ------------------------------------------------------------------ the budget

    def _take_plans(self) -> list[Plan]:
        """What the child's checks did, as far as it has said (one read that does not
        wait: nothing, most times)."""
        self._hear()
        return super()._take_plans()

    def _hear(self, timeout: float = 0.0) -> bool:
        """Read what the child said, waiting up to ``timeout`` for it; ``False`` once it
        closed its standard output (it ended)."""
        stdout = self._child.stdout
        if stdout is None or stdout.closed:
            return False
        if timeout > 0 and not select.select([self._said], [], [], timeout)[0]:
            return True
        going = True
        try:
            while chunk := os.read(self._said, 1 << 16):
                self._heard += chunk
            going = False  # the end of its output
        except BlockingIOError:
            pass  # all it said so far
        except OSError:
            going = False
        self._lines(final=False)
        return going

    def _lines(self, *, final: bool) -> list[dict[str, Any]]:
        """The whole lines heard (with ``final``, the rest too): the child's plans go to
        be reported, its acknowledgement is noted; the others are returned."""
        heard = self._heard
        end = len(heard) if final else heard.rfind(b"\n") + 1
        lines = bytes(heard[:end]).splitlines()
        del heard[:end]
        others = []
        for line in lines:
            try:
                said = json.loads(line)
            except ValueError:
                continue
            if not isinstance(said, dict):
                continue
            if "plan" in said:
                self._plans.append(Plan.from_json(said["plan"]))
            elif "quiet" in said:
                self._quiet = True
            else:
                others.append(said)
        return others

    def _last_checks(self) -> None:
        """At :meth:`close`: tell the child to keep the budget no more and wait for its
        answer, which follows what its last check said; then report every plan heard,
        into the file (the runtime has ended)."""
        live = self._guard is not None and self._stopped is None and self._broken is None
        if live and self._child.stdin is not None:
            self.write_pending()
            self._queue(self._encoder.encode([(_QUIET,)]))
            os.set_blocking(self._fd, True)
            while self._out and self._broken is None:
                self._send()
            deadline = monotonic() + CLOSE_TIMEOUT_S
            while not self._quiet and self._broken is None and monotonic() < deadline:
                if not self._hear(timeout=deadline - monotonic()):
                    break
        plans, self._plans = self._plans, []
        if self._stopped is None:
            self._report_plans(None, plans)

    # ------------------------------------------------------------------ end

    @property
    def stats(self) -> RecorderStats:
        """What the recorder did: the child's figures once it ended; before, only this
        side's (``pending``, ``max_pending``, ``dropped``, ``write_s``, the file's size
        so far), the child's counts being 0."""
        if self._final is not None:
            return self._final
        try:
            size = self.path.stat().st_size
        except OSError:
            size = 0
        return RecorderStats(
            messages=0,
            link_chunks=0,
            records=0,
            file_bytes=size,
            dropped=self._dropped,
            errors=0,
            pending=len(self._pending),
            max_pending=self._max_pending,
            write_s=self._write_s,
            flushes=0,
        )

    @property
    def _ended(self) -> bool:
        # Stopped, and the pipe closed: the child ends the file on its own.
        return self._stopped is not None and self._child.stdin is None

    def stop(self, reason: str) -> None:
        """End the recording now for ``reason`` (its budget), without waiting: what is
        buffered is packed and sent, then the pipe is closed, and the child writes it
        all and ends the file (:meth:`run` sends what the pipe did not take yet first);
        what is handed over from now on is let go. :meth:`close` waits for the child."""
        if self._closed or self._stopped is not None:
            return
        self.write_pending()
        if self._broken is None:
            self._queue(self._encoder.encode([(_STOP, reason)]))
        self._stopped = reason
        self._let_go()
        self._drain()

    def _drain(self) -> None:
        """After a stop: send what the pipe takes; once all is sent, hang up."""
        if self._broken is None and self._out:
            self._send()
        if not self._out:
            self._hang_up()

    def close(self) -> RecorderStats:
        """Send everything pending, let the child end the file, and wait for it.

        Idempotent; returns the final :attr:`stats` (``write_s`` is the child's writing
        time, ``process_cpu_s`` its CPU). Raises :class:`RecordingError` if the file
        could not be written to its end, unless :meth:`keep_budget` reported that as a
        :class:`~whexar.actors.messages.RecordingStopped` event.
        """
        if self._closed:
            if self._broken is not None and not self._reported:
                raise RecordingError(f"recording {self.path} failed: {self._broken}")
            return self.stats
        self._last_checks()
        self.write_pending()
        self._closed = True
        if self._child.stdin is not None:
            os.set_blocking(self._fd, True)  # the rest now, waiting for the child to take it
            while self._out and self._broken is None:
                self._send()
        self._hang_up()
        self._read_report(wait=True)
        found = self._report or {}
        if found.get("failure"):
            self._broken = str(found["failure"])
        elif self._broken is None and self._final is None:
            self._broken = f"the recording process failed (exit status {self._child.returncode})"
        if self._broken is not None and not self._reported:
            raise RecordingError(f"recording {self.path} failed: {self._broken}")
        return self.stats


AnyRecorder = Recorder | RecorderProcess
"""Either recorder: what ``whexar sim`` and ``whexar run`` record through."""


# --------------------------------------------------------------------------- the child


class _Frames:
    """Length-prefixed frames from a file descriptor."""

    EOF: Final = b""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self.buf = bytearray()
        self.pos = 0

    def next(self, timeout: float | None) -> bytes | None:
        """The next frame; ``None`` if none came within ``timeout``; :attr:`EOF` at the
        end (a frame cut by the writer's death is dropped)."""
        while True:
            buf, pos = self.buf, self.pos
            if len(buf) - pos >= _FRAME.size:
                (size,) = _FRAME.unpack_from(buf, pos)
                end = pos + _FRAME.size + size
                if len(buf) >= end:
                    frame = bytes(buf[pos + _FRAME.size : end])
                    self.pos = end
                    if end > len(buf) // 2:  # compact now and then, not per frame
                        del buf[:end]
                        self.pos = 0
                    return frame
            if timeout is not None and not select.select([self.fd], [], [], timeout)[0]:
                return None
            chunk = os.read(self.fd, 1 << 20)
            if not chunk:
                return self.EOF
            buf += chunk


def _import(name: str, path: str) -> type[Message] | str:
    """Message type ``name`` from ``module:QualName``, or why it cannot be had here."""
    cls = MESSAGE_TYPES.get(name)
    if cls is not None and type_path(cls) == path:
        return cls
    module, _, qualname = path.partition(":")
    if module == "__main__" or "<locals>" in qualname:
        return (
            f"type {path} is defined where a recording process cannot import it; "
            "define it in a module, or record in-process (whexar.record.writer.Recorder)"
        )
    try:
        importlib.import_module(module)
    except Exception as exc:  # whatever the module raises, say it
        return f"module {module} could not be imported by the recording process: {exc}"
    cls = MESSAGE_TYPES.get(name)
    if cls is None or type_path(cls) != path:
        return f"type {path} is not a registered message type in the recording process"
    return cls


# The entries of a frame as the child reads them: msgpack arrays whose first item is the
# kind, each decoded straight into its struct; a message's fields stay raw bytes until
# its own type decodes them (a third of the cost of decoding to dicts, then converting).
class _MessageEntry(msgspec.Struct, array_like=True, tag=_MESSAGE):
    channel: str
    name: str
    payload: msgspec.Raw


class _LinkEntry(msgspec.Struct, array_like=True, tag=_LINK):
    link: str
    direction: str
    t: float | int
    data: bytes


class _TransformEntry(msgspec.Struct, array_like=True, tag=_TRANSFORM):
    t: float | int
    parent: str
    child: str
    # An int stays an int, as the in-process recorder writes it.
    translation: tuple[float | int, ...]
    rotation_xyzw: tuple[float | int, ...]


class _TypeEntry(msgspec.Struct, array_like=True, tag=_TYPE):
    name: str
    path: str


class _DescriptionEntry(msgspec.Struct, array_like=True, tag=_DESCRIPTION):
    urdf: str


class _FailedEntry(msgspec.Struct, array_like=True, tag=_FAILED):
    channel: str
    name: str
    t: float | int
    reason: str


class _DroppedEntry(msgspec.Struct, array_like=True, tag=_DROPPED):
    count: int


class _StopEntry(msgspec.Struct, array_like=True, tag=_STOP):
    reason: str


class _QuietEntry(msgspec.Struct, array_like=True, tag=_QUIET):
    pass


_Entry = (
    _MessageEntry
    | _LinkEntry
    | _TransformEntry
    | _TypeEntry
    | _DescriptionEntry
    | _FailedEntry
    | _DroppedEntry
    | _StopEntry
    | _QuietEntry
)


class _Child:
    """What the child does with each entry: hands it to its :class:`Recorder`."""

    def __init__(self, recorder: Recorder) -> None:
        self.recorder = recorder
        self.frames = msgspec.msgpack.Decoder(list[_Entry])
        self.types: dict[str, msgspec.msgpack.Decoder[Any] | str] = {}
        self.quiet = False
        """The runtime asked for the budget's last plans (it is closing)."""

    def frame(self, data: bytes) -> None:
        recorder = self.recorder
        try:
            entries = self.frames.decode(data)
        except msgspec.MsgspecError as exc:  # a bug, not an input: say it, go on
            recorder.not_recorded("?", "frame", recorder.last_t, f"unreadable frame: {exc}")
            return
        for entry in entries:
            if entry.__class__ is _MessageEntry:
                self.message(entry)
            elif entry.__class__ is _LinkEntry:
                recorder.link_bytes(entry.link, entry.direction, entry.t, entry.data)
            elif entry.__class__ is _TransformEntry:
                recorder.transform(
                    entry.t, entry.parent, entry.child, entry.translation, entry.rotation_xyzw
                )
            elif entry.__class__ is _TypeEntry:
                found = _import(entry.name, entry.path)
                self.types[entry.name] = (
                    found if isinstance(found, str) else msgspec.msgpack.Decoder(found)
                )
            elif entry.__class__ is _DescriptionEntry:
                recorder.robot_description(entry.urdf)
            elif entry.__class__ is _FailedEntry:
                recorder.not_recorded(entry.channel, entry.name, entry.t, entry.reason)
            elif entry.__class__ is _DroppedEntry:
                recorder.dropped_elsewhere(entry.count)
            elif entry.__class__ is _StopEntry:
                recorder.stop(entry.reason)  # its budget: the file ends now, saying why
            elif entry.__class__ is _QuietEntry:
                self.quiet = True

    def message(self, entry: _MessageEntry) -> None:
        decoder = self.types.get(entry.name, f"type {entry.name} was never declared")
        if not isinstance(decoder, str):
            try:
                msg = decoder.decode(entry.payload)
            except msgspec.MsgspecError as exc:
                decoder = f"cannot be rebuilt: {exc}"
            else:
                self.recorder(entry.channel, msg)
                return
        try:
            t = float(msgspec.msgpack.decode(entry.payload).get("t", 0.0))
        except (msgspec.MsgspecError, AttributeError, TypeError, ValueError):
            t = self.recorder.last_t
        self.recorder.not_recorded(entry.channel, entry.name, t, decoder)


def _opener(path: str) -> Any:
    """The callable ``module:name`` names (:class:`RecorderProcess`'s ``opener``)."""
    module, _, name = path.partition(":")
    return getattr(importlib.import_module(module), name)


def main() -> int:
    """The child: frames from standard input into a :class:`Recorder`; its statistics
    (JSON) to standard output once the pipe closes."""
    for sig in (signal.SIGINT, signal.SIGTERM):  # the parent decides when it ends
        signal.signal(sig, signal.SIG_IGN)
    with contextlib.suppress(OSError):  # the control loop comes first for the CPU
        os.nice(NICENESS)
    frames = _Frames(sys.stdin.buffer.fileno())
    first = frames.next(None)
    if not first:
        return 1  # the parent went before it began
    start = msgspec.msgpack.decode(first)
    sys.path.extend(p for p in start["sys_path"] if p not in sys.path)
    budget = _Budget(start.get("budget"))
    budget.check()  # before the file is opened: old recordings go first
    try:
        opener = None if start.get("opener") is None else _opener(start["opener"])
        recorder = Recorder(
            start["path"],
            metadata=start["metadata"],
            attachments=start["attachments"],
            opener=opener,
            **start["options"],
        )
    except RecordingError as exc:
        _say({"failure": str(exc)})
        return 1
    child = _Child(recorder)
    while recorder.failure is None:
        frame = frames.next(recorder.flush_period_s)
        if frame is not None:
            if frame == _Frames.EOF:
                break
            child.frame(frame)
        recorder.write_pending()  # and, every flush period, a flush
        if child.quiet:
            budget.quiet()
        elif recorder.stopped is None:
            budget.check()
    # A full disk ends the recording at once (the file ended as far as the disk let
    # it): the runtime learns it from the pipe, closed as this process ends.
    with contextlib.suppress(RecordingError):
        recorder.close()
    failure, stats = recorder.failure, recorder.stats
    stats = dataclasses.replace(stats, process_cpu_s=time.process_time())
    _say({"stats": dataclasses.asdict(stats), "failure": failure})
    return 0


class _Budget:
    """The child's side of the budget: the runtime's guard, described, checked when due
    (no more after a plan that stops the recording, nor once the runtime asked for the
    last plans), each plan that acts told as a line."""

    def __init__(self, described: dict[str, Any] | None) -> None:
        self.guard = None if described is None else BudgetGuard.described(described)
        self.checking = self.guard is not None
        self.said_quiet = False

    def check(self) -> None:
        """Keep the budget, if a check is due; tell what was done."""
        guard = self.guard
        if guard is None or not self.checking or not guard.due():
            return
        found = guard.check()
        if found.acts:
            _say({"plan": found.to_json()})
        if found.stop is not None:
            self.checking = False

    def quiet(self) -> None:
        """The runtime is closing: no more checks; say so, after the last plan."""
        self.checking = False
        if self.guard is not None and not self.said_quiet:
            _say({"quiet": True})
            self.said_quiet = True


def _say(what: dict[str, Any]) -> None:
    """One line to the runtime on standard output (JSON), at once."""
    sys.stdout.write(json.dumps(what) + "\n")
    sys.stdout.flush()


if __name__ == "__main__":
    sys.exit(main())
