"""What a recording holds, at a glance: ``whexar log info``.

Theory of operation
-------------------
One pass over :meth:`Recording.records <whexar.record.reader.Recording.records>`
without decoding (bytes and times only), which counts messages per topic and schema,
notes each one's first and last time and its longest gap, and decodes only the
runtime's events, to sort them by level (:func:`whexar.record.foxglove.event_level`)
and quote the errors. The recorder's own complaints (entries dropped, a message it
could not encode) are ``/log`` entries named ``recorder``; its statistics are the
``whexar.end`` metadata of a file that was closed. The result is a plain
:class:`LogInfo`, printed by :func:`format_info` or as JSON by :meth:`LogInfo.as_dict`.
"""

from __future__ import annotations

import json
import os
from collections import Counter
from dataclasses import asdict, dataclass, field
from typing import Any

from whexar.record.encoding import EncodingError, codec_by_name
from whexar.record.foxglove import LogLevel, event_level, event_text
from whexar.record.reader import Recording
from whexar.runtime.messages import MESSAGE_TYPES, Event

__all__ = ["ChannelInfo", "LogInfo", "Problem", "format_info", "summarize"]

MAX_QUOTED = 10
"""Errors quoted in full; the rest are counted."""


@dataclass(slots=True)
class ChannelInfo:
    """One topic and schema of a recording."""

    topic: str
    schema: str
    count: int = 0
    first_s: float = 0.0
    last_s: float = 0.0
    longest_gap_s: float = 0.0
    """The longest interval between two consecutive messages."""
    gap_at_s: float = 0.0
    """Where that interval starts."""

    @property
    def rate_hz(self) -> float | None:
        """Messages per second between the first and the last (``None`` below two)."""
        span = self.last_s - self.first_s
        return (self.count - 1) / span if self.count > 1 and span > 0 else None


@dataclass(frozen=True, slots=True)
class Problem:
    """An event of level ERROR or worse, or a complaint of the recorder."""

    t: float
    level: str
    text: str


@dataclass(slots=True)
class LogInfo:
    """What :func:`summarize` found in a recording."""

    path: str
    size: int
    complete: bool
    end: str
    """``complete`` or where and why the readable part ends."""
    version: str | None
    metadata: dict[str, dict[str, str]]
    attachments: dict[str, int]
    """Attachment name → size in bytes."""
    first_s: float | None = None
    last_s: float | None = None
    messages: int = 0
    channels: list[ChannelInfo] = field(default_factory=list)
    events: dict[str, int] = field(default_factory=dict)
    """Event counts by level name."""
    event_types: dict[str, int] = field(default_factory=dict)
    problems: list[Problem] = field(default_factory=list)
    """The first :data:`MAX_QUOTED` errors."""
    problem_count: int = 0

    @property
    def duration_s(self) -> float:
        """Time from the first message to the last."""
        if self.first_s is None or self.last_s is None:
            return 0.0
        return self.last_s - self.first_s

    def as_dict(self) -> dict[str, Any]:
        """Plain values for JSON output (rates included)."""
        value = asdict(self)
        value["duration_s"] = self.duration_s
        for entry, channel in zip(value["channels"], self.channels, strict=True):
            entry["rate_hz"] = channel.rate_hz
        return value


def summarize(path: str | os.PathLike[str]) -> LogInfo:
    """Read the recording at ``path`` once and say what it holds (see the module)."""
    recording = Recording(path)
    info = LogInfo(
        path=str(path),
        size=recording.size,
        complete=recording.complete,
        end="",
        version=recording.version,
        metadata=recording.metadata,
        attachments={name: len(a.data) for name, a in recording.attachments.items()},
    )
    channels: dict[tuple[str, str], ChannelInfo] = {}
    levels: Counter[str] = Counter()
    types: Counter[str] = Counter()
    for record in recording.records(decode=False):
        t = record.t
        key = (record.topic, record.schema)
        channel = channels.get(key)
        if channel is None:
            channel = channels[key] = ChannelInfo(record.topic, record.schema, 0, t, t)
        elif t - channel.last_s > channel.longest_gap_s:
            channel.longest_gap_s, channel.gap_at_s = t - channel.last_s, channel.last_s
        channel.count += 1
        channel.last_s = t
        info.messages += 1
        if info.first_s is None:
            info.first_s = t
        info.last_s = t
        cls = MESSAGE_TYPES.get(record.schema)
        if cls is not None and issubclass(cls, Event):
            level = event_level(record.schema)
            levels[level.name] += 1
            types[record.schema] += 1
            if level >= LogLevel.ERROR:
                _problem(info, t, level.name, lambda r=record: _event_text(r.schema, r.data))
        elif record.schema == "foxglove.Log":
            _recorder_complaint(info, t, record.data)
    info.end = "complete" if recording.damage is None else recording.damage.describe(path)
    info.complete = recording.complete and recording.damage is None
    info.channels = sorted(channels.values(), key=lambda c: (c.topic, c.schema))
    info.events = dict(levels)
    info.event_types = dict(types.most_common())
    return info


def _problem(info: LogInfo, t: float, level: str, text: Any) -> None:
    info.problem_count += 1
    if len(info.problems) < MAX_QUOTED:
        info.problems.append(Problem(t, level, text()))


def _event_text(schema: str, data: bytes) -> str:
    try:
        event = codec_by_name(schema).decode(data)
    except EncodingError as exc:
        return f"{schema} (cannot be read: {exc})"
    return event_text(event) if isinstance(event, Event) else schema


def _recorder_complaint(info: LogInfo, t: float, data: bytes) -> None:
    try:
        entry = json.loads(data)
    except ValueError:
        return
    if isinstance(entry, dict) and entry.get("name") == "recorder":
        level = LogLevel(entry.get("level", 0)) if entry.get("level") in range(6) else None
        name = level.name if level is not None else "UNKNOWN"
        _problem(info, t, name, lambda: str(entry.get("message", "")))


def format_info(info: LogInfo) -> str:
    """The report ``whexar log info`` prints."""
    lines = [
        f"{info.path}: {info.size / 1e6:.2f} MB, "
        f"recorded by {'whexar ' + info.version if info.version else 'an unknown writer'}",
    ]
    lines.append("complete" if info.complete else info.end)
    run = info.metadata.get("run")
    if run:
        lines.append("run: " + ", ".join(f"{k} = {v}" for k, v in run.items()))
    if info.attachments:
        lines.append(
            "attachments: " + ", ".join(f"{n} ({s:,} B)" for n, s in info.attachments.items())
        )
    if info.first_s is None or info.last_s is None:
        lines.append("no message")
        return "\n".join(lines)
    lines.append(
        f"time: {info.first_s:.3f} … {info.last_s:.3f} s ({info.duration_s:.3f} s), "
        f"{info.messages:,} messages"
    )
    lines.append("")
    width = max(len(c.topic) for c in info.channels)
    kinds = max(len(c.schema) for c in info.channels)
    lines.append(f"{'topic':<{width}}  {'type':<{kinds}}  {'count':>8}  {'rate/s':>8}  longest gap")
    for c in info.channels:
        rate = "" if c.rate_hz is None else f"{c.rate_hz:.1f}"
        gap = "" if c.count < 2 else f"{c.longest_gap_s:.3f} s at t = {c.gap_at_s:.3f} s"
        lines.append(f"{c.topic:<{width}}  {c.schema:<{kinds}}  {c.count:>8,}  {rate:>8}  {gap}")
    lines.append("")
    if info.events:
        order = [level.name for level in sorted(LogLevel, reverse=True)]
        counts = ", ".join(f"{info.events[n]} {n.lower()}" for n in order if n in info.events)
        lines.append(f"events: {sum(info.events.values())} ({counts})")
    else:
        lines.append("events: none")
    if info.problem_count:
        lines.append(f"errors: {info.problem_count}")
        for p in info.problems:
            first, *rest = p.text.splitlines() or [""]
            lines.append(f"  t = {p.t:.3f} s  {p.level}  {first}")
            lines.extend(f"      {line}" for line in rest[-1:])  # a traceback's last line
        if info.problem_count > len(info.problems):
            lines.append(f"  … and {info.problem_count - len(info.problems)} more")
    else:
        lines.append("errors: none")
    end = info.metadata.get("whexar.end")
    if end:
        lines.append(
            f"recorder: {end.get('dropped', '?')} dropped, {end.get('errors', '?')} not "
            f"encodable, at most {end.get('max_pending', '?')} pending, "
            f"{end.get('write_s', '?')} s writing"
        )
        if end.get("stopped"):
            lines.append(f"recording stopped before the run's end: {end['stopped']}")
    return "\n".join(lines)
