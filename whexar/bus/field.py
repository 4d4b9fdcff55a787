"""A field log's servo bus played back by time: recorded servos that answer whatever is asked.

Theory of operation
-------------------
A log recorded on a real clock (the robot, or ``whexar run`` against ``whexar emulate``
over a pty) holds every byte the bus scheduler wrote and read, with its time
(:func:`whexar.bus.sdk.tap_port`). Replayed on virtual time, the scheduler never writes
those bytes again exactly — its timers, retries and probes fall elsewhere, a goal lands
a cycle later — so a byte-for-byte replay (:mod:`whexar.bus.replay`) soon stalls. Here
the recording is not a script of packets but a record of what the servos *were*.

**Decoding** (:class:`BusDecoder`, :func:`decode`). A packet written that expects an
answer (e-manual, Protocol 2.0, "Status Packet": not a Sync or Bulk Write; to the
broadcast ID only Ping and the group reads) opens a request; the bytes read until the
next one answer it, and are decoded together once its exchange is over. Each status
packet is an :class:`Answered` fact: the servo, its ERR byte (bit 7, Alert: Hardware
Error Status is non-zero) and the register span it carries — a Read's, each servo's of
a Sync or Bulk Read, each servo's part of a Fast one
(:func:`~whexar.bus.protocol.split_fast_status`), a Ping's Model Number (address 0) and
Firmware Version (6) — stamped when the reply was all there. Where the SDK gave up
waiting (a recorded ``timeout``), the servo it waited for — a Ping's or a Read's, the
first of a Sync Read's that had not answered, since the SDK reads them in the order it
asked — is :class:`Silent`. Every write (Write, Sync Write, Bulk Write, Reboot…) is a
:class:`Written` fact per servo.

**The servos** are the emulator's :class:`~whexar.bus.emulator.chain.ServoChain` — the
same instructions, broadcast rules, status packets and bus timing — of
:class:`FieldServo` s, whose horn no dynamics move. Its
:attr:`~whexar.bus.emulator.chain.ServoChain.mover`, called at the bus time ``t`` of
every transaction, applies what was recorded up to ``t``, held until the next value:

* *measured* registers — Hardware Error Status (70) and the present values (120–146),
  MX (2.0) control table — are the latest recorded; so is the Alert bit of every status;
* *settings* (the writable registers: EEPROM, Torque Enable, goals…) hold what was
  last written to them: the recorded values until the replay writes one itself, the
  replay's from then on (until a reboot, for the RAM). So the start-up survey finds
  the robot's EEPROM and torque, and a read-back the robot made later, on its slower
  clock, does not undo the replay's own write;
* a servo answers while its latest evidence is an answer no older than
  ``stale_after_s`` (:data:`STALE_AFTER_S`); recorded silent, or *stale*, it neither
  hears nor answers, and the scheduler degrades it as on the robot;
* before a servo's first evidence, that evidence holds, and so do the values it
  gave within ``stale_after_s`` of it (its start-up survey): a replayed start-up that
  runs ahead of the robot's finds what the robot's found;
* Fast Sync Read works on a servo once the recording shows it answering one;
* a register never recorded nor written has the emulator's initial value. Each read
  is counted (:class:`ReadCounts`): fresh, *stale* (a measured value recorded longer
  ago than ``stale_after_s``) or *unknown*, so that a replay with another read plan
  than the recording's says what it read that the robot never reported.

**By the recording's clock** (``pace``). A packet the replay sends that the recording
sent too — the same bytes, the first within ``write_window_s`` of ``t`` (:meth:`FieldBus.pace`)
— is answered with the values recorded up to the end of the recording's exchange, and
lasts until then (at least the emulator's time for it): the replayed bus keeps the
robot's cycle times, its USB latency and its timeouts included, so the actors' timers
fall where they fell on the robot. Any other packet takes the emulator's time. Nothing
waits for a packet the recording does not have. Such a packet that reads only measured
registers (or pings), answered whole on the robot, gets the very bytes the robot's
servos sent: what the emulator would build again from the same values, CRCs and all,
without the emulator's work of building them.

**Writes compared** (:class:`WriteMismatch`). Each register the replay writes to a
servo is compared with what the recording wrote to the same servo and register within
``write_window_s`` (:data:`WRITE_WINDOW_S`) of that time, and with the value held
entering that window: it agrees when it lies within their span — a trajectory sampled
a little earlier or later lies between the goals sent around it. A recorded write the
replay did not make within its window is a mismatch too (``written=None``), unless the
replay's servo holds that value already (a keepalive the replay sent at another time).
Mismatches are counted per register and kept (the first :data:`KEPT_MISMATCHES`);
writes after the recording's end are counted, not compared. Nothing raises, nothing waits.

**Lazily.** The events are read as the replay goes (:class:`~whexar.runtime.streams.Hand`),
decoded ``max(stale_after_s, write_window_s)`` ahead of the bus time: what is held is
that much of the recording, however long it is. Past its end, the servos go stale.

:class:`FieldBus` is the recorded bus; its :attr:`~FieldBus.chain`, registered
under :data:`~whexar.bus.emulator.chain.SERVO_CHAIN`, opens as ``port = "emulator:NAME"``.
"""

from __future__ import annotations

import dataclasses
import math
from collections import Counter, deque
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Final

from whexar.bus.control_table import MODELS, TABLE_SIZE, Register, ServoModel
from whexar.bus.emulator.chain import ServoChain, Transaction
from whexar.bus.emulator.servo import VirtualServo
from whexar.bus.emulator.timing import TimingModel
from whexar.bus.field_decode import (
    MEASURED,
    OTHER_NAMES,
    OTHER_WRITES,
    WRITES,
    Answered,
    BusDecoder,
    Exchange,
    Fact,
    Recorded,
    Silent,
    Written,
    decode,
    expects_answer,
    packet_writes,
)
from whexar.bus.protocol import (
    ALERT,
    BROADCAST_ID,
    Packet,
)
from whexar.errors import UsageError
from whexar.runtime.streams import Hand

__all__ = [
    "KEPT_MISMATCHES",
    "STALE_AFTER_S",
    "WRITE_WINDOW_S",
    "Answered",
    "BusDecoder",
    "Exchange",
    "Fact",
    "FieldBus",
    "FieldServo",
    "ReadCounts",
    "Silent",
    "WriteMismatch",
    "Written",
    "decode",
    "expects_answer",
    "packet_writes",
]

STALE_AFTER_S: Final = 1.0
"""How long a servo's last recorded answer holds. Above the slowest any read plan polls a
healthy servo — the ``default`` plan reads the 18 servos outside its cycle only in its
round-robin health reads, 7 at a time at 10 Hz: each every 0.6 s — so no servo is taken
for silent between two of its reads; short enough that where the recording says nothing
more (its end, a cut file) the scheduler finds the servos silent within about a second,
as on a bus gone quiet, rather than reading values that no longer mean anything."""
WRITE_WINDOW_S: Final = 0.02
"""How far apart in time a replayed write and the recorded writes it is compared with, or
a replayed packet and the recorded one it is paced by, may lie: two control cycles of
the robot (9.4 ms each for the ``default`` plan's 24 servos through a pty at 1 Mbps), so a
goal that lands a cycle earlier or later still agrees."""
KEPT_MISMATCHES: Final = 1000
"""Mismatches kept as records (all are counted): a changed gait replayed for an hour
would otherwise keep one per goal."""


_UNKNOWN: Final = -math.inf
_KNOWN: Final = math.inf
""":attr:`FieldServo.seen` of an address: never recorded; a setting or constant once known."""


# --------------------------------------------------------------------------- the servos


@dataclass(slots=True)
class ReadCounts:
    """What the replay's reads were given, counted per register of each servo read."""

    fresh: int = 0
    """Spans read whose every value was recorded (or written) recently enough."""
    stale: Counter[str] = field(default_factory=Counter)
    """Measured registers read whose last recorded value was older than the bound."""
    unknown: Counter[str] = field(default_factory=Counter)
    """Registers read that were never recorded nor written: the emulator's initial values."""


class _Playback:
    """What every played-back servo of one chain shares: the bus time and the counters."""

    def __init__(self, stale_after_s: float) -> None:
        self.now = 0.0
        self.stale_after_s = stale_after_s
        self.end = math.inf
        """The recording's last event (once it has been read to its end)."""
        self.reads = ReadCounts()
        self.stale_servos: dict[int, float] = {}
        self.silenced: dict[int, float] = {}


_Ops = tuple[tuple[int, int, bool, tuple[Register, ...]], ...]
"""How a recorded span is applied: per run of registers, (first, end address, measured,
the settings among them); a run of read-only registers has no settings."""
_OPS: dict[tuple[str, int, int], _Ops] = {}
_REGISTERS: dict[tuple[str, int, int], tuple[Register, ...]] = {}


def _registers(model: ServoModel, start: int, length: int) -> tuple[Register, ...]:
    """The registers of ``model`` wholly inside ``[start, start + length)``, by address."""
    key = (model.name, start, length)
    found = _REGISTERS.get(key)
    if found is None:
        end = start + length
        found = tuple(r for r in model.registers.values() if start <= r.address and r.end <= end)
        if len(_REGISTERS) < 4096:
            _REGISTERS[key] = found
    return found


def _measured(reg: Register) -> bool:
    return any(a <= reg.address < b for a, b in MEASURED)


def _ops(model: ServoModel, start: int, length: int) -> _Ops:
    key = (model.name, start, length)
    found = _OPS.get(key)
    if found is not None:
        return found
    ops: list[tuple[int, int, bool, tuple[Register, ...]]] = []
    for reg in _registers(model, start, length):
        if reg.access == "R":
            measured = _measured(reg)
            last = ops[-1] if ops else None
            if last and not last[3] and last[1] == reg.address and last[2] == measured:
                ops[-1] = (last[0], reg.end, measured, ())  # one run of read-only bytes
            else:
                ops.append((reg.address, reg.end, measured, ()))
        else:
            ops.append((reg.address, reg.end, False, (reg,)))
    found = tuple(ops)
    if len(_OPS) < 4096:
        _OPS[key] = found
    return found


class FieldServo(VirtualServo):
    """A servo whose state is the recording's (module doc): no dynamics move its horn,
    its present values and Alert bit are set by :meth:`apply`, it is silent where the
    recording says so or has said nothing for too long."""

    def __init__(self, servo_id: int, model: ServoModel, playback: _Playback) -> None:
        super().__init__(servo_id, model)
        self._play = playback
        self._stale_after_s = playback.stale_after_s
        # The emulator's present values once, as defaults for what is never recorded.
        VirtualServo._refresh(self)
        self.alert = 0
        """The Alert bit (0x80) of the last recorded status: every status answers with it."""
        self.answered_at = -math.inf
        """When the recording last showed it answering."""
        self.silent_at = -math.inf
        """When the recording last showed it silent."""
        self.first_at = math.inf
        """When the recording first showed it, answering or silent."""
        self.seen: list[float] = [_KNOWN] * TABLE_SIZE
        """Per address: when the recording last gave a measured value, :data:`_KNOWN` for a
        setting recorded or written, :data:`_UNKNOWN` never. Addresses of no register count
        as known: nothing is missing there."""
        for reg in model.registers.values():
            self.seen[reg.address : reg.end] = [_UNKNOWN] * reg.size
        self._spans_seen: set[tuple[int, int]] = set()
        """Spans recorded at least once (:meth:`first_values` has nothing left to do)."""
        self.owned = bytearray(TABLE_SIZE)
        """Per address, 1 where the replay wrote the setting: the recording's values no
        longer apply there (until a reboot, for the RAM)."""

    # ------------------------------------------------------------------ the recording

    def apply(self, start: int, data: bytes, t: float) -> None:
        """Set the span recorded at ``t`` (module doc)."""
        table, seen, owned = self.table, self.seen, self.owned
        for first, end, measured, settings in _ops(self.model, start, len(data)):
            if not settings:
                table[first:end] = data[first - start : end - start]
                seen[first:end] = [t if measured else _KNOWN] * (end - first)
                continue
            reg = settings[0]
            if owned[first]:
                continue  # the replay wrote it since: its own value holds
            value = data[first - start : end - start]
            seen[first:end] = [_KNOWN] * (end - first)
            if table[first:end] != value:
                # The firmware's way, so that the servo's cached settings follow.
                self.set_register(reg.name, reg.decode(value, first))

    def first_values(self, start: int, data: bytes, t: float) -> None:
        """Of the span recorded at ``t``, set the registers never recorded before: a first
        value holds back to the start (module doc)."""
        key = (start, len(data))
        if key in self._spans_seen:
            return
        seen = self.seen
        for reg in _registers(self.model, start, len(data)):
            if seen[reg.address] == _UNKNOWN and not self.owned[reg.address]:
                self.apply(reg.address, data[reg.address - start : reg.end - start], t)
        self._spans_seen.add(key)

    def _refresh(self) -> None:
        """Nothing: the present values are the recording's, set by :meth:`apply` (the
        emulator computes them here from the horn's motion)."""

    @property
    def status_error(self) -> int:
        """The Alert bit of the last recorded status."""
        return self.alert

    @property
    def booting_until(self) -> float:
        """When the boot after the last reboot the replay made ends."""
        return self._ready_at

    def booting(self, t: float) -> bool:
        """Silent at ``t``: booting after a reboot, recorded silent, or stale (module doc)."""
        # Asked of every servo for every packet: the common case in one chained test.
        if self.silent_at <= self.answered_at >= t - self._stale_after_s and t >= self._ready_at:
            return False
        if super().booting(t):
            return True
        answered, silent = self.answered_at, self.silent_at
        if silent > answered:
            self._play.silenced.setdefault(self.id, silent)
            return True
        if answered == -math.inf:
            return True  # never heard of: not on the robot's bus
        if t <= self._play.end:
            self._play.stale_servos.setdefault(self.id, answered + self._stale_after_s)
        return True

    # ------------------------------------------------------------------ the replay

    def read(self, address: int, length: int) -> bytes:
        """The span, counted as fresh, stale or unknown (:class:`ReadCounts`)."""
        end = address + length
        if address >= 0 and end <= TABLE_SIZE:
            play = self._play
            oldest = min(self.seen[address:end], default=_KNOWN)
            if oldest >= play.now - self._stale_after_s:
                play.reads.fresh += 1
            else:
                self._count(address, length, play)
        return super().read(address, length)

    def _count(self, address: int, length: int, play: _Playback) -> None:
        horizon = play.now - self._stale_after_s
        for reg in _registers(self.model, address, length):
            oldest = min(self.seen[reg.address : reg.end])
            if oldest == _UNKNOWN:
                play.reads.unknown[reg.name] += 1
            elif oldest < horizon:
                play.reads.stale[reg.name] += 1

    def write(self, address: int, data: bytes) -> int:
        """The emulator's write; what it takes is the replay's from then on."""
        error = super().write(address, data)
        n = len(data)
        if not error and 0 in self.owned[address : address + n]:  # a goal: owned since
            self.owned[address : address + n] = bytes((1,)) * n
            self.seen[address : address + n] = [_KNOWN] * n
        return error

    def reboot(self, t: float | None = None) -> None:
        """The emulator's reboot at the bus time; what it measures is kept (a reboot moves
        no horn), and the recording's RAM settings apply again until written."""
        present = self.table[120:147]
        super().reboot(self._play.now if t is None else t)
        self.table[120:147] = present
        self.owned[64:] = bytes(TABLE_SIZE - 64)


# --------------------------------------------------------------------------- writes


@dataclass(frozen=True, slots=True)
class WriteMismatch:
    """A register the replay wrote otherwise than the recording, near the same time."""

    t: float
    """The replay's bus time of the write (the recorded time, for one it did not make)."""
    servo_id: int
    register: str
    """The register's name (``goal_position``), or ``reboot``, ``factory_reset``, ``clear``."""
    recorded: int | None
    """What the recording wrote nearest in time; ``None``: nothing, near that time."""
    written: int | None
    """What the replay wrote; ``None``: nothing, within the window of a recorded write."""

    def describe(self) -> str:
        """``t = 3.201 s, servo 9 goal_position: recorded 2100, written 2160``."""
        rec = "nothing" if self.recorded is None else str(self.recorded)
        wrote = "nothing" if self.written is None else str(self.written)
        return (
            f"t = {self.t:.3f} s, servo {self.servo_id} {self.register}: "
            f"recorded {rec}, written {wrote}"
        )


class _Writes:
    """The recorded writes within the window, and the comparison of the replay's."""

    def __init__(self, window_s: float, keep: int) -> None:
        self.window_s = window_s
        self.keep = keep
        self.recent: dict[tuple[int, str], deque[Recorded]] = {}
        self.held: dict[tuple[int, str], int] = {}
        """The last recorded value of each servo and register that left the window."""
        self.replayed: dict[tuple[int, str], int] = {}
        """The last value the replay wrote to each servo and register."""
        self.order: deque[tuple[tuple[int, str], Recorded]] = deque()
        self.compared = 0
        self.mismatched = 0
        self.counts: Counter[str] = Counter()
        self.kept: list[WriteMismatch] = []

    def recorded(
        self, t: float, sid: int, register: str, value: int
    ) -> tuple[tuple[int, str], Recorded]:
        entry = Recorded(t, value)
        key = (sid, register)
        queue = self.recent.get(key)
        if queue is None:
            queue = self.recent[key] = deque()
        queue.append(entry)
        kept = (key, entry)
        self.order.append(kept)
        return kept

    def agreed(self, t: float, entries: Iterable[tuple[tuple[int, str], Recorded]]) -> None:
        """The replay wrote at ``t`` exactly these recorded writes (made about then): each
        agrees, and meets the recorded ones of its servo and register in the window."""
        replayed, recent = self.replayed, self.recent
        early, late = t - self.window_s, t + self.window_s
        for key, entry in entries:
            self.compared += 1
            replayed[key] = entry.value
            for e in recent[key]:
                if e.t > late:
                    break
                if e.t >= early:
                    e.met = True

    def expire(self, t: float) -> None:
        """Recorded writes now out of reach of any write to come: one the replay did not
        make is a mismatch."""
        order, horizon = self.order, t - self.window_s
        while order and order[0][1].t < horizon:
            key, entry = order.popleft()
            self.recent[key].popleft()
            self.held[key] = entry.value
            if not entry.met and self.replayed.get(key) != entry.value:
                # Not a repeat of what the replay's servo holds (a keepalive): a difference.
                self._mismatch(WriteMismatch(entry.t, key[0], key[1], entry.value, None))

    def written(self, t: float, sid: int, register: str, value: int) -> None:
        self.compared += 1
        key = (sid, register)
        self.replayed[key] = value
        held = self.held.get(key)
        lo = hi = held
        nearest, gap = held, math.inf
        queue = self.recent.get(key)
        if queue:
            early, late = t - self.window_s, t + self.window_s
            for e in queue:  # in time order, the expired ones gone
                at = e.t
                if at > late:
                    break
                if at < early:
                    continue
                e.met = True
                v = e.value
                if lo is None or v < lo:
                    lo = v
                if hi is None or v > hi:
                    hi = v
                if abs(at - t) < gap:
                    gap, nearest = abs(at - t), v
        if lo is None or hi is None or not lo <= value <= hi:
            self._mismatch(WriteMismatch(t, sid, register, nearest, value))

    def _mismatch(self, m: WriteMismatch) -> None:
        self.mismatched += 1
        self.counts[m.register] += 1
        if len(self.kept) < self.keep:
            self.kept.append(m)


# --------------------------------------------------------------------------- the bus


Pacer = Callable[[bytes, float], "tuple[float, bytes | None] | None"]
"""``(request, t) -> (end, reply)``: when the recording's exchange of the same packet was
over, if the replay's at ``t`` is that one, and its recorded reply if that is the answer
(:meth:`FieldBus.pace`)."""


class _PacedChain(ServoChain):
    """The emulator's chain, whose exchanges take the recording's time where they are the
    recording's: a packet the recording also sent, about then, is answered with the values
    recorded up to that exchange's end, and lasts until then (module doc)."""

    pacer: Pacer | None = None

    def transact(self, request: bytes, t: float) -> Transaction:
        paced = None if self.pacer is None else self.pacer(bytes(request), t)
        if paced is None or paced[0] <= t:
            return super().transact(request, t)
        end, reply = paced
        wait = end - t
        if reply is not None:
            # What the servos measured, asked when the robot asked it: its very answer
            # (what the emulator would build again from the recorded values), not executed.
            self.advance(end)
            stats = self.stats
            stats.requests += 1
            stats.bytes_in += len(request)
            stats.bytes_out += len(reply)
            return Transaction(bytes(request), reply, wait, (), ((len(reply), wait),))
        tx = super().transact(request, end)
        if wait <= tx.cost_s:
            return tx
        later = wait - tx.cost_s
        arrivals = tuple((n, at + later) for n, at in tx.arrivals)
        return dataclasses.replace(tx, cost_s=wait, arrivals=arrivals)


class FieldBus:
    """A field log's bus played back by time (module doc): :attr:`chain` to open as an
    emulated chain, and what the replay did on it."""

    def __init__(
        self,
        events: Iterable[tuple[str, float, bytes]],
        *,
        models: Mapping[int, str],
        baudrate: int,
        stale_after_s: float = STALE_AFTER_S,
        write_window_s: float = WRITE_WINDOW_S,
        pace: bool = True,
        keep: int = KEPT_MISMATCHES,
    ) -> None:
        if not stale_after_s > 0 or not write_window_s >= 0:
            raise UsageError(
                f"stale_after_s = {stale_after_s!r}, write_window_s = {write_window_s!r}: "
                "the bound must be > 0 and the window ≥ 0"
            )
        self._events = Hand.of(events)
        """Read as the replay goes (module doc)."""
        self._exchanges: deque[Exchange] = deque()
        """Recorded packets not yet passed (:meth:`pace`)."""
        self._decoder = BusDecoder(self._exchanges if pace else None, self._recorded_write)
        self._first = True
        """No packet was paced yet: the first may wait for the recording's bus to start."""
        self.paced = 0
        """Exchanges that took the recording's time (:meth:`pace`)."""
        self.reused = 0
        """Of those, the reads answered with the recorded reply itself (:meth:`pace`)."""
        self._matched: Exchange | None = None
        """The recorded exchange the transaction under way is (:meth:`pace`)."""
        self._writing: list[tuple[tuple[int, str], Recorded]] | None = None
        """The recorded writes of the packet being decoded."""
        self._facts: deque[Answered | Silent] = deque()
        """Decoded, not yet applied (recorded after the bus time)."""
        self._decoded_to = -math.inf
        self._lookahead = max(stale_after_s, write_window_s)
        self._play = _Playback(stale_after_s)
        servos: list[FieldServo] = []
        for sid, name in models.items():
            if name not in MODELS:
                raise UsageError(f"servo {sid}: model {name!r}; allowed: {', '.join(MODELS)}")
            servos.append(FieldServo(sid, MODELS[name], self._play))
        self.servos: dict[int, FieldServo] = {s.id: s for s in servos}
        self.chain = _PacedChain(servos, TimingModel(baudrate=baudrate))
        """The servos, opened by the bus scheduler once registered as an emulated chain."""
        if pace:
            self.chain.pacer = self.pace
        self.chain.mover = self._move
        self.chain.hooks.append(self._replayed)
        self._writes = _Writes(write_window_s, keep)
        self.stale_after_s = stale_after_s
        self.write_window_s = write_window_s
        self.ended = False
        """The recording has been read to its end."""
        self.writes_past_end = 0
        """Write packets the replay sent after the recording's end (not compared)."""
        self.strangers: Counter[int] = Counter()
        """Recorded answers from IDs not in ``models``, per ID (ignored)."""

    # ------------------------------------------------------------------ results

    @property
    def mismatches(self) -> Sequence[WriteMismatch]:
        """The writes that differ from the recording's, in the order found (the first
        ``keep``; :attr:`mismatched` counts them all)."""
        return self._writes.kept

    @property
    def mismatched(self) -> int:
        """How many writes differ (replayed and not recorded, or recorded and not replayed)."""
        return self._writes.mismatched

    @property
    def mismatch_counts(self) -> Counter[str]:
        """Mismatches per register name."""
        return self._writes.counts

    @property
    def writes_compared(self) -> int:
        """Registers the replay wrote to a servo, each compared with the recording."""
        return self._writes.compared

    @property
    def stale_servos(self) -> dict[int, float]:
        """Servo → when it first went stale (no recorded answer for :attr:`stale_after_s`)
        while the recording went on; past its end every servo does."""
        return self._play.stale_servos

    @property
    def silenced(self) -> dict[int, float]:
        """Servo → when the replay first found it silent as recorded (a timeout)."""
        return self._play.silenced

    @property
    def reads(self) -> ReadCounts:
        """What the replay's reads were given (:class:`ReadCounts`)."""
        return self._play.reads

    @property
    def packets(self) -> int:
        """Recorded packets decoded so far."""
        return self._decoder.packets

    @property
    def recording_end(self) -> float | None:
        """The time of the recording's last bus event, once it has been read to its end."""
        return self._play.end if self.ended else None

    def describe(self) -> str:
        """One line: what was played back, the writes compared, the servos silent or stale,
        the reads of values stale or never recorded."""
        end = self.recording_end
        to = f" (to {end:.3f} s)" if end is not None else ""
        head = (
            f"played back by time: {self.packets} recorded packets{to}, {self.paced} "
            f"exchanges at their recorded times ({self.reused} answered as recorded); "
            f"{self.writes_compared} writes compared, {self.mismatched} differing"
        )
        if self.mismatched:
            counts = self.mismatch_counts.most_common()
            head += " (" + ", ".join(f"{name} {n}" for name, n in counts) + ")"
        if self.writes_past_end:
            head += f", {self.writes_past_end} write packets past the recording's end"
        silent = _ids(self.silenced) or "none"
        stale = _ids(self.stale_servos) or "none"
        reads = self.reads
        return (
            f"{head}; silent as recorded: {silent}; stale after {self.stale_after_s:g} s: "
            f"{stale}; reads {reads.fresh} fresh, {sum(reads.stale.values())} stale, "
            f"{sum(reads.unknown.values())} never recorded"
        )

    def left(self) -> int:
        """How many recorded packets were not decoded (the rest of the events is read)."""
        decoder, out = BusDecoder(), list[Fact]()
        for direction, t, data in self._events:
            decoder.feed(direction, t, data, out)
            out.clear()
        return decoder.packets

    # ------------------------------------------------------------------ the chain's calls

    def pace(self, request: bytes, t: float) -> tuple[float, bytes | None] | None:
        """When the recording's exchange of ``request`` was over, if the replay's at bus
        time ``t`` is that one — the first the recording sent within ``write_window_s`` of
        ``t`` (for the replay's first packet, sent before the recording's bus started:
        whenever it did) — and its recorded reply, if that is the answer (:meth:`_answer`).
        Every recorded packet up to it is passed; ``None``: the recording has none there."""
        exchanges = self._exchanges
        self._matched = None
        w = self.write_window_s
        while exchanges and exchanges[0].t < t - w:
            exchanges.popleft()
        ahead = t + w
        if self._first:
            self._first = False
            if not self.ended:
                self._read_to(t + self._lookahead)
            if exchanges and t < self._began(exchanges[0]):
                ahead = math.inf  # the replay's bus starts first: it waits for the robot's
        for k, exchange in enumerate(exchanges):
            if self._began(exchange) > ahead:
                return None
            if exchange.data == request:
                for _ in range(k + 1):
                    exchanges.popleft()
                self.paced += 1
                self._matched = exchange
                return exchange.end, self._answer(exchange)
        return None

    def _answer(self, exchange: Exchange) -> bytes | None:
        """The recorded reply of ``exchange`` if it is the replay's answer: it asked only
        what the servos measure, was answered whole, and no servo asked is booting in the
        replay alone (after a reboot the recording did not make)."""
        asked, reply = exchange.asked, exchange.reply
        if asked is None or not asked.measured or reply is None or exchange.timed_out:
            return None
        chain = self.chain
        faults = chain.faults
        if len(chain.hooks) != 1 or faults.corrupt_rate or faults.drop_rate or faults.tx_fail:
            return None  # someone else's hook or faults: the emulator's way, every byte
        servos, end = self.servos, exchange.end
        for sid, _, _ in asked.order:
            servo = servos.get(sid)
            if servo is not None and servo.booting_until > end:
                return None
        self._play.reads.fresh += len(asked.order)
        self.reused += 1
        return reply

    def _began(self, exchange: Exchange) -> float:
        """When a recorded exchange began: as stamped, or — stamped once over, by an
        emulated port — its bus time before that (twice the emulator's, for a slower bus),
        after the exchange before it."""
        began = exchange.began
        if began is not None:
            return began
        began = exchange.t
        if exchange.first_read == began:
            timing = self.chain.timing
            n = exchange.read
            took = timing.wire_s(len(exchange.data) + n) + timing.turnaround_s
            began = max(exchange.after, began - 2 * (took + timing.per_status_byte_s * n))
        if exchange is not self._decoder.last:  # its reply is all decoded: final
            exchange.began = began
        return began

    def _read_to(self, t: float) -> None:
        """Decode the recording up to recorded time ``t`` (or its end)."""
        hand, decoder = self._events, self._decoder
        queue = hand.queue
        out: list[Fact] = []
        last = self._decoded_to
        while last <= t:
            if not queue and not hand.fill():
                decoder.close(out)
                self._take(out)
                self.ended = True
                self._play.end = last
                break
            direction, last, data = queue.popleft()
            decoder.feed(direction, last, data, out)
            if self._writing is not None:  # the packet's writes, with its exchange
                if decoder.last is not None:
                    decoder.last.writes = self._writing
                self._writing = None
            if out:
                self._take(out)
                out.clear()
        self._decoded_to = last

    def _take(self, decoded: list[Fact]) -> None:
        """Keep facts just decoded: the recorded writes to compare with, the answers and
        silences to apply at their time — and now, where they are a servo's first."""
        servos, facts = self.servos, self._facts
        for fact in decoded:
            if isinstance(fact, Written):
                continue  # to _recorded_write instead, by the decoder
            servo = servos.get(fact.servo_id)
            if servo is None:
                self.strangers[fact.servo_id] += 1
                continue
            first = servo.first_at == math.inf
            if first:
                servo.first_at = fact.t  # the first evidence holds back to the start
            if isinstance(fact, Answered):
                if fact.fast:
                    servo.fast_sync_read = True  # a capability: known from now on
                if first:
                    servo.answered_at = fact.t
                    servo.alert = fact.error & ALERT
                if fact.t <= servo.first_at + self.stale_after_s:  # the start-up's values
                    for start, span in fact.spans:
                        servo.first_values(start, span, fact.t)
            elif first:
                servo.silent_at = fact.t
            facts.append(fact)

    def _recorded_write(self, t: float, inst: int, entries: list[tuple[int, int, bytes]]) -> None:
        """Keep what a recorded packet writes for comparison, and for its exchange (made
        once the packet is decoded: :meth:`_read_to` hands them over)."""
        kept: list[tuple[tuple[int, str], Recorded]] = []
        self._writing = kept
        recorded, servos = self._writes.recorded, self.servos
        for one, start, data in entries:
            for sid in list(servos) if one == BROADCAST_ID else (one,):
                servo = servos.get(sid)
                if servo is not None:
                    for name, a, b, signed in _plan(servo.model, inst, start, len(data)):
                        value = int.from_bytes(data[a:b], "little", signed=signed) if b else 1
                        kept.append(recorded(t, sid, name, value))

    def _move(self, t: float) -> None:
        """The chain's mover: the recording applied up to bus time ``t`` (module doc)."""
        self._play.now = t
        if not self.ended and self._decoded_to <= t + self._lookahead:
            self._read_to(t + self._lookahead)
        facts, servos = self._facts, self.servos
        while facts and facts[0].t <= t:
            fact = facts.popleft()
            servo = servos[fact.servo_id]
            if isinstance(fact, Silent):
                servo.silent_at = fact.t
                continue
            servo.answered_at = fact.t
            servo.alert = fact.error & ALERT
            for start, span in fact.spans:
                servo.apply(start, span, fact.t)
        if self._writes.order:
            self._writes.expire(t)

    def _replayed(self, chain: ServoChain, t: float, packets: Sequence[Packet]) -> None:
        """The chain's hook: each register the replay writes, compared with the recording."""
        matched, self._matched = self._matched, None
        if matched is not None and matched.writes:
            # The recording's very packet, within the window: every register agrees.
            self._writes.agreed(t, matched.writes)
            return
        servos, written = self.servos, self._writes.written
        for packet in packets:
            inst = packet.instruction
            if inst not in WRITES and inst not in OTHER_WRITES:
                continue
            if self.ended and t > self._play.end + self.write_window_s:
                self.writes_past_end += 1  # nothing recorded to compare with
                continue
            for sid, start, data in packet_writes(packet):
                for one in list(servos) if sid == BROADCAST_ID else (sid,):
                    servo = servos.get(one)
                    if servo is not None:
                        for name, a, b, signed in _plan(servo.model, inst, start, len(data)):
                            value = int.from_bytes(data[a:b], "little", signed=signed) if b else 1
                            written(t, one, name, value)


_Plan = tuple[tuple[str, int, int, bool], ...]
_PLANS: dict[tuple[str, int, int, int], _Plan] = {}


def _plan(model: ServoModel, instruction: int, start: int, length: int) -> _Plan:
    """Per register a write sets: its name, where its bytes lie in the data (``0, 0``:
    none, for a Reboot and the like: value 1), its sign."""
    key = (model.name, instruction, start, length)
    plan = _PLANS.get(key)
    if plan is not None:
        return plan
    other = OTHER_NAMES.get(instruction)
    regs = _registers(model, start, length)
    if other is not None:
        plan = ((other, 0, 0, False),)
    elif not regs:  # no whole register: the bytes as written
        plan = ((f"@{start}", 0, length, False),)
    else:
        plan = tuple((r.name, r.address - start, r.end - start, r.signed) for r in regs)
    if len(_PLANS) < 4096:
        _PLANS[key] = plan
    return plan


def _ids(first: Mapping[int, float], shown: int = 6) -> str:
    """``servo 9 from 3.201 s, servo 12 from 4.000 s``, in time order (the first
    ``shown``, then how many in all)."""
    ordered = sorted(first.items(), key=lambda item: item[1])
    text = ", ".join(f"servo {sid} from {t:.3f} s" for sid, t in ordered[:shown])
    return text + (f"… ({len(ordered)} servos)" if len(ordered) > shown else "")
