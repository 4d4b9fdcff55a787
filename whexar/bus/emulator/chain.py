"""Virtual Dynamixel MX (2.0) servos daisy-chained on one bus, answering byte for byte.

Theory of operation
-------------------
:class:`ServoChain` plays the far end of the bus. :meth:`ServoChain.transact`
takes the bytes a host sends and the bus time ``t`` they are sent at, and
returns the bytes the servos send back and how long the exchange keeps the
bus busy. In order:

1. decode every complete instruction packet (a bad CRC is ignored, as a
   servo ignores it, and counted);
2. bring every servo's dynamics up to ``t``
   (:meth:`~whexar.bus.emulator.servo.VirtualServo.advance` is lazy and
   exact: nothing moves between transactions, nothing is sampled), or let
   the :attr:`~ServoChain.mover` (a physics world) move them all at once;
3. run the hooks (fault plans, a physics world) with ``t`` and the packets;
4. execute each instruction as the e-manual describes (broadcast rules,
   Status Return Level, the group reads and writes; each servo applies its
   own access rules and limits) and build the status packets each servo
   sends, in the order the instruction lists the IDs;
5. apply :class:`FaultState`: silent servos neither hear nor answer, status
   packets are dropped, bits are flipped;
6. price the exchange with the chain's
   :class:`~whexar.bus.emulator.timing.TimingModel`.

:class:`~whexar.bus.emulator.port.EmulatedPort` makes a chain a port that
dynamixel-sdk drives unmodified. Nothing here reads a clock: time is always
an argument (``t``).
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Final

from whexar.bus.control_table import MODELS, TABLE_SIZE, return_delay_units
from whexar.bus.emulator.dynamics import LoadModel
from whexar.bus.emulator.servo import VirtualServo
from whexar.bus.emulator.timing import DEFAULT_TIMING, TimingModel
from whexar.bus.protocol import (
    BROADCAST_ID,
    Instruction,
    Packet,
    PacketDecoder,
    PacketError,
    StatusError,
    encode_status,
    fast_status_parts,
    parse_bulk_read_params,
    parse_bulk_write_params,
    parse_read_params,
    parse_sync_read_params,
    parse_sync_write_params,
    parse_write_params,
)
from whexar.errors import UsageError
from whexar.runtime.devices import DeviceKind


@dataclass
class FaultState:
    """Faults the chain applies to every transaction; fault plans mutate it."""

    silent_until: dict[int, float] = field(default_factory=dict)
    """ID → bus time until which that servo neither hears nor answers (``math.inf``: for good)."""
    corrupt_rate: float = 0.0
    """Probability per status byte of one flipped bit."""
    drop_rate: float = 0.0
    """Probability that a status packet (or a servo's part of a fast one) is not sent."""
    unplugged: bool = False
    """The port is gone: :class:`EmulatedPort` raises ``OSError(EIO)`` on write and read."""
    tx_fail: int = 0
    """The next ``tx_fail`` host writes are lost: the adapter takes no byte of them (the
    SDK reports a failed transmit) and no servo hears them."""
    rng: random.Random = field(default_factory=lambda: random.Random(0))


@dataclass(frozen=True, slots=True)
class Transaction:
    """One exchange: what the host sent, what came back, and the bus time it took."""

    request: bytes
    reply: bytes
    cost_s: float
    packets: tuple[Packet, ...]
    """The instruction packets decoded from ``request``."""
    arrivals: tuple[tuple[int, float], ...] = ()
    """When the reply's bytes arrive: (bytes so far, seconds after the request started), one
    entry per status packet, the last at ``(len(reply), cost_s)``. The servos answer one
    after another, so a host parses the first packets while the last are still on the
    wire (:mod:`whexar.bus.emulator.pty` writes them so)."""


@dataclass
class ChainStats:
    """Counters over a chain's life."""

    requests: int = 0
    replies: int = 0
    """Status packets sent (a fast status packet counts once)."""
    bytes_in: int = 0
    bytes_out: int = 0
    bad_requests: int = 0
    """Instruction packets with a bad CRC, cut short, or with malformed parameters."""
    dropped: int = 0
    corrupted: int = 0
    """Status bytes with a flipped bit."""


Hook = Callable[["ServoChain", float, Sequence[Packet]], None]
"""Called before each request is handled, with the bus time and the decoded packets."""

_Reply = tuple[VirtualServo, bytes]

_WRITES: Final = frozenset(
    {
        Instruction.WRITE,
        Instruction.ACTION,
        Instruction.SYNC_WRITE,
        Instruction.BULK_WRITE,
        Instruction.FACTORY_RESET,
    }
)
_GROUP_READS: Final = frozenset(
    {
        Instruction.SYNC_READ,
        Instruction.FAST_SYNC_READ,
        Instruction.BULK_READ,
        Instruction.FAST_BULK_READ,
    }
)


class ServoChain:
    """Virtual servos daisy-chained on one bus; see the module docstring for the sequence."""

    def __init__(
        self,
        servos: Iterable[VirtualServo],
        timing: TimingModel = DEFAULT_TIMING,
        load_model: LoadModel | None = None,
    ) -> None:
        self._all = list(servos)
        self._ids: list[int] | None = None
        self.servos: dict[int, VirtualServo] = {}
        self._ordered: list[VirtualServo] = []
        self._rekey()
        self.timing = timing
        self._load_model: LoadModel | None = None
        self.load_model = load_model
        self.faults = FaultState()
        self.hooks: list[Hook] = []
        self.mover: Callable[[float], None] | None = None
        """A physics world that moves every servo's horn at once: ``mover(t)`` replaces
        advancing each servo's :attr:`~VirtualServo.dynamics` (it calls
        :meth:`VirtualServo.follow` on each); ``None``: each servo's own dynamics."""
        self.reply_jitter: Callable[[], float] | None = None
        """Seconds added to each reply's turnaround (the USB adapter's latency,
        :mod:`whexar.sim.spread`); ``None``: the timing model's alone."""
        self.stats = ChainStats()
        self._decoder = PacketDecoder(max_length=0xFFFF)

    @property
    def load_model(self) -> LoadModel | None:
        """Present Current of every servo; ``None``: :func:`default_load`."""
        return self._load_model

    @load_model.setter
    def load_model(self, model: LoadModel | None) -> None:
        self._load_model = model
        for servo in self._all:
            servo.load_model = model

    @classmethod
    def for_models(
        cls,
        models: Mapping[int, str],
        *,
        baudrate: int = DEFAULT_TIMING.baudrate,
        timing: TimingModel | None = None,
        fast_sync_read: bool = False,
        return_delay_us: int | None = None,
        load_model: LoadModel | None = None,
    ) -> ServoChain:
        """Servos of the given IDs and model names (``"MX-64"``), in that order.

        WHexaR's are ``ServoChain.for_models(cfg.servos(), baudrate=cfg.bus.baudrate)``
        (:meth:`whexar.config.RobotConfig.servos`). ``timing`` defaults to the
        thesis's model at ``baudrate``. Return Delay Time stays at the factory
        250 (500 µs) unless ``return_delay_us`` presets it: the bus scheduler
        sets it at start-up.
        """
        servos: list[VirtualServo] = []
        for sid, name in models.items():
            if name not in MODELS:
                raise UsageError(f"servo {sid}: model {name!r}; allowed: {', '.join(MODELS)}")
            servo = VirtualServo(sid, MODELS[name], fast_sync_read=fast_sync_read)
            if return_delay_us is not None:
                servo.set_register("return_delay_time", return_delay_units(return_delay_us * 1e-6))
            servos.append(servo)
        return cls(servos, timing or TimingModel(baudrate=baudrate), load_model)

    def _rekey(self) -> None:
        ids = [s.table[7] for s in self._all]  # ID (7): a write may have changed one
        if ids == self._ids:
            return
        self._ids = ids
        # On a duplicated ID the later servo wins, as a scan would find only one.
        self.servos = {s.id: s for s in self._all}
        self._ordered = sorted(self.servos.values(), key=lambda s: s.id)
        self._ids_ordered = [s.id for s in self._ordered]

    def advance(self, t: float) -> None:
        """Bring every servo's dynamics up to bus time ``t`` (through :attr:`mover` if set)."""
        if self.mover is not None:
            self.mover(t)
            return
        for servo in self._all:
            servo.advance(t)

    def power_up(self, t: float) -> None:
        """Every servo powers up at bus time ``t``: initial RAM, and silent while it boots."""
        for servo in self._all:
            servo.power_cycle(t)

    def _hears(self, servo: VirtualServo, t: float, sid: int | None = None) -> bool:
        """Whether ``servo`` (ID ``sid``, if the caller knows it) hears a packet at ``t``;
        if so, the packet feeds its watchdog."""
        silent = self.faults.silent_until
        if silent and t < silent.get(servo.id if sid is None else sid, -math.inf):
            return False
        if servo.booting(t):
            return False
        servo.heard(t)
        return True

    def transact(self, request: bytes, t: float) -> Transaction:
        """Handle ``request`` sent at bus time ``t``; the reply and its cost (see module doc)."""
        request = bytes(request)
        stats = self.stats
        stats.requests += 1
        stats.bytes_in += len(request)
        decoder = self._decoder
        crc_errors = decoder.crc_errors
        packets = tuple(p for p in decoder.feed(request) if not p.is_status)
        stats.bad_requests += decoder.crc_errors - crc_errors
        if decoder.pending:  # a packet cut short: the servos' inter-byte timeout drops it
            stats.bad_requests += 1
            decoder.reset()
        self.advance(t)
        for hook in list(self.hooks):
            hook(self, t, packets)
        reply = bytearray()
        cost = self.timing.write_s(len(request))
        arrivals: list[tuple[int, float]] = []
        if not self.faults.unplugged:
            for packet in packets:
                replies, fast = self._execute(packet, t)
                if packet.instruction in _WRITES:
                    self._rekey()
                if replies:
                    cost += self._deliver(replies, fast, reply, arrivals, cost)
        if reply and self.faults.corrupt_rate > 0.0:
            self._corrupt(reply)
        stats.bytes_out += len(reply)
        return Transaction(request, bytes(reply), cost, packets, tuple(arrivals))

    def _deliver(
        self,
        replies: list[_Reply],
        fast: bool,
        out: bytearray,
        arrivals: list[tuple[int, float]],
        before: float,
    ) -> float:
        """Append the status packets that are not dropped to ``out``; their bus time.

        ``arrivals`` gets when each packet is complete, ``before`` seconds into the
        exchange plus the turnaround, then each packet's Return Delay Time, wire
        time and host cost in turn.
        """
        drop = self.faults.drop_rate
        rng = self.faults.rng
        timing = self.timing
        packets = 0
        nbytes = 0
        delay = 0.0
        jitter = self.reply_jitter() if self.reply_jitter is not None else 0.0
        at = before + timing.turnaround_s + jitter
        marks: list[tuple[int, float]] = []
        for servo, data in replies:
            if drop > 0.0 and rng.random() < drop:
                self.stats.dropped += 1
                continue
            if not fast or not packets:
                delay += servo.return_delay_s
                at += servo.return_delay_s
                packets += 1
            nbytes += len(data)
            at += timing.wire_s(len(data)) + timing.per_status_byte_s * len(data)
            out += data
            marks.append((len(out), at))
        if not packets:
            return 0.0
        self.stats.replies += packets
        cost = timing.read_s(0, packets, nbytes, delay / packets) + jitter
        # A fast status packet is one packet: it arrives whole. The last mark is the cost.
        marks = marks[:-1] if not fast else []
        arrivals.extend(marks)
        arrivals.append((len(out), before + cost))
        return cost

    def _corrupt(self, reply: bytearray) -> None:
        rate = self.faults.corrupt_rate
        rng = self.faults.rng
        n = len(reply)
        i = -1
        log_miss = math.log1p(-rate) if rate < 1.0 else -math.inf
        while True:
            # Geometric skip to the next corrupted byte: one RNG draw per flip.
            i += 1 if log_miss == -math.inf else 1 + int(math.log1p(-rng.random()) / log_miss)
            if i >= n:
                return
            reply[i] ^= 1 << rng.randrange(8)
            self.stats.corrupted += 1

    # ----------------------------------------------------------------- instructions

    def _hearing(self, t: float) -> dict[int, VirtualServo]:
        """The servos that hear a broadcast packet at ``t`` by ID, in ID order (:meth:`_hears`;
        the IDs cached, as every group read and write asks it of every servo)."""
        return {
            sid: servo
            for sid, servo in zip(self._ids_ordered, self._ordered, strict=True)
            if self._hears(servo, t, sid)
        }

    def _execute(self, p: Packet, t: float) -> tuple[list[_Reply], bool]:
        inst = p.instruction
        broadcast = p.id == BROADCAST_ID
        if broadcast:
            hearing = self._hearing(t)
            if inst in _GROUP_READS:
                return self._group_read(p, hearing)
            if inst == Instruction.SYNC_WRITE:
                self._sync_write(p, hearing)
                return [], False
            if inst == Instruction.BULK_WRITE:
                self._bulk_write(p, hearing)
                return [], False
            targets = list(hearing.values())
        else:
            one = self.servos.get(p.id)
            targets = [one] if one is not None and self._hears(one, t) else []
        out: list[_Reply] = []

        def answer(servo: VirtualServo, error: int, params: bytes = b"", level: int = 2) -> None:
            # Broadcast answers only Ping; Status Return Level gates the rest (e-manual).
            # A unicast reply carries the ID addressed, so a write to ID answers as before.
            if (not broadcast or inst == Instruction.PING) and servo.status_return_level >= level:
                reply_id = servo.id if broadcast else p.id
                out.append((servo, encode_status(reply_id, servo.status_error | error, params)))

        for servo in targets:
            if inst == Instruction.PING:  # Model Number and Firmware Version (e-manual)
                answer(servo, 0, bytes(servo.table[0:2]) + bytes((servo.table[6],)), 0)
            elif inst == Instruction.READ:
                if broadcast:
                    continue  # Read is not executed for the broadcast ID (e-manual)
                try:
                    start, length = parse_read_params(p.params)
                except PacketError:
                    answer(servo, StatusError.DATA_LENGTH, level=1)
                    continue
                if start + length > TABLE_SIZE:
                    answer(servo, StatusError.ACCESS, level=1)
                else:
                    answer(servo, 0, servo.read(start, length), 1)
            elif inst in (Instruction.WRITE, Instruction.REG_WRITE):
                try:
                    start, data = parse_write_params(p.params)
                except PacketError:
                    self.stats.bad_requests += 1
                    answer(servo, StatusError.DATA_LENGTH)
                    continue
                if inst == Instruction.WRITE:
                    answer(servo, servo.write(start, data))
                else:
                    servo.registered = (start, data)
                    servo.table[69] = 1
                    answer(servo, 0)
            elif inst == Instruction.ACTION:
                if servo.registered is None:
                    answer(servo, StatusError.INSTRUCTION)
                    continue
                start, data = servo.registered
                servo.registered = None
                servo.table[69] = 0
                answer(servo, servo.write(start, data))
            elif inst == Instruction.REBOOT:
                answer(servo, 0)  # the status goes out before the reboot
                servo.reboot()
            elif inst == Instruction.FACTORY_RESET:
                option = p.params[0] if len(p.params) == 1 else -1
                if option not in (0x01, 0x02, 0xFF):
                    answer(servo, StatusError.DATA_RANGE)
                elif not (broadcast and option == 0xFF):  # refused to the broadcast ID
                    answer(servo, 0)
                    servo.factory_reset(option)
            elif inst == Instruction.CLEAR:
                if p.params == b"\x01\x44\x58\x4c\x22":
                    answer(servo, servo.clear_multi_turn())
                else:
                    answer(servo, StatusError.DATA_RANGE)
            else:  # unknown, or a group instruction sent to one ID
                answer(servo, StatusError.INSTRUCTION)
        return out, False

    def _sync_write(self, p: Packet, hearing: dict[int, VirtualServo]) -> None:
        try:
            start, _, entries = parse_sync_write_params(p.params)
        except PacketError:
            self.stats.bad_requests += 1
            return
        for servo_id, data in entries:
            servo = hearing.get(servo_id)
            if servo is not None:
                servo.write(start, data)

    def _bulk_write(self, p: Packet, hearing: dict[int, VirtualServo]) -> None:
        try:
            entries = parse_bulk_write_params(p.params)
        except PacketError:
            self.stats.bad_requests += 1
            return
        for servo_id, start, data in entries:
            servo = hearing.get(servo_id)
            if servo is not None:
                servo.write(start, data)

    def _group_read(self, p: Packet, hearing: dict[int, VirtualServo]) -> tuple[list[_Reply], bool]:
        """(Fast) Sync/Bulk Read: replies in the order the instruction lists the IDs (e-manual).

        ``hearing``: the servos that heard the packet (:meth:`_hearing`)."""
        fast = p.instruction in (Instruction.FAST_SYNC_READ, Instruction.FAST_BULK_READ)
        try:
            if p.instruction in (Instruction.SYNC_READ, Instruction.FAST_SYNC_READ):
                start, length, ids = parse_sync_read_params(p.params)
                wanted = [(i, start, length) for i in ids]
            else:
                wanted = parse_bulk_read_params(p.params)
        except PacketError:
            self.stats.bad_requests += 1
            return [], fast
        entries: list[tuple[int, int, bytes]] = []
        answering: list[VirtualServo | None] = []
        for servo_id, start, length in wanted:
            servo = hearing.get(servo_id)
            ok = (
                servo is not None
                and servo.status_return_level >= 1
                # A servo whose firmware lacks Fast Sync/Bulk Read does not know the
                # instruction, and stays silent as for any broadcast it cannot execute.
                and (servo.fast_sync_read or not fast)
            )
            if servo is None or not ok:
                answering.append(None)
                entries.append((0, servo_id if servo_id <= 252 else 0, bytes(length)))
                continue
            if start + length > TABLE_SIZE:
                entries.append((servo.status_error | StatusError.ACCESS, servo_id, bytes(length)))
            else:
                entries.append((servo.status_error, servo_id, servo.read(start, length)))
            answering.append(servo)
        if not fast:
            out: list[_Reply] = []
            for servo, (error, servo_id, data) in zip(answering, entries, strict=True):
                if servo is not None:
                    params = data if not error & 0x7F else b""  # Access Error: no parameters
                    out.append((servo, encode_status(servo_id, error, params)))
            return out, False
        # Every servo computes LEN and the running CRCs for the whole packet; a
        # silent one leaves its part out, so the host sees a broken packet.
        parts = fast_status_parts(entries)
        return [(s, part) for s, part in zip(answering, parts, strict=True) if s is not None], True


SERVO_CHAIN: Final = DeviceKind[ServoChain]("emulated servo chain", "emulator")
"""Servo chains in :data:`~whexar.runtime.devices.DEVICES`: ``port = "emulator:NAME"`` of
:class:`~whexar.actors.bus.BusScheduler` opens the one registered as NAME."""
