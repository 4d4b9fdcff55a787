"""Two runs compared by time: the check for a real clock, and ``whexar log diff``.

Theory of operation
-------------------
A log recorded on a real clock never replays to the last bit: timers, retries and
a goal landing one cycle later shift every message a little. So two runs — a
recording and its replay, or two recordings — are compared as signals, not as
message sequences:

* **States** (servo states, goals, the legs' and the coordinator's states, the body
  motion, tilt, loads, ranges, servo health) are cut into keyed samples: one per
  numeric, boolean or text field of a message, keyed by the channel, the message
  type, who it is about (its source, its leg, joint or servo) and the field
  (``servo-state ServoStates leg 0 joint 2 position_rad``). A recorded sample agrees
  when a sample of the other run with the same key, within ``window_s`` of it (or
  the one in force at its time: a goal holds until the next), is within the field
  kind's absolute tolerance (:class:`Tolerances`: angles in radians, lengths in
  metres, currents in amperes…; angles and the gait phase wrap around).
* **Discrete messages** — events, step commands, swing ends — are matched by kind
  and order (the i-th ``ServoDegraded`` of the one with the i-th of the other),
  their times within ``event_s``, their fields as states.
* **Health events** — what a servo's Hardware Error Status says that does not latch
  (``HardwareWarning``), and the supply it tells of (``SupplyLow``,
  ``SupplyRestored``) — are found when a read reaches the servo, and a servo outside
  the cycle is read only at its turn of the round-robin health reads (every 0.6 s in
  the ``default`` plan). On a real clock, a replay whose read of a servo falls a
  cycle or a stall before the robot's — just before the change the robot's read
  found — finds the change only at that servo's next turn. So they are matched per
  servo and order (the order across servos is only the order they were read in),
  their times within ``health_s``; which servos a ``SupplyLow`` names (those read
  first) is not compared: each one's warning is.

The result (:class:`DiffReport`) is a table, not a first difference: per channel
and field, how many samples were compared, the largest and the mean difference,
the tolerance, how many were beyond it, how many of those for longer than
``persist_s`` in a row, and when the first such lasting difference began (naming
the key: the joint, the leg); per event kind, the counts on both sides and the
first one unmatched. A blip — beyond for a cycle or two, a discrete change a cycle
apart — is counted but does not make two runs disagree. :attr:`DiffReport.agrees`
is the verdict. The runtime's own lifecycle events (an actor starting, stopping)
are not compared: a replay starts its actors its own way; nor are the process's
statistics (bus and sensor-link counters per second).

Both runs are read as they go: :class:`TimeDiff` keeps, per key, only the samples
within a window of the instant being compared, so memory stays bounded on an
hour's log. It is fed in time order, from two recordings (:func:`diff_recordings`)
or from a recording and a live replay (``whexar replay --check`` on a field log).
"""

from __future__ import annotations

import functools
import itertools
import math
import os
from collections import deque
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field, fields, is_dataclass, replace
from typing import TYPE_CHECKING, Any, Final

from whexar.actors.messages import RecordingDeleted, RecordingStopped
from whexar.robot import JOINT_NAMES, LEG_NAMES
from whexar.runtime.messages import (
    ActorFailed,
    ActorReady,
    ActorRestarted,
    ActorStarting,
    ActorStopped,
    Event,
    Message,
    StopRequested,
    TickOverrun,
)

if TYPE_CHECKING:
    from whexar.record.reader import Recording

__all__ = [
    "DEFAULT_TOLERANCES",
    "DiffReport",
    "EventRow",
    "FieldRow",
    "TimeDiff",
    "Tolerances",
]

LIFECYCLE: Final = (
    ActorStarting,
    ActorReady,
    ActorStopped,
    ActorRestarted,
    ActorFailed,
    StopRequested,
    TickOverrun,
    RecordingDeleted,
    RecordingStopped,
)
"""Runtime events about the process, not the robot: not compared (a replay starts and
stops its actors its own way, on a clock that never overruns; the recorder's events are
the disk's). An escalation and a safe stop are compared: the robot stops for them."""
_SKIPPED: Final = frozenset({"t", "source", "cycle", "seq", "missed"})
"""Fields that are no signal: the time, who said it, counters of the process."""
_IDENTITY: Final = ("leg", "joint", "servo_id", "sensor", "link")
"""Fields that say what a message or an element is about: part of the key."""
_DISCRETE: Final = frozenset({"StepCommand", "SwingEnded", "MotionCommand"})
"""Messages that are no state: matched by kind and order, as events are."""
_EVENT_KINDS: Final = ("what", "kind")
"""Fields that say which kind of event a message is (a LocomotionChanged of the activity,
a StepCommand of a swing): matched in order within their kind, so that one event more in
either run does not put every later one out of step."""
_STATISTICS: Final = frozenset({"BusStats", "SensorStats"})
"""Counters of the process (cycles, bytes, retries per second): not the robot's signals."""
_HEALTH: Final = frozenset({"HardwareWarning", "SupplyLow", "SupplyRestored"})
"""Events a servo's health reads find (module docstring): matched per servo, their times
within ``health_s``."""
_READ_ORDER: Final = frozenset({"servo_ids"})
"""Fields of health events that say only which servos happened to be read first."""


@dataclass(frozen=True)
class Tolerances:
    """How far two runs may differ and still agree, per field kind (absolute)."""

    window_s: float = 0.05
    """How far apart in time two samples of one signal may be: five bus cycles. On a real
    clock an actor that falls behind skips a cycle or more (its inbox keeps the latest
    state), and a step then begins a few cycles later on the robot than in its replay
    (docs/replay.md has one measured: 49 ms)."""
    event_s: float = 0.25
    """How far apart in time two matched events (or step commands) may be."""
    health_s: float = 0.85
    """How far apart in time two matched health events (a servo's warning, the supply low
    or back: module docstring) may be: a round of the ``default`` plan's health reads,
    which reach each servo's Hardware Error Status every 0.6 s (a replay whose read falls
    just before the robot's finds the change at the next turn), and ``event_s`` more."""
    angle_rad: float = 0.02
    angular_velocity_rad_s: float = 0.5
    length_m: float = 0.005
    speed_m_s: float = 0.02
    current_a: float = 0.25
    voltage_v: float = 0.3
    temperature_c: float = 2.0
    acceleration_g: float = 0.05
    persist_s: float = 0.05
    """How long a signal must stay beyond its tolerance to disagree: five bus cycles. A
    discrete change a cycle apart (a foot down one cycle later, the margin at a tripod's
    hand-over) is counted as a blip, not a difference."""
    time_s: float = 0.05
    ratio: float = 0.1
    """Progress through a step, the gait's phase (0…1)."""
    load: float = 5.0
    """The eq. 5.19 load indicator, A/m."""
    value: float = 1e-6
    """Any other number."""

    def of(self, kind: str) -> float:
        """The tolerance of field kind ``kind`` (0 for counts, flags and labels)."""
        return float(getattr(self, _KIND_FIELD.get(kind, "value"), 0.0))

    def with_(self, settings: Mapping[str, float]) -> Tolerances:
        """These tolerances with ``settings`` (``{"angle_rad": 0.05}``) changed; an unknown
        name is a :class:`KeyError` naming the known ones."""
        known = {f.name for f in fields(self)}
        unknown = sorted(set(settings) - known)
        if unknown:
            raise KeyError(f"{', '.join(unknown)}; known: {', '.join(sorted(known))}")
        return replace(self, **dict(settings))


DEFAULT_TOLERANCES: Final = Tolerances()
_KIND_FIELD: Final = {
    "angle": "angle_rad",
    "angular_velocity": "angular_velocity_rad_s",
    "length": "length_m",
    "speed": "speed_m_s",
    "current": "current_a",
    "voltage": "voltage_v",
    "temperature": "temperature_c",
    "acceleration": "acceleration_g",
    "time": "time_s",
    "ratio": "ratio",
    "phase": "ratio",
    "load": "load",
    "value": "value",
}
_SUFFIXES: Final = (
    ("_rad_s", "angular_velocity"),
    ("_dps", "angular_velocity"),
    ("_rad", "angle"),
    ("_m_s", "speed"),
    ("_m", "length"),
    ("_s", "time"),
    ("_a", "current"),
    ("_v", "voltage"),
    ("_c", "temperature"),
    ("_g", "acceleration"),
)
_NAMED: Final[Mapping[str, str | tuple[str, ...]]] = {
    "twist": ("speed", "speed", "angular_velocity"),
    "pose": ("length", "length", "length", "angle", "angle", "angle"),
    "foot": "length",
    "measured_foot": "length",
    "target": "length",
    "start_t": "time",
    "progress": "ratio",
    "gait_phase": "phase",
    "load": "load",
}


def _kind(name: str, value: object, index: int | None = None) -> str:
    """The kind of field ``name`` (element ``index`` of it), from its name or its type (a
    number left out, ``None``, is of the kind its name says)."""
    if isinstance(value, bool):
        return "flag"
    if isinstance(value, str):
        return "label"
    if isinstance(value, int):
        return "count"
    return _number_kind(name, index)


@functools.cache
def _number_kind(name: str, index: int | None) -> str:
    named = _NAMED.get(name)
    if isinstance(named, tuple):
        return named[index] if index is not None and index < len(named) else "value"
    if named is not None:
        return named
    for suffix, kind in _SUFFIXES:
        if name.endswith(suffix):
            return kind
    return "value"


Key = tuple[str, ...]
Value = float | str | bool | None


def _about(record: object) -> tuple[str, ...]:
    """What a message or an element is about, as key parts (``leg RF``, ``joint femur``)."""
    ident = (type(record), *(getattr(record, name, None) for name in _IDENTITY))
    found = _ABOUT.get(ident)
    if found is None:
        found = _ABOUT[ident] = _about_parts(record)
    return found


_ABOUT: dict[tuple[object, ...], tuple[str, ...]] = {}


def _about_parts(record: object) -> tuple[str, ...]:
    parts: list[str] = []
    for name in _IDENTITY:
        value = getattr(record, name, None)
        if value is None:
            continue
        if name == "leg" and isinstance(value, int) and 0 <= value < len(LEG_NAMES):
            value = LEG_NAMES[value]
        elif name == "joint" and isinstance(value, int) and 0 <= value < len(JOINT_NAMES):
            value = JOINT_NAMES[value]
        parts.append(f"{'servo' if name == 'servo_id' else name} {value}")
    return tuple(parts)


Sample = tuple[tuple[str, ...], str, str, Value]
"""One compared field of a message: ``(about, field, kind, value)``."""


def _compared_fields(tp: type) -> tuple[str, ...]:
    """The fields of a record type that are signals: not the time, who said it, counters
    or what it is about (a dataclass's fields, a named tuple's), in their order."""
    found = _FIELDS.get(tp)
    if found is None:
        names: Iterable[str] = (
            (f.name for f in fields(tp)) if is_dataclass(tp) else getattr(tp, "_fields", ())
        )
        found = _FIELDS[tp] = tuple(n for n in names if n not in _SKIPPED and n not in _IDENTITY)
    return found


def _is_record(tp: type) -> bool:
    found = _RECORD.get(tp)
    if found is None:
        found = _RECORD[tp] = is_dataclass(tp) or hasattr(tp, "_fields")
    return found


_FIELDS: dict[type, tuple[str, ...]] = {}
_RECORD: dict[type, bool] = {}


@functools.cache
def _indexed(name: str, index: int) -> str:
    return f"{name}[{index}]"


def samples(msg: Message) -> list[Sample]:
    """The signals of ``msg``: ``(about, field, kind, value)`` for every compared field.

    Sequences of records (a cycle's joints, a message's goals) give each element's
    fields, keyed by what the element is about; tuples of numbers give one per item.
    Built into one list, each type's fields looked up once (a replay's check takes
    some 20 samples from each of tens of thousands of messages)."""
    out: list[Sample] = []
    about = (f"from {msg.source}", *_about(msg))
    for name in _compared_fields(type(msg)):
        _field(out, about, name, getattr(msg, name))
    return out


def _field(out: list[Sample], about: tuple[str, ...], name: str, value: object) -> None:
    if isinstance(value, tuple | list):
        if value and _is_record(type(value[0])):
            for element in value:
                inner = (*about, *_about(element))
                for sub in _compared_fields(type(element)):
                    _field(out, inner, sub, getattr(element, sub))
            return
        if all(isinstance(v, int | float | type(None)) and not isinstance(v, bool) for v in value):
            for i, item in enumerate(value):
                out.append(
                    (
                        about,
                        _indexed(name, i),
                        _kind(name, item if item is not None else 0.0, i),
                        (None if item is None else float(item)),
                    )
                )
            return
        out.append((about, name, "label", repr(value)))
        return
    if isinstance(value, bool | str) or value is None:
        out.append((about, name, _kind(name, value), value))
    elif isinstance(value, int | float):
        out.append((about, name, _kind(name, value), float(value)))
    else:
        out.append((about, name, "label", repr(value)))


def _difference(kind: str, a: Value, b: Value) -> float:
    """How far apart two samples of one kind are: 0 or 1 for flags, labels and counts
    that differ or not; a wrapped difference for angles and phases."""
    if a == b:
        return 0.0  # infinities too: a rangefinder that sees nothing in both runs
    if isinstance(a, float) and isinstance(b, float):
        if math.isnan(a) and math.isnan(b):
            return 0.0
        d = abs(a - b)
        if kind == "angle":
            d = abs((a - b + math.pi) % (2 * math.pi) - math.pi)
        elif kind == "phase":
            d = min(d % 1.0, 1.0 - d % 1.0)
        if kind == "count":
            return 0.0 if d == 0 else 1.0
        return d if not math.isnan(d) else math.inf
    return 0.0 if a == b else 1.0


def _nearest(
    kind: str,
    value: Value,
    t: float,
    w: float,
    held: tuple[float, Value] | None,
    samples: deque[tuple[float, Value]],
) -> float:
    """How far ``value`` (at ``t``) is from the other run's signal within ``w`` of ``t``.

    A number is compared with the signal drawn through the other run's samples (the one
    held before the window, those in it, the first after it): over the window, that line
    takes every value between its lowest and highest, so a difference of timing within
    the window costs nothing and only a difference of value counts. Flags, labels and
    counts are compared with each sample in the window (and the held one)."""
    if not isinstance(value, float) or kind in ("count", "flag", "label"):
        best = math.inf if held is None else _difference(kind, value, held[1])
        for u, other in samples:
            if u > t + w:
                break
            d = _difference(kind, value, other)
            if d < best:
                best = d
        return best
    period = 2 * math.pi if kind == "angle" else 1.0 if kind == "phase" else 0.0
    half = period / 2
    lo_t, hi_t = t - w, t + w
    low, high = math.inf, -math.inf
    u1 = v1 = math.nan  # the previous sample, once there is one
    seen = False
    wrap = period and math.isfinite(value)
    # One pass, in time order: the held sample, then those of the window and the first
    # after it. The line's range only grows: once it holds ``value``, that is the answer.
    # (Written out, comparisons for min and max: tens of thousands of calls a replay.)
    for u, other in itertools.chain((held,), samples) if held is not None else samples:
        if not isinstance(other, float) or other != other:  # a flag, or NaN
            continue
        if wrap and math.isfinite(other):
            other = value + ((other - value + half) % period - half)
        if seen and (u1 < lo_t < u or u1 < hi_t < u):
            for edge in (lo_t, hi_t):  # where the line crosses the window's edges
                if u1 < edge < u:
                    x = v1 + (other - v1) * (edge - u1) / (u - u1)
                    if x < low:
                        low = x
                    if x > high:
                        high = x
        if lo_t <= u <= hi_t:
            if other < low:
                low = other
            if other > high:
                high = other
        if low <= value <= high:
            return 0.0
        u1, v1, seen = u, other, True
        if u > hi_t:
            break
    if low > high:  # nothing in the window: the last sample before it holds
        if not seen:
            return math.inf
        low = high = v1
    if low <= value <= high:
        return 0.0
    d = min(abs(value - low), abs(value - high))
    return d if d == d else math.inf


# --------------------------------------------------------------------------- the report


@dataclass
class FieldRow:
    """One channel's field: how it compared (the largest difference over all keys)."""

    channel: str
    message: str
    field: str
    kind: str
    tolerance: float
    compared: int = 0
    beyond: int = 0
    """Samples beyond tolerance, blips included."""
    lasting: int = 0
    """Samples beyond tolerance for at least ``persist_s`` in a row (a discrete message:
    any): what makes the field disagree."""
    largest: float = 0.0
    total: float = 0.0
    unmatched: int = 0
    """Samples of one run with nothing of the other near them."""
    first_beyond_t: float | None = None
    """When the first lasting difference began."""
    first_beyond_key: str | None = None
    worst_key: str | None = None

    @property
    def mean(self) -> float:
        """The mean difference over the compared samples."""
        return self.total / self.compared if self.compared else 0.0

    @property
    def agrees(self) -> bool:
        return self.lasting == 0 and self.unmatched == 0


@dataclass
class EventRow:
    """One kind of event (or step command, swing end): how the two runs' matched."""

    channel: str
    kind: str
    first: int = 0
    """How many the first run (the recording) has."""
    second: int = 0
    """How many the second run (the replay) has."""
    largest_dt: float = 0.0
    late: int = 0
    """Matched pairs further apart in time than the tolerance."""
    first_unmatched_t: float | None = None

    @property
    def agrees(self) -> bool:
        return self.first == self.second and self.late == 0


@dataclass
class DiffReport:
    """What :class:`TimeDiff` found (module docstring)."""

    tolerances: Tolerances
    fields: list[FieldRow] = field(default_factory=list)
    events: list[EventRow] = field(default_factory=list)
    compared: int = 0
    """Samples compared in all."""

    @property
    def agrees(self) -> bool:
        """Every field within its tolerance and every event matched."""
        return all(r.agrees for r in self.fields) and all(r.agrees for r in self.events)

    @property
    def first_beyond(self) -> FieldRow | None:
        """The field row whose first difference beyond tolerance came earliest."""
        found = [r for r in self.fields if r.first_beyond_t is not None]
        return min(found, key=lambda r: r.first_beyond_t or 0.0, default=None)

    def table(self, *, all_rows: bool = False) -> str:
        """The report as text: the rows beyond tolerance first (all rows with ``all_rows``)."""
        rows = sorted(
            (r for r in self.fields if all_rows or not r.agrees),
            key=lambda r: (r.agrees, r.first_beyond_t if r.first_beyond_t is not None else 0.0),
        )
        lines = [
            f"{'channel':<13}{'field':<34}{'compared':>9}{'largest':>11}{'mean':>11}"
            f"{'tolerance':>11}{'beyond':>8}{'lasting':>8}  first lasting"
        ]
        for r in rows:
            first = (
                f"t = {r.first_beyond_t:.3f} s, {r.first_beyond_key}"
                if r.first_beyond_t is not None
                else ("-" if not r.unmatched else f"{r.unmatched} without a match")
            )
            lines.append(
                f"{r.channel:<13}{(r.message + '.' + r.field)[:33]:<34}{r.compared:>9}"
                f"{_num(r.largest):>11}{_num(r.mean):>11}{_num(r.tolerance):>11}"
                f"{r.beyond:>8}{r.lasting:>8}  {first}"
            )
        events = [e for e in self.events if all_rows or not e.agrees]
        if events:
            lines.append("")
            lines.append(
                f"{'channel':<13}{'event':<34}{'recorded':>9}{'replayed':>9}  first unmatched"
            )
            for e in events:
                first = "-" if e.first_unmatched_t is None else f"t = {e.first_unmatched_t:.3f} s"
                lines.append(f"{e.channel:<13}{e.kind[:33]:<34}{e.first:>9}{e.second:>9}  {first}")
        return "\n".join(lines)

    def to_json(self) -> dict[str, Any]:
        """The report as strict JSON data (no infinities)."""
        return {
            "agrees": self.agrees,
            "compared": self.compared,
            "tolerances": {
                f.name: getattr(self.tolerances, f.name) for f in fields(self.tolerances)
            },
            "fields": [
                {
                    "channel": r.channel,
                    "message": r.message,
                    "field": r.field,
                    "kind": r.kind,
                    "tolerance": r.tolerance,
                    "compared": r.compared,
                    "beyond": r.beyond,
                    "lasting": r.lasting,
                    "unmatched": r.unmatched,
                    "largest": _finite(r.largest),
                    "mean": _finite(r.mean),
                    "first_beyond_t": r.first_beyond_t,
                    "first_beyond_key": r.first_beyond_key,
                    "worst_key": r.worst_key,
                }
                for r in self.fields
            ],
            "events": [
                {
                    "channel": e.channel,
                    "kind": e.kind,
                    "recorded": e.first,
                    "replayed": e.second,
                    "late": e.late,
                    "largest_dt": _finite(e.largest_dt),
                    "first_unmatched_t": e.first_unmatched_t,
                }
                for e in self.events
            ],
        }


def _num(x: float) -> str:
    return "inf" if math.isinf(x) else f"{x:.4g}"


def _finite(x: float) -> float | None:
    return x if math.isfinite(x) else None  # strict JSON: no infinity (whexar._json)


# --------------------------------------------------------------------------- the diff


@dataclass(slots=True)
class _Signal:
    """One key's samples of both runs, within a window of what is being compared."""

    row: FieldRow
    name: str
    first: deque[tuple[float, Value]] = field(default_factory=deque)
    second: deque[tuple[float, Value]] = field(default_factory=deque)
    held: tuple[float, Value] | None = None
    """The second run's last sample before the window: in force until the next."""
    held_first: tuple[float, Value] | None = None
    beyond_since: float | None = None
    """When the first run's samples began to be beyond tolerance, while they are."""


class TimeDiff:
    """Compares two runs fed in time order (module docstring); :meth:`report` at the end.

    :meth:`first` and :meth:`second` take a message of each run with its channel;
    :meth:`advance` says both runs have been fed up to a time, so that what is
    further than the window behind it can be compared and let go."""

    def __init__(self, tolerances: Tolerances = DEFAULT_TOLERANCES) -> None:
        self.tol = tolerances
        self._signals: dict[Key, _Signal] = {}
        self._rows: dict[tuple[str, str, str], FieldRow] = {}
        self._events: dict[tuple[str, str], tuple[EventRow, deque[Message], deque[Message]]] = {}
        self._event_rows: dict[tuple[str, str], EventRow] = {}
        self.compared = 0
        # Ordered (a dict, not a set): the order keys are compared in decides sums and ties
        # in the report, which must not change with the process's string hashing.
        self._dirty: dict[Key, None] = {}

    # ----------------------------------------------------------------- feeding

    def first(self, channel: str, msg: Message) -> None:
        """A message of the first run (the recording)."""
        self._take(channel, msg, True)

    def second(self, channel: str, msg: Message) -> None:
        """A message of the second run (the replay)."""
        self._take(channel, msg, False)

    def _take(self, channel: str, msg: Message, first: bool) -> None:
        if isinstance(msg, LIFECYCLE):
            return
        name = type(msg).__name__
        if name in _STATISTICS:
            return
        if isinstance(msg, Event) or name in _DISCRETE:
            self._event(channel, msg, first)
            return
        t = msg.t
        signals, dirty = self._signals, self._dirty
        for about, fname, kind, value in samples(msg):
            key = (channel, name, *about, fname)
            signal = signals.get(key)
            if signal is None:
                row = self._row(channel, name, fname, kind)
                signal = signals[key] = _Signal(row, " ".join(about[1:]) or about[0])
            (signal.first if first else signal.second).append((t, value))
            dirty[key] = None

    def _row(self, channel: str, message: str, fname: str, kind: str) -> FieldRow:
        generic = fname.split("[")[0] + ("[]" if "[" in fname else "")
        found = self._rows.get((channel, message, generic))
        if found is None:
            found = self._rows[(channel, message, generic)] = FieldRow(
                channel, message, generic, kind, self.tol.of(kind)
            )
        return found

    def _event(self, channel: str, msg: Message, first: bool) -> None:
        what = type(msg).__name__
        for name in _EVENT_KINDS:
            value = getattr(msg, name, None)
            if isinstance(value, str):
                what = f"{what} {value}"  # a change of activity is not one of gait
        leg = getattr(msg, "leg", None)
        if leg is not None and isinstance(leg, int) and 0 <= leg < len(LEG_NAMES):
            what = f"{what} {LEG_NAMES[leg]}"
        servo = getattr(msg, "servo_id", None)
        if type(msg).__name__ in _HEALTH and isinstance(servo, int):
            what = f"{what} servo {servo}"  # per servo: the order across them is the reads'
        key = (channel, what)
        entry = self._events.get(key)
        if entry is None:
            entry = self._events[key] = (EventRow(channel, what), deque(), deque())
        row, mine, theirs = (
            (entry[0], entry[1], entry[2]) if first else (entry[0], entry[2], entry[1])
        )
        if first:
            row.first += 1
        else:
            row.second += 1
        if theirs:
            other = theirs.popleft()
            a, b = (msg, other) if first else (other, msg)
            self._match(row, channel, a, b)
        else:
            mine.append(msg)

    def _match(self, row: EventRow, channel: str, a: Message, b: Message) -> None:
        name = type(a).__name__
        health = name in _HEALTH
        dt = abs(a.t - b.t)
        row.largest_dt = max(row.largest_dt, dt)
        if dt > (self.tol.health_s if health else self.tol.event_s):
            row.late += 1
        if type(b) is not type(a):
            return
        sa: Iterable[Sample] = samples(a)
        sb: Iterable[Sample] = samples(b)
        if health:  # which servos happened to be read first: not compared
            sa = (x for x in sa if x[1].split("[")[0] not in _READ_ORDER)
            sb = (x for x in sb if x[1].split("[")[0] not in _READ_ORDER)
        for (about, fname, kind, va), (_, _, _, vb) in zip(sa, sb, strict=False):
            frow = self._row(channel, name, fname, kind)
            self._score(frow, " ".join(about[1:]) or about[0], a.t, _difference(kind, va, vb))

    # ----------------------------------------------------------------- comparing

    def _score(
        self, row: FieldRow, key: str, t: float, d: float, signal: _Signal | None = None
    ) -> None:
        row.compared += 1
        self.compared += 1
        row.total += d if math.isfinite(d) else 0.0
        if d > row.largest:
            row.largest = d
            row.worst_key = key
        if d <= row.tolerance + 1e-12:
            if signal is not None:
                signal.beyond_since = None
            return
        row.beyond += 1
        if signal is not None:
            # A signal beyond its tolerance for less than persist_s is a blip: a discrete
            # change one cycle apart (a foot down a cycle later), counted, not a verdict.
            since = signal.beyond_since
            if since is None:
                since = signal.beyond_since = t
            if t - since + 1e-12 < self.tol.persist_s:
                return
        row.lasting += 1
        start = t if signal is None or signal.beyond_since is None else signal.beyond_since
        if row.first_beyond_t is None or start < row.first_beyond_t:
            row.first_beyond_t = start
            row.first_beyond_key = key

    def advance(self, t: float) -> None:
        """Both runs are fed up to ``t``: compare what lies a window behind it."""
        frontier = t - self.tol.window_s
        done = []
        for key in self._dirty:
            signal = self._signals[key]
            self._compare(signal, frontier)
            if not signal.first and not signal.second:
                done.append(key)
        for key in done:
            del self._dirty[key]

    def _compare(self, s: _Signal, frontier: float) -> None:
        w = self.tol.window_s
        row = s.row
        kind = row.kind
        first, second = s.first, s.second
        while first and first[0][0] <= frontier:
            t, value = first.popleft()
            # The other run's samples older than the window go, the last one kept held.
            while second and second[0][0] < t - w:
                s.held = second.popleft()
            best = _nearest(kind, value, t, w, s.held, second)
            if best == math.inf and s.held is None and not second:
                row.unmatched += 1
                continue
            s.held_first = (t, value)
            self._score(row, s.name, t, best, s)
        # What the second run said with no first-run sample anywhere near: unmatched,
        # unless the first run has held a value through it.
        while second and second[0][0] < frontier - w:
            u, _ = second.popleft()
            if s.held_first is None:
                row.unmatched += 1
            s.held = (u, _)

    def report(self) -> DiffReport:
        """Compare everything left and say how the two runs agree."""
        for key in list(self._dirty):
            self._compare(self._signals[key], math.inf)
        for row, mine, theirs in self._events.values():
            left = mine or theirs
            if left:
                row.first_unmatched_t = left[0].t
        events = [entry[0] for entry in self._events.values()]
        return DiffReport(
            self.tol,
            sorted(self._rows.values(), key=lambda r: (r.channel, r.message, r.field)),
            sorted(events, key=lambda e: (e.channel, e.kind)),
            self.compared,
        )


def merged(
    a: Iterable[tuple[str, Message]], b: Iterable[tuple[str, Message]]
) -> Iterator[tuple[bool, str, Message]]:
    """Two runs' ``(channel, message)`` streams, merged by time: ``(from_a, channel, msg)``."""
    ia, ib = iter(a), iter(b)
    na, nb = next(ia, None), next(ib, None)
    while na is not None or nb is not None:
        if nb is None or (na is not None and na[1].t <= nb[1].t):
            assert na is not None
            yield True, na[0], na[1]
            na = next(ia, None)
        else:
            yield False, nb[0], nb[1]
            nb = next(ib, None)


def diff_streams(
    a: Iterable[tuple[str, Message]],
    b: Iterable[tuple[str, Message]],
    tolerances: Tolerances = DEFAULT_TOLERANCES,
) -> DiffReport:
    """Compare two runs' message streams (each in time order, or nearly)."""
    diff = TimeDiff(tolerances)
    last = -math.inf
    for from_a, channel, msg in merged(a, b):
        (diff.first if from_a else diff.second)(channel, msg)
        if msg.t > last + tolerances.window_s:
            last = msg.t
            # Messages come a little out of order across channels: a margin behind.
            diff.advance(msg.t - tolerances.window_s)
    return diff.report()


def recorded_messages(
    path: str | os.PathLike[str], channels: Iterable[str] | None = None
) -> Iterator[tuple[str, Message]]:
    """A recording's messages as ``(channel, message)``, in log-time order: the channels
    of its wiring and the events (or ``channels``); no device bytes, no viewer topics."""
    from whexar.record.reader import Recording

    rec = Recording(path)
    rec.check_compatible()
    if channels is None:
        channels = [*wiring_channels(rec), "events"]
    for r in rec.records([f"/{ch}" for ch in channels]):
        if isinstance(r.value, Message):
            yield r.topic[1:], r.value


def wiring_channels(rec: Recording) -> list[str]:
    """The channels a recording's wiring declares (none when it holds no wiring)."""
    import json
    import tomllib

    for name, attachment in sorted(rec.attachments.items()):
        if name.startswith("wiring."):
            text = attachment.data.decode("utf-8")
            data = json.loads(text) if name.endswith(".json") else tomllib.loads(text)
            return [str(ch) for ch in data.get("channels", {})]
    return []


def diff_recordings(
    a: str | os.PathLike[str],
    b: str | os.PathLike[str],
    tolerances: Tolerances = DEFAULT_TOLERANCES,
) -> DiffReport:
    """Compare two recordings' messages by time (``whexar log diff A B``), over the time
    both cover up to the earlier one's stop: the last :data:`STOP_S` before it are each
    run's own stopping, on its own clock."""
    from whexar.record.reader import Recording

    until = min(_stop_time(Recording(a)), _stop_time(Recording(b))) - STOP_S

    def window(path: str | os.PathLike[str]) -> Iterator[tuple[str, Message]]:
        for channel, msg in recorded_messages(path):
            if msg.t > until:
                return
            yield channel, msg

    return diff_streams(window(a), window(b), tolerances)


STOP_S: Final = 0.1
"""The end of a run not compared with another's: where each stopped on its own clock."""


def _stop_time(rec: Recording) -> float:
    """Where a recorded run stopped: its duration, or where its readable part ends."""
    duration = rec.metadata.get("run", {}).get("duration_s")
    readable = (rec.last_ns or 0) / 1e9
    return min(float(duration), readable) if duration is not None else readable
