"""The exact check of a replay: every message as recorded, to the last bit.

A replay on virtual time of a log recorded on virtual time, with the recording's
code and configuration, publishes every message exactly as recorded.
:class:`Checker` (a runtime observer) compares each published message with the
recorded one, channel by channel and in order: its type, then each field, floats
within :data:`FLOAT_TOLERANCE` (relative, at least absolute), everything else
exactly. The first difference stops the replay and is a :class:`Divergence` naming
the channel, the time, the field and both values; so are a packet written to a
device that differs from the recorded one, and recorded messages the replay never
published. A log recorded on a real clock is compared by time instead
(:mod:`whexar.record.diff`).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, fields, is_dataclass
from typing import Any, Final

from whexar.runtime.messages import Message

__all__ = ["FLOAT_TOLERANCE", "LATE_S", "Checker", "Divergence", "compare"]

FLOAT_TOLERANCE: Final = 1e-9
"""Floats agree within this, relative to the larger (and at least this absolute): a replay
on the recording's code agrees to the last bit; this forgives a time summed in another
order."""
LATE_S: Final = 0.1
"""A replay cut short by ``stop`` does not miss a recorded message stamped this little
before ``stop``: it may have been published after it. Where a damaged recording ends,
this much before its end is not compared: the cut chunk held part of it."""


@dataclass(frozen=True)
class Divergence:
    """Where a replay first did something other than the recording."""

    kind: str
    """``message`` (a field differs), ``type``, ``missing`` (recorded, never published),
    ``extra`` (published, never recorded) or ``link`` (bytes written to a device)."""
    channel: str
    """The channel (or ``links/NAME``)."""
    t: float
    """The recorded time (s)."""
    what: str
    """The message type and field path (``ServoStates.joints[3].position``), or a packet."""
    recorded: str
    replayed: str

    def describe(self) -> str:
        """One paragraph naming the channel, the time, the field and both values."""
        head = {
            "message": "differs",
            "type": "is another message",
            "missing": "was recorded but not published by the replay",
            "extra": "was published by the replay but not recorded",
            "link": "written to the device differs",
        }[self.kind]
        return (
            f"diverged at t = {self.t:.6f} s on {self.channel}: {self.what} {head}\n"
            f"  recorded: {self.recorded}\n"
            f"  replayed: {self.replayed}"
        )


def _short(value: Any, limit: int = 400) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 1] + "…"


def compare(
    recorded: Any,
    replayed: Any,
    path: str = "",
    aliases: Mapping[str, str] | None = None,
    tolerance: float = FLOAT_TOLERANCE,
) -> tuple[str, Any, Any] | None:
    """The first difference between two values: ``(path, recorded, replayed)``, or ``None``.

    Dataclasses field by field, sequences and mappings item by item, floats within
    ``tolerance`` (relative to the larger, and at least absolute), everything else
    exactly. ``aliases`` maps a played-back device's name to the recorded one
    (``replay:sensors`` → ``/dev/ttyACM0``): a replayed string naming it counts as
    naming the recorded device."""
    return Comparison(aliases or {}, tolerance).first(recorded, replayed, path)


class Comparison:
    def __init__(self, aliases: Mapping[str, str], tolerance: float) -> None:
        self.aliases = aliases
        self.tolerance = tolerance

    def close(self, a: float, b: float) -> bool:
        if a == b or (math.isnan(a) and math.isnan(b)):
            return True
        return abs(a - b) <= self.tolerance * max(1.0, abs(a), abs(b))

    def first(self, recorded: Any, replayed: Any, path: str) -> tuple[str, Any, Any] | None:
        # Nearly every replayed message equals its recording exactly: one ``==`` (tuple
        # equality in C under the dataclasses') is then the whole comparison.
        if recorded == replayed:
            return None
        return self._walk(recorded, replayed, path)

    def _walk(self, recorded: Any, replayed: Any, path: str) -> tuple[str, Any, Any] | None:
        if self.aliases and isinstance(replayed, str) and isinstance(recorded, str):
            for alias, name in self.aliases.items():
                replayed = replayed.replace(alias, name)
        if type(recorded) is not type(replayed):
            numbers = isinstance(recorded, int | float) and isinstance(replayed, int | float)
            if numbers and self.close(float(recorded), float(replayed)):
                return None
            return path, recorded, replayed
        if isinstance(recorded, float):
            return None if self.close(recorded, replayed) else (path, recorded, replayed)
        pairs: Iterator[tuple[str, Any, Any]]
        if is_dataclass(recorded):
            pairs = (
                (f"{path}.{f.name}", getattr(recorded, f.name), getattr(replayed, f.name))
                for f in fields(recorded)
            )
        elif isinstance(recorded, list | tuple):
            if len(recorded) != len(replayed):
                return f"{path} (length)", len(recorded), len(replayed)
            together = enumerate(zip(recorded, replayed, strict=True))
            pairs = ((f"{path}[{k}]", a, b) for k, (a, b) in together)
        elif isinstance(recorded, Mapping):
            if recorded.keys() != replayed.keys():
                return f"{path} (keys)", sorted(map(str, recorded)), sorted(map(str, replayed))
            pairs = ((f"{path}[{key!r}]", recorded[key], replayed[key]) for key in recorded)
        else:
            return None if recorded == replayed else (path, recorded, replayed)
        for where, a, b in pairs:
            found = self.first(a, b, where)
            if found is not None:
                return found
        return None


class Checker:
    """The runtime observer that compares what is published with the recording."""

    def __init__(
        self,
        expected: Iterator[tuple[str, Message]],
        skip: set[str],
        start: float,
        stop: float,
        whole: bool,
    ) -> None:
        self._source = expected
        self._pending: dict[str, deque[Message]] = {}
        self._skip = skip
        self._start = start
        self._stop = stop
        self._whole = whole
        """The replay runs to the recording's end: what is published while stopping counts."""
        self.now: Callable[[], float] = lambda: -math.inf
        """The runtime clock (set once the run starts)."""
        self.comparison = Comparison({}, FLOAT_TOLERANCE)
        """How values are compared (:func:`compare`): device aliases, float tolerance."""
        self.compared = 0
        self.divergence: Divergence | None = None
        self.stopped_at = math.inf
        """Runtime time of the divergence that stopped the replay."""
        self.on_divergence: Callable[[], None] = lambda: None

    def _next(self, channel: str) -> Message | None:
        queue = self._pending.get(channel)
        if queue:
            return queue.popleft()
        for ch, msg in self._source:
            if ch == channel:
                return msg
            self._pending.setdefault(ch, deque()).append(msg)
        return None

    def _counts(self) -> bool:
        # Before --to, by publish time: the stop that --to makes was not recorded.
        return self._whole or self.now() < self._stop

    def __call__(self, channel: str, msg: Message) -> None:
        if self.divergence is not None or channel in self._skip or not self._counts():
            return
        recorded = self._next(channel)
        if msg.t < self._start - 1e-12:
            return
        name = type(msg).__name__
        if recorded is None:
            self._diverged("extra", channel, msg.t, name, "nothing", _short(msg))
            return
        self.compared += 1
        if type(recorded) is not type(msg):
            self._diverged("type", channel, recorded.t, name, _short(recorded), _short(msg))
            return
        found = self.comparison.first(recorded, msg, name)
        if found is not None:
            path, a, b = found
            self._diverged("message", channel, recorded.t, path, _short(a), _short(b))

    def _diverged(self, kind: str, channel: str, t: float, what: str, a: str, b: str) -> None:
        self.divergence = Divergence(kind, channel, t, what, a, b)
        now = self.now()
        # Before the run hands its clock over (an actor starting), the message's time.
        self.stopped_at = now if math.isfinite(now) else t
        self.on_divergence()

    def _missed(self, t: float) -> bool:
        # A message stamped just before --to may have been published after it.
        return t >= self._start and (self._whole or t < self._stop - LATE_S)

    def left_over(self) -> Divergence | None:
        """The first recorded message (within the window) the replay did not publish."""
        first: tuple[float, str, Message] | None = None
        for channel, queue in self._pending.items():
            for msg in queue:
                if channel not in self._skip and self._missed(msg.t):
                    if first is None or msg.t < first[0]:
                        first = (msg.t, channel, msg)
                    break
        for channel, msg in self._source:
            if first is not None and msg.t >= first[0]:
                break
            if channel not in self._skip and self._missed(msg.t):
                first = (msg.t, channel, msg)
                break
        if first is None:
            return None
        t, channel, msg = first
        return Divergence("missing", channel, t, type(msg).__name__, _short(msg), "nothing")
