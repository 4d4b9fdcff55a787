"""Declarative fault plans for the servo emulator.

Theory of operation
-------------------
A :class:`FaultPlan` is a list of :class:`Fault` entries, read from TOML
(``config/faults/*.toml``)::

    seed = 1                 # seeds the emulator's random faults (corrupt, drop)

    [[faults]]
    kind = "silent"          # servo 3 stops answering for good…
    ids = [3]
    at_s = 2.0               # …from 2 s of emulator time

    [[faults]]
    kind = "hardware_error"
    ids = [4]
    bits = ["overload"]
    on = "sync_write"        # …after the 10th Sync Write that includes servo 4
    count = 10

A :class:`FaultInjector` attaches to a :class:`~whexar.bus.emulator.chain.ServoChain`
as one of its hooks. The chain calls the hook before it handles each request,
with the emulator time ``t`` and the decoded instruction packets; the injector
then starts the faults whose trigger has come and ends the faults whose
``duration_s`` has run out, by setting the chain's :class:`FaultState` and the
servos' state. It never touches bytes itself; the chain does that.

Triggers
--------
Every fault has exactly one trigger:

* ``at_s`` — emulator time. The fault starts with the first request at or
  after ``at_s`` and its ``duration_s`` counts from ``at_s``.
* ``on`` (with ``count``, default 1) — the ``count``-th occurrence of an
  event. The fault starts *after* the request that completes the count (at
  the next request the chain handles; the triggering request itself is
  answered normally) and its ``duration_s`` counts from that request's time.

The event vocabulary (:data:`EVENTS`):

* an instruction's name — ``"ping"``, ``"read"``, ``"write"``,
  ``"reg_write"``, ``"action"``, ``"factory_reset"``, ``"reboot"``,
  ``"clear"``, ``"sync_read"``, ``"sync_write"``, ``"fast_sync_read"``,
  ``"bulk_read"``, ``"bulk_write"``, ``"fast_bulk_read"``: one occurrence per
  instruction packet of that kind;
* ``"torque_enabled"`` / ``"torque_disabled"``: one occurrence per request
  that writes 1 / 0 to Torque Enable (64), by Write, Reg Write, Sync Write or
  Bulk Write.

When the fault names ``ids``, only requests that concern one of them count:
a packet addressed to one of them, a broadcast packet (Ping, Write…), or a
Sync/Bulk instruction that lists one of them. Bus-wide kinds (``corrupt``,
``drop``, ``unplug``) take no ``ids``; every request counts for them.

Kinds
-----
* ``silent`` — the servos do not answer (``FaultState.silent_until``).
  ``ids`` absent means every servo.
* ``corrupt`` — each status byte gets one flipped bit with probability
  ``rate`` (``FaultState.corrupt_rate``): at 1e-4, about one Sync Read of
  42 × 10 bytes (882 status bytes) in twelve comes back with a bad CRC.
* ``drop`` — each status packet is lost with probability ``rate``
  (``FaultState.drop_rate``). Overlapping corrupt or drop faults combine as
  independent events.
* ``hardware_error`` — the servos raise Hardware Error Status ``bits``
  (:meth:`VirtualServo.raise_error`). A hardware error stays latched until
  the servo is rebooted (Reboot, instruction 0x08), as on the device, so
  ``duration_s`` does not apply to this kind.
* ``voltage_sag`` — the servos' input voltage drops to ``volts`` (below Min
  Voltage Limit the servo flags Input Voltage Error), and comes back at the
  end.
* ``unplug`` — the whole bus goes away (``FaultState.unplugged``); for good
  unless ``duration_s`` is given.

``duration_s`` absent means for good.
"""

from __future__ import annotations

import math
import typing
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Final, Literal

from pydantic import AfterValidator, Field, ValidationError

from whexar.bus.control_table import HardwareError
from whexar.bus.protocol import MAX_ID
from whexar.errors import MISSING, ConfigError, Problem
from whexar.runtime.schema import CheckedSection, Section, loads, problem_from_error, read_toml

if TYPE_CHECKING:
    from whexar.bus.emulator.chain import ServoChain
    from whexar.bus.protocol import Packet

__all__ = [
    "EVENTS",
    "KINDS",
    "Fault",
    "FaultInjector",
    "FaultPlan",
    "load_fault_plan",
    "parse_fault_plan",
]

FaultKind = Literal["silent", "corrupt", "drop", "hardware_error", "voltage_sag", "unplug"]
KINDS: Final[tuple[str, ...]] = typing.get_args(FaultKind)

BitName = Literal["input_voltage", "overheating", "motor_encoder", "electrical_shock", "overload"]
"""Bits of Hardware Error Status (70), :class:`HardwareError` in snake case."""

Event = Literal[
    "ping",
    "read",
    "write",
    "reg_write",
    "action",
    "factory_reset",
    "reboot",
    "clear",
    "sync_read",
    "sync_write",
    "fast_sync_read",
    "bulk_read",
    "bulk_write",
    "fast_bulk_read",
    "torque_enabled",
    "torque_disabled",
]
EVENTS: Final[tuple[str, ...]] = typing.get_args(Event)
"""Events a fault can be triggered ``on`` (see the module docstring)."""

# Instruction codes (ROBOTIS e-manual, Protocol 2.0, "Instruction"); kept here
# by number so that the event vocabulary does not depend on how the codec
# names its enum members.
_INSTRUCTION_EVENTS: Final[Mapping[int, str]] = {
    0x01: "ping",
    0x02: "read",
    0x03: "write",
    0x04: "reg_write",
    0x05: "action",
    0x06: "factory_reset",
    0x08: "reboot",
    0x10: "clear",
    0x82: "sync_read",
    0x83: "sync_write",
    0x8A: "fast_sync_read",
    0x92: "bulk_read",
    0x93: "bulk_write",
    0x9A: "fast_bulk_read",
}
_BROADCAST_ID: Final = 0xFE
_TORQUE_ENABLE: Final = 64
"""Torque Enable's address (e-manual, MX (2.0) control table)."""

_USES_IDS: Final = frozenset({"silent", "hardware_error", "voltage_sag"})
_USES_DURATION: Final = frozenset({"silent", "corrupt", "drop", "voltage_sag", "unplug"})
_ONLY_FOR: Final[Mapping[str, frozenset[str]]] = {
    "rate": frozenset({"corrupt", "drop"}),
    "bits": frozenset({"hardware_error"}),
    "volts": frozenset({"voltage_sag"}),
}

ServoId = Annotated[int, Field(ge=0, le=MAX_ID)]


class Fault(CheckedSection):
    """One fault: what goes wrong, to which servos, when, and for how long."""

    kind: FaultKind
    ids: list[ServoId] | None = Field(default=None, min_length=1)
    """Servos affected (silent, hardware_error, voltage_sag); absent = every servo."""
    at_s: float | None = Field(default=None, ge=0, allow_inf_nan=False)
    """Trigger: emulator time in seconds."""
    on: Event | None = None
    """Trigger: an event (see :data:`EVENTS`)."""
    count: int = Field(default=1, ge=1)
    """With ``on``: the occurrence of the event that starts the fault (1 = the first)."""
    duration_s: float | None = Field(default=None, gt=0, allow_inf_nan=False)
    """How long the fault lasts; absent = for good. Not for hardware_error (latched)."""
    rate: float | None = Field(default=None, ge=0, le=1, allow_inf_nan=False)
    """corrupt: probability per status byte of a flipped bit; drop: of losing a status packet."""
    bits: list[BitName] | None = Field(default=None, min_length=1)
    """hardware_error: the Hardware Error Status bits raised."""
    volts: float | None = Field(default=None, gt=0, le=30, allow_inf_nan=False)
    """voltage_sag: the input voltage during the sag, V."""

    def problems(self, at: str) -> list[Problem]:
        """Fields that do not fit together: triggers, and fields of another kind."""
        here = f"{at}." if at else ""
        found: list[Problem] = []
        if self.at_s is None and self.on is None:
            found.append(
                Problem(f"{here}at_s", MISSING, "a trigger is required: give at_s or on (not both)")
            )
        elif self.at_s is not None and self.on is not None:
            found.append(Problem(f"{here}on", self.on, "only one trigger: at_s or on, not both"))
        if self.on is None and "count" in self.model_fields_set:
            found.append(Problem(f"{here}count", self.count, "only with on = an event"))
        for key, kinds in _ONLY_FOR.items():
            value = getattr(self, key)
            if self.kind in kinds and value is None:
                found.append(Problem(f"{here}{key}", MISSING, f"required for kind {self.kind!r}"))
            elif self.kind not in kinds and value is not None:
                found.append(
                    Problem(
                        f"{here}{key}",
                        value,
                        f"only for kind {' or '.join(sorted(kinds))}, not {self.kind!r}",
                    )
                )
        if self.ids is not None and self.kind not in _USES_IDS:
            found.append(
                Problem(
                    f"{here}ids",
                    self.ids,
                    f"kind {self.kind!r} affects the whole bus; ids only for "
                    + ", ".join(sorted(_USES_IDS)),
                )
            )
        if self.duration_s is not None and self.kind not in _USES_DURATION:
            found.append(
                Problem(
                    f"{here}duration_s",
                    self.duration_s,
                    "not for hardware_error: the error stays latched until the servo is "
                    "rebooted; allowed for " + ", ".join(sorted(_USES_DURATION)),
                )
            )
        return found

    @property
    def hardware_error(self) -> HardwareError:
        """``bits`` as flags (no bits for another kind)."""
        flags = HardwareError(0)
        for name in self.bits or ():
            flags |= HardwareError[name.upper()]
        return flags

    def describe(self) -> str:
        """``"silent servo 3"``, ``"corrupt rate 0.001"``, ``"hardware_error overload …"``."""
        who = "every servo" if self.ids is None else _servos(self.ids)
        if self.kind == "silent":
            return f"silent {who}"
        if self.kind in ("corrupt", "drop"):
            return f"{self.kind} rate {self.rate:g}"
        if self.kind == "hardware_error":
            return f"hardware_error {self.hardware_error.describe()} on {who}"
        if self.kind == "voltage_sag":
            return f"voltage_sag to {self.volts:g} V on {who}"
        return "unplug"

    def trigger(self) -> str:
        """``"at 2 s"`` or ``"on the 10th sync_write"``."""
        if self.on is None:
            return f"at {self.at_s:g} s"
        return f"on the {_ordinal(self.count)} {self.on}"


def _servos(ids: Sequence[int]) -> str:
    return ("servo " if len(ids) == 1 else "servos ") + ", ".join(str(i) for i in ids)


def _ordinal(n: int) -> str:
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{suffix}"


class FaultPlan(Section):
    """Faults to inject, and the seed of the emulator's random faults."""

    seed: int = 0
    faults: list[Fault] = Field(default_factory=list)

    def problems(self, at: str = "") -> list[Problem]:
        """Every relational problem of every fault."""
        here = f"{at}." if at else ""
        return [p for i, f in enumerate(self.faults) for p in f.problems(f"{here}faults[{i}]")]


def parse_fault_plan(data: Mapping[str, Any], source: str = "<fault plan>") -> FaultPlan:
    """Validate a fault plan document (as parsed from TOML).

    Raises :class:`~whexar.errors.ConfigError` listing every problem: the key
    path, the value found and what is allowed.
    """
    try:
        plan = FaultPlan.model_validate(data, context={"defer_relations": True})
    except ValidationError as exc:
        errors = exc.errors(include_url=False)
    else:
        found = plan.problems()
        if found:
            raise ConfigError(source, found)
        return plan
    problems = [problem_from_error(error, FaultPlan) for error in errors]
    # Faults that validated on their own still get their relational checks.
    failed = {e["loc"][1] for e in errors if len(e["loc"]) > 1 and e["loc"][0] == "faults"}
    raw = data.get("faults")
    if isinstance(raw, list):
        for i, item in enumerate(raw):
            if i in failed:
                continue
            try:
                fault = Fault.model_validate(item, context={"defer_relations": True})
            except ValidationError:
                continue
            problems.extend(fault.problems(f"faults[{i}]"))
    raise ConfigError(source, problems)


def load_fault_plan(path: str | Path) -> FaultPlan:
    """Read and validate a TOML fault plan (``config/faults/*.toml``)."""
    return parse_fault_plan(read_toml(path), str(path))


FaultPlanFile = Annotated[str, AfterValidator(loads(load_fault_plan, "a fault plan"))]
"""An actor parameter naming a fault plan file, checked with the wiring."""


# --------------------------------------------------------------------------- injection


def _u16(data: bytes, at: int) -> int:
    return data[at] | (data[at + 1] << 8)


@dataclass(slots=True)
class _Observed:
    """What one request did, as the event vocabulary sees it."""

    concerned: set[int] | None = field(default_factory=set)
    """IDs the request concerns; ``None`` = every servo (a broadcast)."""
    torque: dict[int | None, int] = field(default_factory=dict)
    """Torque Enable values written, by ID (``None`` = broadcast)."""


def _torque_write(
    torque: dict[int | None, int], sid: int | None, address: int, data: bytes
) -> None:
    offset = _TORQUE_ENABLE - address
    if 0 <= offset < len(data):
        torque[None if sid == _BROADCAST_ID else sid] = data[offset]


def _observe(code: int, sid: int, params: bytes) -> _Observed:
    """The IDs a packet concerns and the Torque Enable values it writes."""
    seen = _Observed()
    broadcast = sid == _BROADCAST_ID
    try:
        if code in (0x82, 0x8A):  # Sync Read: addr(2) len(2) ids…
            seen.concerned = set(params[4:])
        elif code == 0x83:  # Sync Write: addr(2) len(2) (id data…)…
            address, length = _u16(params, 0), _u16(params, 2)
            step = 1 + length
            ids = set()
            for at in range(4, len(params) - step + 1, step):
                ids.add(params[at])
                _torque_write(seen.torque, params[at], address, params[at + 1 : at + step])
            seen.concerned = ids
        elif code in (0x92, 0x9A):  # Bulk Read: (id addr(2) len(2))…
            seen.concerned = {params[at] for at in range(0, len(params) - 4, 5)}
        elif code == 0x93:  # Bulk Write: (id addr(2) len(2) data…)…
            ids = set()
            at = 0
            while at + 5 <= len(params):
                bid, address, length = params[at], _u16(params, at + 1), _u16(params, at + 3)
                ids.add(bid)
                _torque_write(seen.torque, bid, address, params[at + 5 : at + 5 + length])
                at += 5 + length
            seen.concerned = ids
        else:
            seen.concerned = None if broadcast else {sid}
            if code in (0x03, 0x04) and len(params) > 2:  # Write / Reg Write: addr(2) data…
                _torque_write(seen.torque, sid, _u16(params, 0), params[2:])
    except IndexError:  # a malformed packet: it concerns whom it is addressed to
        seen.concerned = None if broadcast else {sid}
    return seen


@dataclass(slots=True)
class _Run:
    """The life of one fault of the plan inside an injector."""

    index: int
    fault: Fault
    seen: int = 0
    state: Literal["waiting", "pending", "active", "over"] = "waiting"
    start: float = 0.0
    end: float = math.inf


LogSink = Callable[[float, str], None]


class FaultInjector:
    """Runs a :class:`FaultPlan` on a :class:`~whexar.bus.emulator.chain.ServoChain`.

    ``FaultInjector(plan).attach(chain)`` registers the injector as one of
    the chain's hooks and seeds ``chain.faults.rng`` with ``plan.seed``.
    :attr:`log` lists ``(emulator time, text)`` for every fault that started
    or ended; ``on_log`` is also called with each entry as it happens (from
    the thread that drives the chain).
    """

    def __init__(self, plan: FaultPlan, *, on_log: LogSink | None = None) -> None:
        self.plan = plan
        self.log: list[tuple[float, str]] = []
        self._on_log = on_log
        self._runs = [_Run(i, f) for i, f in enumerate(plan.faults)]
        self._chain: ServoChain | None = None
        self._base_corrupt = 0.0
        self._base_drop = 0.0
        self._base_unplugged = False
        self._base_volts: dict[int, float] = {}
        """Input voltage of each sagging servo before its sag."""

    def attach(self, chain: ServoChain) -> FaultInjector:
        """Hook into ``chain``; :class:`ConfigError` if a fault names a servo not on it."""
        if self._chain is not None:
            raise RuntimeError("a FaultInjector attaches to one chain only")
        present = sorted(chain.servos)
        problems = [
            Problem(f"faults[{run.index}].ids", sid, f"an ID on the bus: {_id_ranges(present)}")
            for run in self._runs
            for sid in run.fault.ids or ()
            if sid not in chain.servos
        ]
        if problems:
            raise ConfigError("fault plan", problems)
        self._chain = chain
        chain.faults.rng.seed(self.plan.seed)
        self._base_corrupt = chain.faults.corrupt_rate
        self._base_drop = chain.faults.drop_rate
        self._base_unplugged = chain.faults.unplugged
        chain.hooks.append(self)
        return self

    def update(self, t: float) -> None:
        """Start and end faults at emulator time ``t`` without a request.

        The chain runs the hook on every request; a driver that stops sending
        requests (an :class:`~whexar.bus.emulator.chain.EmulatedPort` raises on every
        access while unplugged) calls this to let time-bound faults end.
        """
        if self._chain is None:
            raise RuntimeError("attach the FaultInjector to a chain first")
        self(self._chain, t, ())

    @property
    def active(self) -> list[Fault]:
        """The faults in effect now."""
        return [run.fault for run in self._runs if run.state == "active"]

    # The chain calls this before it handles each request.
    def __call__(self, chain: ServoChain, t: float, packets: Sequence[Packet]) -> None:
        """Start and end faults at emulator time ``t``, then count this request's events."""
        changed = False
        for run in self._runs:
            if run.state == "waiting" and run.fault.at_s is not None and t >= run.fault.at_s:
                self._start(chain, run, run.fault.at_s)
                changed = True
            elif run.state == "pending":
                self._start(chain, run, run.start)
                changed = True
        for run in self._runs:
            if run.state == "active" and t >= run.end:
                run.state = "over"
                self._emit(run.end, f"fault {run.index}: {run.fault.describe()} ended")
                changed = True
        if changed:
            self._apply(chain, t)
        waiting = [r for r in self._runs if r.state == "waiting" and r.fault.on is not None]
        if not waiting:
            return
        observed = [
            (
                _INSTRUCTION_EVENTS.get(int(p.instruction)),
                _observe(int(p.instruction), p.id, bytes(p.params)),
            )
            for p in packets
        ]
        for run in waiting:
            hits = sum(_occurrences(run.fault, name, seen) for name, seen in observed)
            if not hits:
                continue
            run.seen += hits
            if run.seen >= run.fault.count:
                # Starts at the next request: this one is answered normally.
                run.state = "pending"
                run.start = t

    def _start(self, chain: ServoChain, run: _Run, start: float) -> None:
        fault = run.fault
        run.start = start
        run.end = start + fault.duration_s if fault.duration_s is not None else math.inf
        run.state = "active"
        ids = list(chain.servos) if fault.ids is None else fault.ids
        if fault.kind == "silent":
            for sid in ids:
                chain.faults.silent_until[sid] = max(
                    chain.faults.silent_until.get(sid, -math.inf), run.end
                )
        elif fault.kind == "hardware_error":
            for sid in ids:
                chain.servos[sid].raise_error(fault.hardware_error)
            run.end = start  # latched in the servo: nothing for the injector to end
        until = "for good" if math.isinf(run.end) else f"until {run.end:.3f} s"
        if fault.kind == "hardware_error":
            until = "latched until reboot"
        self._emit(
            start, f"fault {run.index}: {fault.describe()} started ({fault.trigger()}, {until})"
        )
        if fault.kind == "hardware_error":
            run.state = "over"

    def _apply(self, chain: ServoChain, t: float) -> None:
        """Set the chain's bus-wide state and voltages from the faults in effect."""
        active = [run.fault for run in self._runs if run.state == "active"]
        keep_corrupt, keep_drop = 1.0 - self._base_corrupt, 1.0 - self._base_drop
        for fault in active:
            if fault.kind == "corrupt" and fault.rate is not None:
                keep_corrupt *= 1.0 - fault.rate
            elif fault.kind == "drop" and fault.rate is not None:
                keep_drop *= 1.0 - fault.rate
        chain.faults.corrupt_rate = 1.0 - keep_corrupt
        chain.faults.drop_rate = 1.0 - keep_drop
        chain.faults.unplugged = self._base_unplugged or any(f.kind == "unplug" for f in active)
        sags: dict[int, float] = {}
        for fault in active:
            if fault.kind == "voltage_sag" and fault.volts is not None:
                for sid in chain.servos if fault.ids is None else fault.ids:
                    sags[sid] = min(sags.get(sid, math.inf), fault.volts)
        touched = set(self._base_volts) | set(sags)
        for sid in list(self._base_volts):
            if sid not in sags:  # its last sag ended: the supply comes back
                chain.servos[sid].input_voltage_v = self._base_volts.pop(sid)
        for sid, volts in sags.items():
            self._base_volts.setdefault(sid, chain.servos[sid].input_voltage_v)
            chain.servos[sid].input_voltage_v = volts
        for sid in touched:
            # The servo checks its voltage limits as it advances: below Min
            # Voltage Limit it latches Input Voltage Error for this request.
            chain.servos[sid].advance(t)

    def _emit(self, t: float, text: str) -> None:
        self.log.append((t, text))
        if self._on_log is not None:
            self._on_log(t, text)


def _occurrences(fault: Fault, name: str | None, seen: _Observed) -> int:
    """How many occurrences of ``fault.on`` one packet makes (0 or 1)."""
    wanted = set(fault.ids) if fault.ids is not None else None
    if fault.on in ("torque_enabled", "torque_disabled"):
        value = 1 if fault.on == "torque_enabled" else 0
        hits = [sid for sid, v in seen.torque.items() if v == value]
        if wanted is None:
            return int(bool(hits))
        return int(any(sid is None or sid in wanted for sid in hits))
    if name != fault.on:
        return 0
    if wanted is None or seen.concerned is None:
        return 1
    return int(bool(seen.concerned & wanted))


def _id_ranges(ids: Iterable[int]) -> str:
    """``"1–42"`` or ``"1–3, 7"``."""
    spans: list[list[int]] = []
    for sid in sorted(ids):
        if spans and sid == spans[-1][1] + 1:
            spans[-1][1] = sid
        else:
            spans.append([sid, sid])
    return ", ".join(f"{a}–{b}" if a != b else f"{a}" for a, b in spans) or "none"
