"""What a simulated run keeps of its messages: compact series, not the messages.

Theory of operation
-------------------
A run publishes about a thousand messages per simulated second (every bus
cycle a :class:`~whexar.actors.messages.ServoStates` of 42 joints, six
:class:`~whexar.actors.messages.LegState`, the legs' goals…). Kept whole they
cost over a megabyte per simulated second, so a long run would grow without
bound. :class:`RunSeries` is a channel observer that keeps, as the messages
pass, only what the summary, the report and the campaign metrics read:

* the coordinator's state per :class:`~whexar.actors.messages.LocomotionState`
  (time, activity, mode, gait, stability margin): :class:`LocomotionPoints`;
* each leg's swings as (start, end) intervals, from its ``LegState``;
* leg 0's goal and present angles of the plotted joints (:data:`TRACED_JOINTS`);
* per bus cycle the Σ |Present Current| of each leg, and each servo's |Present
  Current| (NaN where it was not read), as flat float arrays;
* per force-sensor reading (:class:`~whexar.actors.messages.LegLoads`) the six
  legs' contact flags, one byte;
* each reflex's active spells as (start, end) intervals, from its
  :class:`~whexar.actors.messages.ReflexActivity`; each swing's end as (time,
  leg, outcome), from :class:`~whexar.actors.messages.SwingEnded`;
* every runtime event (they are few), and the latest activity and event for the
  progress line.

The arrays grow by a few hundred bytes per bus cycle, not by every message. What
needs the messages themselves reads the run's recording (MCAP), or runs with
``simulate(keep_log=True)`` (tests).
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any, Final, NoReturn

import numpy as np

from whexar.actors.messages import (
    JointGoals,
    LegLoads,
    LegState,
    LocomotionState,
    ReflexActivity,
    ServoStates,
    SwingEnded,
)
from whexar.errors import UsageError
from whexar.robot import LEG_NAMES, N_LEGS
from whexar.runtime.harness import MessageLog
from whexar.runtime.messages import ActorReady, ActorStarting, Event, Message
from whexar.runtime.wiring import EVENTS_CHANNEL

TRACED_LEG: Final = 0
"""The leg whose joint angles are kept (the report's Fig. 6.2 plot draws leg 0, RF)."""
TRACED_JOINTS: Final = (0, 2, 3, 4)
"""Its joints kept: coxa, femur, tibia, tarsus (:data:`whexar.record.plots.FIG_6_2_JOINTS`)."""
_QUIET: Final = (ActorStarting, ActorReady)

Trace = list[tuple[float, float]]


class _Floats:
    """(t, value) pairs as two float arrays: 16 bytes a point."""

    __slots__ = ("t", "v")

    def __init__(self) -> None:
        self.t = array("d")
        self.v = array("d")

    def add(self, t: float, v: float) -> None:
        self.t.append(t)
        self.v.append(v)

    def pairs(self) -> Trace:
        return list(zip(self.t, self.v, strict=True))


@dataclass(frozen=True, slots=True)
class LocomotionPoint:
    """One :class:`LocomotionState`, the fields the summary and the metrics read."""

    t: float
    activity: str
    mode: str
    gait: str
    margin_m: float
    yaw_rate_rad_s: float = 0.0
    """The turning rate it commands (its twist's ω): what the robot reckons it turns."""


class LocomotionPoints:
    """The coordinator's states in order: times, margins and commanded turning rates as
    floats, the names interned (a state's strings repeat from cycle to cycle)."""

    def __init__(self) -> None:
        self._t = array("d")
        self._margin = array("d")
        self._yaw_rate = array("d")
        self._names = array("H")  # index into _table of (activity, mode, gait)
        self._table: list[tuple[str, str, str]] = []
        self._index: dict[tuple[str, str, str], int] = {}

    def add(self, msg: LocomotionState) -> None:
        key = (msg.activity, msg.mode, msg.gait)
        k = self._index.get(key)
        if k is None:
            k = self._index[key] = len(self._table)
            self._table.append(key)
        self._t.append(msg.t)
        self._margin.append(msg.margin_m)
        self._yaw_rate.append(msg.twist[2])
        self._names.append(k)

    def __len__(self) -> int:
        return len(self._t)

    def __getitem__(self, k: int) -> LocomotionPoint:
        activity, mode, gait = self._table[self._names[k]]
        t, margin, rate = self._t[k], self._margin[k], self._yaw_rate[k]
        return LocomotionPoint(t, activity, mode, gait, margin, rate)

    def __iter__(self) -> Iterator[LocomotionPoint]:
        for k in range(len(self._t)):
            yield self[k]

    def between(self, t0: float, t1: float) -> list[LocomotionPoint]:
        """The states from ``t0`` to ``t1`` s (both included, to 1 ns)."""
        return [p for p in self if t0 - 1e-9 <= p.t <= t1 + 1e-9]


@dataclass
class RunSeries:
    """The compact series of one run, fed as a channel observer (see the module docstring)."""

    locomotion: LocomotionPoints = field(default_factory=LocomotionPoints)
    events: list[Event] = field(default_factory=list)
    """Every runtime event, in order."""
    latest_activity: str = ""
    """``"activity mode/gait"`` of the latest :class:`LocomotionState`."""
    latest_event: str = ""
    """The latest event that is not start-up, as ``"Name @t s"``."""
    cycles: int = 0
    """:class:`ServoStates` seen: the bus cycles."""
    cycle_t: array[float] = field(default_factory=lambda: array("d"))
    """Each bus cycle's time (s)."""
    loads_t: array[float] = field(default_factory=lambda: array("d"))
    """Each force-sensor reading's time (s)."""
    _contacts: array[int] = field(default_factory=lambda: array("B"))
    _leg_amps: array[float] = field(default_factory=lambda: array("d"))
    _servo_amps: dict[int, array[float]] = field(default_factory=dict)
    _servo_joint: dict[int, int] = field(default_factory=dict)
    _goals: dict[int, _Floats] = field(default_factory=dict)
    _present: dict[int, _Floats] = field(default_factory=dict)
    _swings: dict[int, list[tuple[float, float]]] = field(default_factory=dict)
    _swing_from: dict[int, float] = field(default_factory=dict)
    _legs_t: float = 0.0
    swing_ends: list[tuple[float, int, str]] = field(default_factory=list)
    """(time, leg, outcome) of every swing's end: a few per second."""
    _reflexes: dict[str, list[tuple[float, float]]] = field(default_factory=dict)
    _reflex_from: dict[str, float] = field(default_factory=dict)
    _last_t: float = 0.0
    quiet: tuple[type[Message], ...] = _QUIET
    """Events too routine for :attr:`latest_event`."""

    def __post_init__(self) -> None:
        self._goals = {j: _Floats() for j in TRACED_JOINTS}
        self._present = {j: _Floats() for j in TRACED_JOINTS}
        self._swings = {leg: [] for leg in range(N_LEGS)}

    @classmethod
    def of(cls, published: Iterable[tuple[str, Message]]) -> RunSeries:
        """The series of these (channel, message) pairs, in publish order (a hand-made run)."""
        series = cls()
        for channel, msg in published:
            series(channel, msg)
        return series

    def __call__(self, channel: str, msg: Message) -> None:
        """Take one published message."""
        if isinstance(msg, ServoStates):
            self._servo_states(msg)
        elif isinstance(msg, LegState):
            self._leg_state(msg)
        elif isinstance(msg, JointGoals):
            self._joint_goals(msg)
        elif isinstance(msg, LegLoads):
            self.loads_t.append(msg.t)
            self._contacts.append(sum(1 << leg for leg, c in enumerate(msg.contacts) if c))
        elif isinstance(msg, LocomotionState):
            self.locomotion.add(msg)
            self._last_t = msg.t
            self.latest_activity = f"{msg.activity} {msg.mode}/{msg.gait}"
        elif isinstance(msg, ReflexActivity):
            self._reflex_activity(msg)
        elif isinstance(msg, SwingEnded):
            self.swing_ends.append((msg.t, msg.leg, msg.outcome))
        elif isinstance(msg, Event):
            if channel == EVENTS_CHANNEL:
                self.events.append(msg)
            if not isinstance(msg, self.quiet):
                self.latest_event = f"{type(msg).__name__} @{msg.t:.1f}s"

    # ------------------------------------------------------------------ accumulating

    def _servo_states(self, msg: ServoStates) -> None:
        row = [0.0] * N_LEGS
        seen: set[int] = set()
        for js in msg.joints:
            amps = math.nan
            if js.current_a is not None:
                amps = abs(js.current_a)
                row[js.leg] += amps
            column = self._servo_amps.get(js.servo_id)
            if column is None:  # a servo first read now: not read before
                column = self._servo_amps[js.servo_id] = array("d", [math.nan] * self.cycles)
                self._servo_joint[js.servo_id] = js.joint
            column.append(amps)
            seen.add(js.servo_id)
            if js.leg == TRACED_LEG and js.joint in self._present and js.position_rad is not None:
                self._present[js.joint].add(msg.t, js.position_rad)
        for sid, column in self._servo_amps.items():
            if sid not in seen:  # left out of this cycle (degraded)
                column.append(math.nan)
        self._leg_amps.extend(row)
        self.cycle_t.append(msg.t)
        self.cycles += 1

    def _leg_state(self, msg: LegState) -> None:
        # As whexar.record.series.swing_intervals, one message at a time.
        self._legs_t = msg.t
        if msg.phase == "swing":
            self._swing_from.setdefault(msg.leg, msg.t)
        elif msg.leg in self._swing_from:
            self._swings.setdefault(msg.leg, []).append((self._swing_from.pop(msg.leg), msg.t))

    def _reflex_activity(self, msg: ReflexActivity) -> None:
        name = msg.reflex.removeprefix("reflex-")
        self._reflexes.setdefault(name, [])
        if msg.active:
            self._reflex_from.setdefault(name, msg.t)
        # Held back by another reflex (inhibited), what it asked stays in force and it is
        # handed nothing meanwhile: active again when let go is the same spell going on.
        elif not msg.inhibited and name in self._reflex_from:
            self._reflexes[name].append((self._reflex_from.pop(name), msg.t))

    def _joint_goals(self, msg: JointGoals) -> None:
        if msg.source != f"leg-{LEG_NAMES[TRACED_LEG]}":
            return
        for g in msg.goals:
            if g.leg == TRACED_LEG and g.joint in self._goals and g.position_rad is not None:
                self._goals[g.joint].add(msg.t, g.position_rad)

    # ------------------------------------------------------------------ reading

    def swing_intervals(self) -> dict[int, list[tuple[float, float]]]:
        """Per leg, the (start, end) times it was in swing; a swing still going ends at the
        last LegState."""
        out = {leg: list(found) for leg, found in self._swings.items()}
        for leg, t0 in self._swing_from.items():
            out.setdefault(leg, []).append((t0, self._legs_t))
        return out

    def activity_intervals(self) -> list[tuple[float, float, str]]:
        """(start, end, activity) of the coordinator."""
        out: list[tuple[float, float, str]] = []
        for p in self.locomotion:
            if out and out[-1][2] == p.activity:
                out[-1] = (out[-1][0], p.t, p.activity)
            else:
                if out:
                    out[-1] = (out[-1][0], p.t, out[-1][2])
                out.append((p.t, p.t, p.activity))
        return out

    def gait_intervals(self) -> list[tuple[float, float, str]]:
        """(start, end, how it moves) of the coordinator: its gait while it walks (or steps
        the hybrid gait), ``wheels`` while it rides; nothing while it stands or sits."""
        runs: list[tuple[float, float, str]] = []
        for p in self.locomotion:
            if p.activity == "riding":
                what = "wheels"
            else:
                what = p.gait if p.activity in ("walking", "hybrid") else ""
            if runs:
                runs[-1] = (runs[-1][0], p.t, runs[-1][2])
            if not runs or runs[-1][2] != what:
                runs.append((p.t, p.t, what))
        return [r for r in runs if r[2]]

    def reflex_intervals(self) -> dict[str, list[tuple[float, float]]]:
        """By reflex (its name without ``reflex-``), the (start, end) times it was active,
        a spell going on while another reflex holds it back (its requests stay in force);
        one still active ends at the last coordinator state. A reflex that never acted
        has an empty list."""
        out = {name: list(found) for name, found in self._reflexes.items()}
        for name, t0 in self._reflex_from.items():
            out[name].append((t0, max(t0, self._last_t)))
        return out

    def joint_traces(self, leg: int = TRACED_LEG) -> dict[int, tuple[Trace, Trace]]:
        """For each of :data:`TRACED_JOINTS` of :data:`TRACED_LEG`: (goals its own actor sent,
        present angles) as (t, rad) lists. Another leg's were not kept."""
        if leg != TRACED_LEG:
            raise UsageError(
                f"a run keeps the joint angles of leg {TRACED_LEG} only; "
                f"leg {leg}'s are in its recording (whexar plot)"
            )
        return {j: (self._goals[j].pairs(), self._present[j].pairs()) for j in TRACED_JOINTS}

    def leg_currents(self) -> tuple[list[float], np.ndarray]:
        """Bus cycle times and, per cycle and leg, Σ |Present Current| of the leg's servos (A)."""
        amps = np.frombuffer(self._leg_amps, dtype=float).reshape(-1, N_LEGS).copy()
        return list(self.cycle_t), amps

    def contacts(self) -> tuple[np.ndarray, np.ndarray]:
        """Force-sensor reading times and, per reading and leg, its contact flag."""
        bits = np.frombuffer(self._contacts, dtype=np.uint8)
        flags = (bits[:, None] >> np.arange(N_LEGS, dtype=np.uint8)) & 1
        return np.frombuffer(self.loads_t, dtype=float).copy(), flags.astype(bool)

    def servo_amps(self) -> dict[int, tuple[int, array[float]]]:
        """By servo ID: (joint, |Present Current| per bus cycle, NaN where not read)."""
        return {sid: (self._servo_joint[sid], col) for sid, col in self._servo_amps.items()}


class NoMessageLog(MessageLog):
    """The log of a run that kept none (:class:`RunSeries` instead): reading it is an error,
    not an empty answer."""

    def _refuse(self) -> NoReturn:
        raise UsageError(
            "this run kept no message log: its series are SimResult.series; "
            "run it with simulate(keep_log=True) or read its recording for every message"
        )

    def messages(self, channel: str | None = None, *, of: type[Message] = Message) -> Any:
        """Refused: the run kept no message."""
        self._refuse()

    def lines(self) -> list[str]:
        """Refused: the run kept no message."""
        self._refuse()


__all__ = [
    "TRACED_JOINTS",
    "TRACED_LEG",
    "LocomotionPoint",
    "LocomotionPoints",
    "NoMessageLog",
    "RunSeries",
]
