"""Virtual Dynamixel MX (2.0) servos on one bus, answering Protocol 2.0 byte for byte, with timing.

Theory of operation
-------------------
:class:`ServoChain` plays the far end of the bus. :meth:`ServoChain.transact`
takes the bytes a host sends and the bus time ``t`` they are sent at, and
returns the bytes the servos send back and how long the exchange keeps the
bus busy. In order:

1. decode every complete instruction packet (a bad CRC is ignored, as a
   servo ignores it, and counted);
2. bring every servo's dynamics up to ``t`` (:meth:`VirtualServo.advance` is
   lazy and exact: nothing moves between transactions, nothing is sampled);
3. run the hooks (fault plans, a physics world) with ``t`` and the packets;
4. execute each instruction as the e-manual describes (access rules, limits,
   Status Return Level, broadcast rules) and build the status packets each
   servo sends, in the order the instruction lists the IDs;
5. apply :class:`FaultState`: silent servos neither hear nor answer, status
   packets are dropped, bits are flipped;
6. price the exchange with :class:`TimingModel`.

:class:`EmulatedPort` wraps a chain in the duck-typed port ``dynamixel_sdk``
drives, so the SDK runs unmodified in-process, on bus time: the port adds up
each transaction's cost, and when the SDK waits for bytes that will never
come, charges the SDK's own timeout instead of sleeping.

Nothing here reads a clock: time is always an argument (``t``, ``now``).
"""

from __future__ import annotations

import errno
import math
import random
import struct
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, ClassVar, Final

from whexar.bus.control_table import (
    ACCELERATION_UNIT_RPM2,
    CENTER_TICKS,
    LOAD_UNIT,
    MODELS,
    RETURN_DELAY_UNIT_S,
    TABLE_SIZE,
    TICKS_PER_REV,
    VELOCITY_UNIT_RPM,
    VOLTAGE_UNIT_V,
    HardwareError,
    Register,
    ServoModel,
    return_delay_units,
)
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
    sync_read_bytes,
    sync_write_bytes,
)
from whexar.errors import UsageError
from whexar.robot import JOINT_NAMES
from whexar.runtime.devices import DeviceKind

if TYPE_CHECKING:
    from whexar.config import RobotConfig

# --------------------------------------------------------------------------- timing


@dataclass(frozen=True, slots=True)
class TimingModel:
    """How long transactions keep the bus busy (wire time plus measured host costs).

    Wire time is ``bits_per_byte / baudrate`` per byte (8N1: 10 bits). A read
    also pays each status packet's Return Delay Time, one host/USB turnaround
    and a host cost per status byte received. The two host constants are a
    least-squares fit (in seconds per transaction) to the thesis's sync reads of
    42 servos at 1 Mbps with Return Delay Time 20 µs (Tables 6.1, 6.2)::

        X  status bytes 42·(11+X)  1/rate    wire(56+status)+42·20 µs   residual
        1  504                     8.4617 ms  6.4400 ms                  2.0217 ms
        2  546                     8.9928 ms  6.8600 ms                  2.1328 ms
        4  630                     9.9800 ms  7.7000 ms                  2.2800 ms

        residual = turnaround + per_status_byte · status bytes
        → turnaround = 1.0203 ms, per_status_byte = 2.008 µs

    giving 118.03 / 111.40 / 100.15 Hz against 118.18 / 111.2 / 100.2 Hz
    (−0.13 %, +0.18 %, −0.05 %) and two reads (position, then current)
    52.74 Hz against 52.8 Hz. Writes are pure wire time: sync write of Goal
    Position (224 bytes) 446.4 Hz against 446.6 Hz, of Goal Current (140
    bytes) 714.3 Hz against 714.6 Hz. The host constants were measured at
    1 Mbps and are assumed not to scale with the baud rate.
    """

    baudrate: int = 1_000_000
    bits_per_byte: int = 10
    turnaround_s: float = 1.0203e-3
    per_status_byte_s: float = 2.008e-6

    def __post_init__(self) -> None:
        if self.baudrate <= 0 or self.bits_per_byte <= 0:
            raise UsageError(f"{self!r}: baudrate and bits_per_byte must be > 0")

    def wire_s(self, nbytes: int) -> float:
        """Time on the wire of ``nbytes`` bytes."""
        return nbytes * self.bits_per_byte / self.baudrate

    def read_s(
        self, request_bytes: int, status_packets: int, status_bytes: int, return_delay_s: float
    ) -> float:
        """A read transaction: wire(request + status) + return delay per status packet
        + turnaround + per-status-byte host cost. ``return_delay_s`` is per packet."""
        return (
            self.wire_s(request_bytes + status_bytes)
            + status_packets * return_delay_s
            + self.turnaround_s
            + self.per_status_byte_s * status_bytes
        )

    def write_s(self, request_bytes: int) -> float:
        """A transaction without reply: pure wire time."""
        return self.wire_s(request_bytes)

    def sync_read_s(
        self, n: int, data_bytes: int, return_delay_s: float, fast: bool = False
    ) -> float:
        """Analytic (Fast) Sync Read of ``data_bytes`` from each of ``n`` servos.

        Fast: one status packet of 8 + n·(X + 4) bytes and *one* Return Delay
        Time — the first servo waits it, every later one appends its part as
        soon as the previous part ends (that is the instruction's point: "one
        Status Packet ... as if one DYNAMIXEL has returned a single Status
        Packet", e-manual). The per-byte host cost is kept per byte received.
        """
        request, response = sync_read_bytes(n, data_bytes, fast=fast)
        return self.read_s(request, 1 if fast else n, response, return_delay_s)

    def sync_write_s(self, n: int, data_bytes: int) -> float:
        """Analytic Sync Write of ``data_bytes`` to each of ``n`` servos: 14 + n·(1 + X) bytes."""
        return self.write_s(sync_write_bytes(n, data_bytes))


DEFAULT_TIMING: Final = TimingModel()
"""The thesis's bus: 1 Mbps, host constants fitted to Tables 6.1 and 6.2."""

# --------------------------------------------------------------------------- servo

LoadModel = Callable[["VirtualServo", float], float]
"""``(servo, t) -> present current in A`` (MX-28: Present Load as a fraction of full torque)."""

_VEL_TICKS: Final = VELOCITY_UNIT_RPM / 60.0 * TICKS_PER_REV
"""Ticks/s per velocity unit (0.229 rev/min, e-manual)."""
_ACC_TICKS: Final = ACCELERATION_UNIT_RPM2 / 3600.0 * TICKS_PER_REV
"""Ticks/s² per Profile Acceleration unit (214.577 rev/min², e-manual)."""
_RAD_PER_TICK: Final = 2.0 * math.pi / TICKS_PER_REV

STANDBY_CURRENT_A: Final = 0.1
"""Holding term of the default load model: "Standby Current 100 mA" (e-manual, MX-64(2.0))."""
ACCEL_CURRENT_A_PER_RAD_S2: Final = 0.004
"""Default load model's current per rad/s² of profile acceleration: 0.4 A at 100 rad/s².
Illustrative (a leg segment's inertia through a 200:1 gear), not measured."""
MX28_STALL_CURRENT_A: Final = 1.4
"""MX-28 current at stall torque, 12 V (Table 5.1; ``servo_models."MX-28"``): full load."""


def default_load(servo: VirtualServo, t: float) -> float:
    """Standby current plus a term proportional to |acceleration|; 0 with torque off.

    The sign follows the acceleration. For the MX-28 the current is
    expressed as a fraction of its stall current (Present Load).
    """
    if not servo.torque_enabled:
        return 0.0
    amps = STANDBY_CURRENT_A + ACCEL_CURRENT_A_PER_RAD_S2 * abs(servo.acceleration) * _RAD_PER_TICK
    amps = -amps if servo.acceleration < 0 else amps
    return amps if servo.model.current_unit_a is not None else amps / MX28_STALL_CURRENT_A


def _trapezoid(
    x: float, v: float, goal: float, vmax: float, amax: float, dt: float
) -> tuple[float, float, float]:
    """Move ``(x, v)`` toward ``goal`` for ``dt`` with |v| ≤ vmax, |a| ≤ amax (∞: steps).

    Exact piecewise-constant-acceleration phases (brake if moving away or if
    the stopping distance has reached the goal, else accelerate, cruise, brake),
    so the result does not depend on how time is sliced. Returns (x, v, a).
    """
    a_last = 0.0
    if vmax <= 0.0:
        return x, 0.0, 0.0
    for _ in range(16):
        if dt <= 0.0:
            break
        d = goal - x
        if d == 0.0 and v == 0.0:
            return goal, 0.0, 0.0
        s = 1.0 if d > 0.0 or (d == 0.0 and v < 0.0) else -1.0
        dist = d * s
        u = v * s
        if math.isinf(amax):
            if dist <= vmax * dt:
                return goal, 0.0, 0.0
            return x + s * vmax * dt, s * vmax, 0.0
        eps = 1e-9 * max(1.0, dist)
        stop = u * u / (2.0 * amax)
        if u < 0.0:  # moving away: brake to zero
            acc, span = amax, -u / amax
        elif stop >= dist - eps:  # brake now (lands on the goal, or overshoots and returns)
            acc, span = -amax, u / amax
        elif u > vmax * (1.0 + 1e-12):  # faster than the profile allows: slow down
            acc, span = -amax, (u - vmax) / amax
        elif u < vmax * (1.0 - 1e-12):  # accelerate to vmax or to the braking point
            u_switch = math.sqrt(u * u + amax * (dist - stop))
            acc, span = amax, (min(u_switch, vmax) - u) / amax
        else:  # cruise to the braking point
            acc, span = 0.0, (dist - stop) / u
        h = min(span, dt)
        x += s * (u * h + 0.5 * acc * h * h)
        v = s * (u + acc * h)
        a_last = s * acc
        dt -= h
        if abs(goal - x) < 1e-6 and abs(v) < 1e-6:
            return goal, 0.0, 0.0
    return x, v, a_last


@dataclass(frozen=True, slots=True)
class _Layout:
    """Which register owns each address of one model's table, and checked write spans."""

    owner: tuple[Register | None, ...]
    ranges: dict[str, tuple[int, int]]
    spans: dict[tuple[int, int], tuple[int, tuple[Register, ...]]]


_INDIRECT: Final = ((168, 224, 0), (578, 634, 28))
"""(first Indirect Address, first Indirect Data, index offset): 28 each (e-manual MX (2.0))."""
_INDIRECT_TARGETS: Final = (64, TABLE_SIZE - 1)
"""Where an Indirect Address may point: the RAM area (e-manual: Indirect Address range)."""

_STATIC_RANGES: Final = {
    # Value ranges of the e-manual's MX (2.0) control tables; a write outside
    # them is a Data Range Error. Limits that depend on other registers
    # (goal vs position/velocity/current/PWM limits) are checked dynamically.
    "id": (0, 252),
    "baud_rate": (0, 7),
    "return_delay_time": (0, 254),
    "operating_mode": (0, 16),
    "protocol_type": (1, 2),
    "moving_threshold": (0, 1023),
    "temperature_limit": (0, 100),
    "max_voltage_limit": (95, 160),
    "min_voltage_limit": (95, 160),
    "pwm_limit": (0, 885),
    "acceleration_limit": (0, 32767),
    "velocity_limit": (0, 1023),
    "max_position_limit": (0, 4095),
    "min_position_limit": (0, 4095),
    "torque_enable": (0, 1),
    "led": (0, 1),
    "status_return_level": (0, 2),
    "profile_acceleration": (0, 32767),
    "profile_velocity": (0, 32767),
}
_OPERATING_MODES: Final = frozenset({0, 1, 3, 4, 5, 16})
"""Current, velocity, position, extended position, current-based position, PWM (e-manual)."""
_GOAL_LIMITS: Final = {
    "goal_velocity": "_vel_limit",
    "goal_current": "_current_limit",
    "goal_pwm": "_pwm_limit",
}
"""Goals bounded by a limit register (|goal| ≤ limit, e-manual): the cached limit's name."""
_EXTENDED_GOAL: Final = 1_048_575
"""Goal Position range in extended/current-based position modes: ±256 rev (e-manual)."""

_LAYOUTS: dict[str, tuple[ServoModel, _Layout]] = {}


def _layout(model: ServoModel) -> _Layout:
    known = _LAYOUTS.get(model.name)
    if known is not None and known[0] is model:
        return known[1]
    regs = list(model.registers.values())
    for first_address, first_data, offset in _INDIRECT:
        for k in range(28):
            regs.append(
                Register(
                    f"indirect_address_{offset + k + 1}", first_address + 2 * k, 2, "RW", "ram"
                )
            )
            regs.append(Register(f"indirect_data_{offset + k + 1}", first_data + k, 1, "RW", "ram"))
    owner: list[Register | None] = [None] * TABLE_SIZE
    for reg in regs:
        for a in range(reg.address, reg.end):
            owner[a] = reg
    ranges = dict(_STATIC_RANGES)
    if "current_limit" in model.registers:
        limit = model.registers["current_limit"].initial or 0
        ranges["current_limit"] = (0, limit)
    for reg in regs:
        if reg.name.startswith("indirect_address"):
            ranges[reg.name] = _INDIRECT_TARGETS
    layout = _Layout(tuple(owner), ranges, {})
    _LAYOUTS.setdefault(model.name, (model, layout))
    return layout


def _span(layout: _Layout, address: int, length: int) -> tuple[int, tuple[Register, ...]]:
    """Static check of a write to ``[address, address+length)``: (error, registers covered).

    Access Error for a read-only byte or a span with no writable register;
    Data Length Error for a register written only in part (e-manual, "Error").
    Bytes in undefined gaps between registers are ignored.
    """
    key = (address, length)
    known = layout.spans.get(key)
    if known is not None:
        return known
    end = address + length
    result: tuple[int, tuple[Register, ...]]
    if address < 0 or length <= 0 or end > TABLE_SIZE:
        result = (StatusError.ACCESS, ())
    else:
        covered: dict[str, Register] = {}
        error = 0
        for a in range(address, end):
            reg = layout.owner[a]
            if reg is None:
                continue
            if reg.access == "R":
                error = StatusError.ACCESS
                break
            covered[reg.name] = reg
        if not error and not covered:
            error = StatusError.ACCESS
        if not error and any(r.address < address or r.end > end for r in covered.values()):
            error = StatusError.DATA_LENGTH
        result = (error, tuple(covered.values()))
    if len(layout.spans) < 4096:
        layout.spans[key] = result
    return result


_PRESENT: Final = struct.Struct("<HBBhhiiiiHB")
"""Registers 120–146 in one block: tick, moving, moving status, PWM, current, velocity,
position, velocity/position trajectory, input voltage, temperature."""
_PRESENT_START: Final = 120
_PRESENT_END: Final = 147


class VirtualServo:
    """One MX (2.0) servo: its control table, the e-manual's write rules, and its motion.

    Motion (torque on): in the position modes Present Position follows a
    trapezoidal profile to Goal Position, limited by Profile Velocity (0 →
    Velocity Limit) and Profile Acceleration (0 → a step in velocity); in
    velocity mode Present Velocity ramps to Goal Velocity. Current and PWM
    modes hold still (no torque model). Present Current comes from the load
    model. Not modelled: Homing Offset, Drive Mode's reverse bit, Secondary ID,
    Present PWM (reads 0), the baud-rate register, boot time after a reboot.
    """

    FIRMWARE_VERSION: ClassVar[int] = 42
    """MX (2.0) firmware v42+: knows Clear and refuses broadcast Factory Reset 0xFF (e-manual)."""

    def __init__(
        self,
        servo_id: int,
        model: ServoModel,
        *,
        position: int = CENTER_TICKS,
        fast_sync_read: bool | None = None,
        input_voltage_v: float = 12.0,
        temperature_c: float = 35.0,
    ) -> None:
        if not 0 <= servo_id <= 252:
            raise UsageError(f"servo_id = {servo_id!r}: a Dynamixel ID in 0–252")
        self.model = model
        self._layout = _layout(model)
        self.fast_sync_read: bool = (
            model.fast_sync_read if fast_sync_read is None else fast_sync_read
        )
        self.input_voltage_v = input_voltage_v
        self.temperature_c = temperature_c
        self.load_model: LoadModel | None = None
        self.rejected_goals = 0
        """Goal Position writes refused for lying outside the position limits."""
        self.registered: tuple[int, bytes] | None = None
        """The write a REG_WRITE left pending for ACTION."""
        self.table = self._initial_table(servo_id)
        self._t = 0.0
        self._x = float(position)
        self._v = 0.0
        self._a = 0.0
        self._goal = position
        self._in_profile = False
        self._dirty = True
        self._torque = False
        self.table[116:120] = position.to_bytes(4, "little", signed=True)
        self._sync_params()

    def _initial_table(self, servo_id: int) -> bytearray:
        table = self.model.initial_table()
        table[6] = self.FIRMWARE_VERSION
        table[7] = servo_id
        for first_address, first_data, _ in _INDIRECT:
            for k in range(28):  # Indirect Address k points at Indirect Data k (e-manual)
                table[first_address + 2 * k : first_address + 2 * k + 2] = (
                    first_data + k
                ).to_bytes(2, "little")
        return table

    # ----------------------------------------------------------------- state

    @property
    def id(self) -> int:
        """The servo's ID (register 7)."""
        return self.table[7]

    @property
    def torque_enabled(self) -> bool:
        """Torque Enable (64)."""
        return self._torque

    @property
    def hardware_error(self) -> HardwareError:
        """Hardware Error Status (70)."""
        return HardwareError(self.table[70])

    @property
    def status_error(self) -> int:
        """The ERR byte's Alert bit: set while Hardware Error Status is non-zero."""
        return 0x80 if self.table[70] else 0

    @property
    def return_delay_s(self) -> float:
        """Return Delay Time (9) in seconds."""
        return self._rdt_s

    @property
    def status_return_level(self) -> int:
        """Status Return Level (68): 0 Ping only, 1 and reads, 2 everything."""
        return self._srl

    @property
    def position(self) -> float:
        """Present position in ticks (unrounded)."""
        return self._x

    @property
    def velocity(self) -> float:
        """Present velocity in ticks/s."""
        return self._v

    @property
    def acceleration(self) -> float:
        """Acceleration of the current profile phase in ticks/s² (0 when steady)."""
        return self._a

    @property
    def goal(self) -> int:
        """Goal Position (116) in ticks."""
        return self._goal

    @property
    def time(self) -> float:
        """Bus time the dynamics have been advanced to."""
        return self._t

    def set_state(self, position: float, velocity: float = 0.0) -> None:
        """Put the horn at ``position`` ticks moving at ``velocity`` ticks/s (a hook's override)."""
        self._x = float(position)
        self._v = float(velocity)
        self._a = 0.0
        self._in_profile = self._torque and self._mode in (3, 4, 5) and self._x != self._goal
        self._dirty = True

    def register_value(self, name: str) -> int:
        """Current value of register ``name`` (present values refreshed first)."""
        reg = self.model.register(name)
        self._refresh()
        return reg.decode(self.table)

    def set_register(self, name: str, value: int) -> None:
        """Set register ``name`` as the firmware would, bypassing the bus's access rules."""
        reg = self.model.register(name)
        self.table[reg.address : reg.end] = reg.encode(value)
        self._after_write(reg.address, reg.end)

    def _sync_params(self) -> None:
        t = self.table
        self._rdt_s = t[9] * RETURN_DELAY_UNIT_S
        self._mode = t[11]
        self._moving_threshold = int.from_bytes(t[24:28], "little")
        self._temp_limit = t[31]
        max_v, min_v = struct.unpack_from("<HH", t, 32)
        self._max_v, self._min_v = max_v * VOLTAGE_UNIT_V, min_v * VOLTAGE_UNIT_V
        self._pwm_limit, self._current_limit = struct.unpack_from("<HH", t, 36)
        (self._vel_limit,) = struct.unpack_from("<I", t, 44)
        self._max_pos, self._min_pos = struct.unpack_from("<ii", t, 48)
        self._shutdown = t[63]
        self._torque = bool(t[64])
        self._srl = t[68]
        (self._goal_velocity,) = struct.unpack_from("<i", t, 104)
        self._prof_acc, self._prof_vel = struct.unpack_from("<II", t, 108)

    # ----------------------------------------------------------------- dynamics

    def advance(self, t: float) -> None:
        """Integrate the dynamics up to bus time ``t`` (earlier times are ignored)."""
        volts = self.input_voltage_v
        if (volts < self._min_v - 1e-9 or volts > self._max_v + 1e-9) and not self.table[70] & 1:
            self.raise_error(HardwareError.INPUT_VOLTAGE)
        if self.temperature_c > self._temp_limit and not self.table[70] & 4:
            self.raise_error(HardwareError.OVERHEATING)
        dt = t - self._t
        if dt <= 0.0:
            return
        self._t = t
        self._dirty = True
        if not self._torque:
            self._v = self._a = 0.0
            return
        mode = self._mode
        if mode in (3, 4, 5):
            if not self._in_profile:
                return
            vmax = min(self._prof_vel or self._vel_limit, self._vel_limit) * _VEL_TICKS
            amax = self._prof_acc * _ACC_TICKS if self._prof_acc else math.inf
            self._x, self._v, self._a = _trapezoid(self._x, self._v, self._goal, vmax, amax, dt)
            if self._x == self._goal and self._v == 0.0:
                self._in_profile = False
        elif mode == 1:
            target = max(-self._vel_limit, min(self._vel_limit, self._goal_velocity)) * _VEL_TICKS
            amax = self._prof_acc * _ACC_TICKS if self._prof_acc else math.inf
            gap = target - self._v
            h = dt if gap == 0.0 else min(dt, abs(gap) / amax)
            acc = 0.0 if gap == 0.0 or math.isinf(amax) else math.copysign(amax, gap)
            self._x += self._v * h + 0.5 * acc * h * h
            self._v += acc * h
            if h < dt:
                self._v = target
                self._x += target * (dt - h)
                acc = 0.0
            self._a = acc
        else:  # current and PWM modes: no torque model, so no motion
            self._v = self._a = 0.0

    def _refresh(self) -> None:
        if not self._dirty:
            return
        self._dirty = False
        amps = (self.load_model or default_load)(self, self._t)
        unit = self.model.current_unit_a
        current = round(amps / unit) if unit is not None else round(amps / LOAD_UNIT)
        limit = 1000 if unit is None else 32767
        current = max(-limit, min(limit, current))
        velocity = max(-(2**31), min(2**31 - 1, round(self._v / _VEL_TICKS)))
        position = max(-(2**31), min(2**31 - 1, round(self._x)))
        moving = self._in_profile or abs(velocity) > self._moving_threshold
        status = 0
        if self._mode in (3, 4, 5):
            status |= 1 if position == self._goal else 0  # in position
            status |= 2 if self._in_profile else 0  # profile ongoing
            if self._prof_vel:
                status |= 0x30 if self._prof_acc else 0x10  # trapezoidal / rectangular
        _PRESENT.pack_into(
            self.table,
            _PRESENT_START,
            int(self._t * 1000.0) % 32768,  # Realtime Tick: ms, wraps at 32767 (e-manual)
            1 if moving else 0,
            status,
            0,
            current,
            velocity,
            position,
            velocity,
            position,
            max(0, min(0xFFFF, round(self.input_voltage_v / VOLTAGE_UNIT_V))),
            max(0, min(0xFF, round(self.temperature_c))),
        )

    # ----------------------------------------------------------------- bus access

    def read(self, address: int, length: int) -> bytes:
        """``length`` bytes of the control table from ``address`` (Indirect Data resolved).

        :class:`UsageError` for a span outside the table; the chain answers that
        with an Access Error before calling this.
        """
        end = address + length
        if address < 0 or length < 0 or end > TABLE_SIZE:
            raise UsageError(f"read of {length} bytes at {address}: outside the control table")
        indirect = (end > 224 and address < 252) or end > 634
        if indirect or (end > _PRESENT_START and address < _PRESENT_END):
            self._refresh()
        if not indirect:
            return bytes(self.table[address:end])
        out = bytearray(self.table[address:end])
        for i in range(length):
            target = self._indirect_target(address + i)
            if target is not None:
                out[i] = self.table[target]
        return bytes(out)

    def _indirect_target(self, address: int) -> int | None:
        for first_address, first_data, _ in _INDIRECT:
            k = address - first_data
            if 0 <= k < 28:
                at = first_address + 2 * k
                return self.table[at] | (self.table[at + 1] << 8)
        return None

    def _runs(self, address: int, data: bytes) -> list[tuple[int, bytes]]:
        """The write as contiguous runs at their real addresses (Indirect Data resolved)."""
        end = address + len(data)
        if not ((end > 224 and address < 252) or end > 634):
            return [(address, data)]
        runs: list[tuple[int, bytearray]] = []
        for i, byte in enumerate(data):
            target = self._indirect_target(address + i)
            real = address + i if target is None else target
            if runs and runs[-1][0] + len(runs[-1][1]) == real:
                runs[-1][1].append(byte)
            else:
                runs.append((real, bytearray((byte,))))
        return [(a, bytes(b)) for a, b in runs]

    def write(self, address: int, data: bytes) -> int:
        """Write ``data`` at ``address`` under the e-manual's rules; 0 or a :class:`StatusError`.

        Access Error: a read-only or undefined span, beyond the table, or EEPROM
        (below 64) while torque is on. Data Length Error: a register written in
        part. Data Range Error: a value outside the register's range. Data Limit
        Error: Goal Position outside the position limits in position mode (also
        counted in :attr:`rejected_goals`), or a goal beyond its velocity,
        current or PWM limit. Result Fail: Torque Enable 1 while a shutdown
        error is latched (only a reboot clears it). A refused write changes
        nothing.
        """
        runs = self._runs(address, bytes(data))
        for start, chunk in runs:
            error = self._check(start, chunk)
            if error:
                return error
        for start, chunk in runs:
            end = start + len(chunk)
            self.table[start:end] = chunk
            self._after_write(start, end)
        return 0

    def _check(self, address: int, data: bytes) -> int:
        error, regs = _span(self._layout, address, len(data))
        if error:
            return error
        if self._torque and address < 64:
            return StatusError.ACCESS  # EEPROM is locked while torque is on (e-manual)
        ranges = self._layout.ranges
        for reg in regs:
            value = reg.decode(data, address)
            bounds = ranges.get(reg.name)
            if bounds is not None and not bounds[0] <= value <= bounds[1]:
                return StatusError.DATA_RANGE
            name = reg.name
            if name == "operating_mode" and value not in _OPERATING_MODES:
                return StatusError.DATA_RANGE
            if name == "goal_position":
                error = self._check_goal(value)
                if error:
                    self.rejected_goals += 1
                    return error
            elif name in _GOAL_LIMITS and abs(value) > getattr(self, _GOAL_LIMITS[name]):
                return StatusError.DATA_LIMIT
            elif name == "torque_enable" and value and self.table[70] & self._shutdown:
                return StatusError.RESULT_FAIL
        return 0

    def _check_goal(self, value: int) -> int:
        if self._mode == 3:
            if not self._min_pos <= value <= self._max_pos:
                return StatusError.DATA_LIMIT
        elif self._mode in (4, 5) and abs(value) > _EXTENDED_GOAL:
            return StatusError.DATA_RANGE
        return 0

    def _after_write(self, start: int, end: int) -> None:
        was_torque = self._torque
        old_mode = self._mode
        if start < 116:  # every setting the model caches lies below Goal Position
            self._sync_params()
        if start < 120 and end > 116:
            (self._goal,) = struct.unpack_from("<i", self.table, 116)
            self._in_profile = (
                self._torque and self._mode in (3, 4, 5) and (self._x != self._goal or self._v != 0)
            )
        if self._mode != old_mode:
            self._goal = round(self._x)
            self.table[116:120] = self._goal.to_bytes(4, "little", signed=True)
        if self._torque != was_torque:
            if self._torque:
                self._in_profile = self._mode in (3, 4, 5) and self._x != self._goal
            else:
                self._v = self._a = 0.0
                self._in_profile = False
        self._dirty = True

    # ----------------------------------------------------------------- faults & instructions

    def raise_error(self, bits: HardwareError) -> None:
        """Latch ``bits`` in Hardware Error Status; bits also in Shutdown (63) turn torque off."""
        self.table[70] |= int(bits)
        if int(bits) & self._shutdown and self._torque:
            self.table[64] = 0
            self._after_write(64, 65)
        self._dirty = True

    def reboot(self) -> None:
        """RAM back to its initial values (torque off, errors cleared); EEPROM kept.

        The multi-turn count is lost, as at power-up: Present Position comes
        back within one revolution, and Goal Position is set to it.
        """
        fresh = self._initial_table(self.id)
        self.table[64:] = fresh[64:]
        self.registered = None
        self._x = float(round(self._x) % TICKS_PER_REV)
        self._v = self._a = 0.0
        self._goal = round(self._x)
        self.table[116:120] = self._goal.to_bytes(4, "little", signed=True)
        self._in_profile = False
        self._sync_params()
        self._dirty = True

    def factory_reset(self, option: int) -> None:
        """Initial values everywhere (0xFF), except ID (0x01), except ID and baud rate (0x02)."""
        keep_id, keep_baud = self.table[7], self.table[8]
        self.table[:64] = self._initial_table(1)[:64]
        if option in (0x01, 0x02):
            self.table[7] = keep_id
        if option == 0x02:
            self.table[8] = keep_baud
        self.reboot()

    def clear_multi_turn(self) -> int:
        """Present Position back within one revolution; Result Fail while moving (e-manual)."""
        if self._in_profile or self._v != 0.0:
            return StatusError.RESULT_FAIL
        self._x = float(round(self._x) % TICKS_PER_REV)
        self._dirty = True
        return 0

    def __repr__(self) -> str:
        return f"VirtualServo({self.id}, {self.model.name}, position={self._x:.1f})"


# --------------------------------------------------------------------------- chain


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
    rng: random.Random = field(default_factory=lambda: random.Random(0))


@dataclass(frozen=True, slots=True)
class Transaction:
    """One exchange: what the host sent, what came back, and the bus time it took."""

    request: bytes
    reply: bytes
    cost_s: float
    packets: tuple[Packet, ...]
    """The instruction packets decoded from ``request``."""


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
        self.servos: dict[int, VirtualServo] = {}
        self._ordered: list[VirtualServo] = []
        self._rekey()
        self.timing = timing
        self._load_model: LoadModel | None = None
        self.load_model = load_model
        self.faults = FaultState()
        self.hooks: list[Hook] = []
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
    def from_config(
        cls,
        cfg: RobotConfig,
        *,
        timing: TimingModel | None = None,
        fast_sync_read: bool = False,
        return_delay_us: int | None = None,
        load_model: LoadModel | None = None,
    ) -> ServoChain:
        """WHexaR's servos: IDs and models from ``cfg``, baud rate from ``cfg.bus``.

        Return Delay Time stays at the factory 250 (500 µs) unless
        ``return_delay_us`` presets it: the bus scheduler sets it at start-up.
        """
        servos: list[VirtualServo] = []
        for leg in cfg.legs:
            for j, sid in enumerate(leg.servo_ids):
                model = MODELS[cfg.joints.by_name(JOINT_NAMES[j]).model]
                servo = VirtualServo(sid, model, fast_sync_read=fast_sync_read)
                if return_delay_us is not None:
                    servo.set_register(
                        "return_delay_time", return_delay_units(return_delay_us * 1e-6)
                    )
                servos.append(servo)
        return cls(servos, timing or TimingModel(baudrate=cfg.bus.baudrate), load_model)

    def _rekey(self) -> None:
        if len(self.servos) == len(self._all) and all(k == s.id for k, s in self.servos.items()):
            return
        # On a duplicated ID the later servo wins, as a scan would find only one.
        self.servos = {s.id: s for s in self._all}
        self._ordered = sorted(self.servos.values(), key=lambda s: s.id)

    def advance(self, t: float) -> None:
        """Bring every servo's dynamics up to bus time ``t``."""
        for servo in self._all:
            servo.advance(t)

    def _hears(self, servo: VirtualServo, t: float) -> bool:
        silent = self.faults.silent_until
        return not silent or t >= silent.get(servo.id, -math.inf)

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
        if not self.faults.unplugged:
            for packet in packets:
                replies, fast = self._execute(packet, t)
                if packet.instruction in _WRITES:
                    self._rekey()
                if replies:
                    cost += self._deliver(replies, fast, reply)
        if reply and self.faults.corrupt_rate > 0.0:
            self._corrupt(reply)
        stats.bytes_out += len(reply)
        return Transaction(request, bytes(reply), cost, packets)

    def _deliver(self, replies: list[_Reply], fast: bool, out: bytearray) -> float:
        drop = self.faults.drop_rate
        rng = self.faults.rng
        packets = 0
        nbytes = 0
        delay = 0.0
        for servo, data in replies:
            if drop > 0.0 and rng.random() < drop:
                self.stats.dropped += 1
                continue
            if not fast or not packets:
                delay += servo.return_delay_s
                packets += 1
            nbytes += len(data)
            out += data
        if not packets:
            return 0.0
        self.stats.replies += packets
        return self.timing.read_s(0, packets, nbytes, delay / packets)

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

    def _execute(self, p: Packet, t: float) -> tuple[list[_Reply], bool]:
        inst = p.instruction
        broadcast = p.id == BROADCAST_ID
        if broadcast:
            targets = [s for s in self._ordered if self._hears(s, t)]
        else:
            one = self.servos.get(p.id)
            targets = [one] if one is not None and self._hears(one, t) else []
        if broadcast and inst in _GROUP_READS:
            return self._group_read(p, t)
        if broadcast and inst == Instruction.SYNC_WRITE:
            self._sync_write(p, t)
            return [], False
        if broadcast and inst == Instruction.BULK_WRITE:
            self._bulk_write(p, t)
            return [], False
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

    def _sync_write(self, p: Packet, t: float) -> None:
        try:
            start, _, entries = parse_sync_write_params(p.params)
        except PacketError:
            self.stats.bad_requests += 1
            return
        servos = self.servos
        for servo_id, data in entries:
            servo = servos.get(servo_id)
            if servo is not None and self._hears(servo, t):
                servo.write(start, data)

    def _bulk_write(self, p: Packet, t: float) -> None:
        try:
            entries = parse_bulk_write_params(p.params)
        except PacketError:
            self.stats.bad_requests += 1
            return
        for servo_id, start, data in entries:
            servo = self.servos.get(servo_id)
            if servo is not None and self._hears(servo, t):
                servo.write(start, data)

    def _group_read(self, p: Packet, t: float) -> tuple[list[_Reply], bool]:
        """(Fast) Sync/Bulk Read: replies in the order the instruction lists the IDs (e-manual)."""
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
            servo = self.servos.get(servo_id)
            ok = (
                servo is not None
                and self._hears(servo, t)
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


# --------------------------------------------------------------------------- port

_SDK_BAUDRATES: Final = frozenset(
    {9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 576000, 921600, 1000000}
    | {1152000, 2000000, 2500000, 3000000, 3500000, 4000000}
)
"""Rates dynamixel-sdk 4.1.0's ``PortHandler.setBaudRate`` accepts."""


class EmulatedPort:
    """Duck-typed port for dynamixel-sdk that talks to a :class:`ServoChain` on bus time.

    The SDK uses only ``is_using``, ``clearPort()``, ``writePort(bytes)``,
    ``readPort(n)``, ``setPacketTimeout(n)``, ``setPacketTimeoutMillis(ms)``,
    ``isPacketTimeout()`` and ``getBaudRate()``; the rest of ``PortHandler``'s
    surface is here too. Each write runs one transaction at bus time
    ``now() + elapsed_s`` and adds its cost to :attr:`elapsed_s`. The SDK asks
    whether it has timed out only when bytes are missing; the port then
    charges the rest of the SDK's timeout (``tx_time_per_byte·n + 2·latency
    timer + 2 ms``, counted from the write, as ``PortHandler`` does) and says
    yes, so a failed read costs what it costs on a real bus.
    """

    def __init__(
        self,
        chain: ServoChain,
        now: Callable[[], float] = lambda: 0.0,
        *,
        latency_timer_ms: float = 16.0,
        timer: Callable[[], float] | None = None,
    ) -> None:
        self.chain = chain
        self.now = now
        self.latency_timer_ms = latency_timer_ms
        self.timer = timer
        self.is_open = True
        self.is_using = False
        self.port_name = "emulated"
        self.baudrate = chain.timing.baudrate
        self.elapsed_s = 0.0
        """Bus time accumulated since the last :meth:`take_elapsed`."""
        self.emulator_s = 0.0
        """Host CPU seconds spent inside the chain (only counted when ``timer`` is given)."""
        self.last: Transaction | None = None
        self._rx = bytearray()
        self._tx_start = 0.0
        self._deadline = 0.0

    @property
    def tx_time_per_byte(self) -> float:
        """Milliseconds per byte at the port's baud rate (``PortHandler``'s attribute)."""
        return 1000.0 / self.baudrate * 10.0

    def take_elapsed(self) -> float:
        """Return :attr:`elapsed_s` and reset it to 0."""
        elapsed = self.elapsed_s
        self.elapsed_s = 0.0
        self._tx_start -= elapsed
        self._deadline -= elapsed
        return elapsed

    def _check_plugged(self) -> None:
        if self.chain.faults.unplugged:
            raise OSError(errno.EIO, "emulated port: device disconnected")

    def openPort(self) -> bool:  # noqa: N802
        """Always succeeds: there is no device to open."""
        self.is_open = True
        return True

    def closePort(self) -> None:  # noqa: N802
        """Mark the port closed (the chain keeps its state)."""
        self.is_open = False

    def clearPort(self) -> None:  # noqa: N802
        """Drop received bytes not yet read (the SDK does this before every transmit)."""
        self._rx.clear()

    def setPortName(self, port_name: str) -> None:  # noqa: N802
        """Rename the port (cosmetic)."""
        self.port_name = port_name

    def getPortName(self) -> str:  # noqa: N802
        """The port's name, ``"emulated"`` unless renamed."""
        return self.port_name

    def setBaudRate(self, baudrate: int) -> bool:  # noqa: N802
        """Accept a rate from the SDK's list; servos at another rate will not hear the port."""
        if baudrate not in _SDK_BAUDRATES:
            return False
        self.baudrate = baudrate
        return True

    def getBaudRate(self) -> int:  # noqa: N802
        """The port's baud rate."""
        return self.baudrate

    def getBytesAvailable(self) -> int:  # noqa: N802
        """Received bytes not yet read."""
        return len(self._rx)

    def readPort(self, length: int) -> bytes:  # noqa: N802
        """Up to ``length`` received bytes; ``OSError(EIO)`` when unplugged."""
        self._check_plugged()
        data = bytes(self._rx[:length])
        del self._rx[:length]
        return data

    def writePort(self, packet: bytes | Sequence[int]) -> int:  # noqa: N802
        """Send ``packet``: one chain transaction, its reply buffered, its cost added."""
        self._check_plugged()
        data = bytes(packet)
        self._tx_start = self._deadline = self.elapsed_s
        if self.baudrate != self.chain.timing.baudrate:
            # Servos at another rate see framing errors only: nothing answers.
            self.elapsed_s += len(data) * self.chain.timing.bits_per_byte / self.baudrate
            return len(data)
        started = self.timer() if self.timer is not None else 0.0
        tx = self.chain.transact(data, self.now() + self.elapsed_s)
        if self.timer is not None:
            self.emulator_s += self.timer() - started
        self.last = tx
        self._rx += tx.reply
        self.elapsed_s += tx.cost_s
        return len(data)

    def setPacketTimeout(self, packet_length: int) -> None:  # noqa: N802
        """Arm the SDK's timeout for ``packet_length`` bytes, counted from the last write."""
        # dynamixel_sdk PortHandler: tx_time_per_byte·n + LATENCY_TIMER·2 + 2 ms.
        ms = self.tx_time_per_byte * packet_length + 2.0 * self.latency_timer_ms + 2.0
        self._deadline = self._tx_start + ms / 1000.0

    def setPacketTimeoutMillis(self, msec: float) -> None:  # noqa: N802
        """Arm a timeout of ``msec`` ms, counted from the last write."""
        self._deadline = self._tx_start + msec / 1000.0

    def isPacketTimeout(self) -> bool:  # noqa: N802
        """True once nothing is left to read; bus time then runs on to the deadline."""
        if self._rx:
            return False
        self.elapsed_s = max(self.elapsed_s, self._deadline)
        return True
