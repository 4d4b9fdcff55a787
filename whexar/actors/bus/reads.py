"""What a cycle reads, how, and what it read.

:class:`CycleReads` binds the read plan (:mod:`whexar.bus.plan`) to the
servo table: each read is one Sync Read or Fast Sync Read of a contiguous
register span, due every cycle or at its rate, of all its servos or a
round-robin chunk of them. A servo whose last read failed is asked again in
every cycle, in the first read of the plan that covers it, until it answers
or is degraded (:meth:`~whexar.actors.bus.health.HealthMachine.to_ask`).

:class:`ReadMode` decides between Fast Sync Read and Sync Read: detected,
never assumed; Fast Sync Read that fails where Sync Read succeeds
``FAST_FALLBACK_AFTER`` cycles in a row falls back to Sync Read.

:func:`decode`, :func:`joint_states` and :func:`health_readings` turn the
bytes a cycle read into the values and messages it publishes. No I/O, no
clock: the time comes in as an argument.
"""

from __future__ import annotations

from collections.abc import Container, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Final

from whexar.actors.bus.servos import Servo
from whexar.actors.messages import JointState, ReadModeChanged, ServoHealth
from whexar.bus import control_table as ct
from whexar.bus.plan import FastMode, PlanRead, ReadPlan
from whexar.bus.protocol import ALERT
from whexar.bus.sdk import SyncReadResult
from whexar.robot import JOINT_NAMES, LEG_NAMES
from whexar.runtime.messages import Event

FAST_FALLBACK_AFTER: Final = 3
"""Consecutive Fast Sync Read failures, each healed by Sync Read, before falling back."""

_RAD_PER_TICK: Final = ct.ticks_to_rad(ct.CENTER_TICKS + 1)
_CENTER_TICKS: Final = ct.CENTER_TICKS
_RAD_S_PER_UNIT: Final = ct.velocity_to_rad_s(1)


@dataclass(slots=True)
class BoundRead:
    """One plan read bound to servos: its span, its due time and its round-robin cursor."""

    spec: PlanRead
    block: ct.Block
    servos: list[Servo]
    next_due: float = 0.0
    cursor: int = 0

    def take(self, now: float, out: Container[int]) -> list[Servo]:
        """The servos this read asks in a cycle at ``now`` (none when not due), leaving out
        those in ``out`` (not in the cycle)."""
        if self.spec.rate_hz is not None:
            if now < self.next_due:
                return []
            self.next_due = max(self.next_due + 1.0 / self.spec.rate_hz, now)
        live = [s for s in self.servos if s.id not in out]
        chunk = self.spec.chunk
        if chunk is None or chunk >= len(live):
            return live
        start = self.cursor % max(1, len(live))
        self.cursor = start + chunk
        return (live[start:] + live[:start])[:chunk]


Due = list[tuple[BoundRead, list[Servo]]]
"""A cycle's reads: each read that is due, with the servos it asks."""


class CycleReads:
    """The read plan bound to ``servos`` (in ID order)."""

    def __init__(self, plan: ReadPlan, servos: Sequence[Servo]) -> None:
        self.reads: list[BoundRead] = []
        for spec in plan.reads:
            chosen = [
                s
                for s in servos
                if JOINT_NAMES[s.joint] in spec.joints and LEG_NAMES[s.leg] in spec.legs
            ]
            models = {s.model.name: s.model for s in chosen}.values() or ct.MODELS.values()
            self.reads.append(BoundRead(spec, ct.block(spec.registers, models), chosen))
        self.home: dict[int, int] = {}
        """Each servo's first read in the plan: where a suspect is asked again."""
        for k, read in enumerate(self.reads):
            for s in read.servos:
                self.home.setdefault(s.id, k)
        self.by_id = {s.id: s for s in servos}

    def due(self, now: float, out: Container[int], suspects: Sequence[int]) -> Due:
        """The reads of a cycle at ``now`` without the servos in ``out``; each of
        ``suspects`` (IDs) not asked already is added to its first read."""
        due: Due = []
        for read in self.reads:
            servos = read.take(now, out)
            if servos:
                due.append((read, servos))
        if not suspects:
            return due
        asked = {s.id for _, servos in due for s in servos}
        lists = {id(read): servos for read, servos in due}
        for sid in suspects:
            if sid not in asked:
                lists.setdefault(id(self.reads[self.home[sid]]), []).append(self.by_id[sid])
        return [(read, lists[id(read)]) for read in self.reads if id(read) in lists]

    def first_ids(self, out: Container[int]) -> list[int]:
        """The servos of the plan's first read that are in the cycle: what a detection of
        Fast Sync Read asks."""
        return [s.id for s in self.reads[0].servos if s.id not in out]


class ReadMode:
    """Fast Sync Read or Sync Read, per the plan's ``fast_sync_read`` setting."""

    def __init__(self, setting: FastMode, source: str) -> None:
        self.setting = setting
        self.source = source
        self.fast = setting == "on"
        """Whether the cycle reads with Fast Sync Read."""
        self.streak = 0
        """Consecutive cycles whose Fast Sync Read failed where Sync Read worked."""

    @property
    def detects(self) -> bool:
        """Whether Fast Sync Read is tried (at start-up and after a servo recovers)."""
        return self.setting == "auto"

    def detected(self, now: float, works: bool, why: str, *, report: bool = False) -> list[Event]:
        """A detection (``why``) found that Fast Sync Read ``works`` or not: the mode, and
        an event when it changed (always when ``report``: at start-up)."""
        events: list[Event] = []
        if works != self.fast or report:
            mode = "fast_sync_read" if works else "sync_read"
            verdict = "answered" if works else "did not answer"
            events.append(
                ReadModeChanged(
                    t=now, source=self.source, mode=mode, reason=f"{why}: Fast Sync Read {verdict}"
                )
            )
        self.fast = works
        self.streak = 0
        return events

    def cycled(self, now: float, fast_failures: int) -> list[Event]:
        """A cycle's reads had ``fast_failures`` Fast Sync Reads healed by Sync Read."""
        if fast_failures:
            self.streak += 1
            if self.streak >= FAST_FALLBACK_AFTER:
                self.fast = False
                return [
                    ReadModeChanged(
                        t=now,
                        source=self.source,
                        mode="sync_read",
                        reason=f"Fast Sync Read failed {self.streak} cycles in a row "
                        "where Sync Read worked",
                    )
                ]
        elif self.fast:
            self.streak = 0
        return []

    @property
    def name(self) -> str:
        """``fast_sync_read`` or ``sync_read`` (as :class:`BusStats` says it)."""
        return "fast_sync_read" if self.fast else "sync_read"


def decode(
    due: Due, results: Sequence[SyncReadResult]
) -> tuple[dict[int, dict[str, int]], dict[int, int]]:
    """The register values per servo of a cycle's reads (``due``, their ``results``), and
    the ERR byte of each status that arrived."""
    values: dict[int, dict[str, int]] = {}
    errors: dict[int, int] = {}
    for (read, _), res in zip(due, results, strict=True):
        decode_one = read.block.decode
        for sid, data in res.data.items():
            decoded = decode_one(data)
            if sid in values:
                values[sid].update(decoded)
            else:
                values[sid] = decoded
        errors.update(res.errors)
    return values, errors


def joint_states(
    servos: Mapping[int, Servo],
    values: Mapping[int, Mapping[str, int]],
    errors: Mapping[int, int],
) -> tuple[JointState, ...]:
    """What each servo read reported, in ID order (a servo with nothing read is left out)."""
    joints = []
    center, rad_per_tick, rad_s_per_unit = _CENTER_TICKS, _RAD_PER_TICK, _RAD_S_PER_UNIT
    # The conversions of whexar.bus.control_table, inlined: 42 servos every cycle.
    for sid, regs in sorted(values.items()):
        get = regs.get
        pos = get("present_position")
        vel = get("present_velocity")
        cur = get("present_current")
        if cur is None:
            cur = get("present_load")
        if pos is None and vel is None and cur is None:
            continue
        s = servos[sid]
        joints.append(
            JointState(
                s.leg,
                s.joint,
                sid,
                None if pos is None else (pos - center) * rad_per_tick,
                None if vel is None else vel * rad_s_per_unit,
                None if cur is None else cur * s.current_unit,
                bool(errors.get(sid, 0) & ALERT),
            )
        )
    return tuple(joints)


def health_readings(
    t: float, source: str, values: Mapping[int, Mapping[str, int]]
) -> Iterator[ServoHealth]:
    """A :class:`ServoHealth` per servo whose voltage, temperature or Hardware Error
    Status was read, in ID order."""
    for sid, regs in sorted(values.items()):
        volt = regs.get("present_input_voltage")
        temp = regs.get("present_temperature")
        hw = regs.get("hardware_error_status")
        if volt is None and temp is None and hw is None:
            continue
        yield ServoHealth(
            t=t,
            source=source,
            servo_id=sid,
            voltage_v=None if volt is None else ct.voltage_to_v(volt),
            temperature_c=temp,
            hardware_error=hw,
        )
