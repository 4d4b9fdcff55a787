"""One virtual Dynamixel MX (2.0) servo: its control table, the e-manual's rules, its motor.

Theory of operation
-------------------
A :class:`VirtualServo` is what the host sees of a servo: a 1 KiB control
table read and written by address, with the e-manual's access rules (EEPROM
locked while torque is on, read-only spans, partial register writes, value
ranges, goals beyond their limits), Indirect Address/Data, Hardware Error
Status and its shutdown, Reboot, Factory Reset and Clear. The present values
(position, velocity, current, moving status, voltage, temperature) are
written into the table when a read covers them.

The motor itself is behind the seam of :mod:`whexar.bus.emulator.dynamics`:
the servo hands its :class:`~whexar.bus.emulator.dynamics.ServoDynamics` a
:class:`~whexar.bus.emulator.dynamics.Drive` (what the table orders) and
asks it to move its :class:`~whexar.bus.emulator.dynamics.Motion`; Present
Current comes from its load model. Nothing here reads a clock: the chain
advances each servo to the bus time of each transaction.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from typing import ClassVar, Final

from whexar.bus.control_table import (
    ACCELERATION_UNIT_RPM2,
    CENTER_TICKS,
    LOAD_UNIT,
    RETURN_DELAY_UNIT_S,
    TABLE_SIZE,
    TICKS_PER_REV,
    VELOCITY_UNIT_RPM,
    VOLTAGE_UNIT_V,
    HardwareError,
    Register,
    ServoModel,
)
from whexar.bus.emulator.dynamics import (
    POSITION_MODES,
    TRAPEZOIDAL,
    Drive,
    LoadModel,
    Motion,
    ServoDynamics,
    default_load,
)
from whexar.bus.protocol import MAX_ID, StatusError
from whexar.errors import UsageError

BOOT_TIME_S: Final = 0.4
"""How long a servo answers nothing after a Reboot or a power-up. The e-manual gives no
figure; "about 0.4 seconds" was measured on Protocol 2.0 servos (ROBOTIS-GIT/emanual
issue #1698), so every recovery sees a realistic boot."""
WATCHDOG_UNIT_S: Final = 0.02
"""Bus Watchdog (98): 1–127 in units of 20 ms; 0 off and clears its error; −1 the error
(e-manual, MX (2.0) control table, "Bus Watchdog")."""
_WATCHDOG_ERROR: Final = 0xFF
"""Bus Watchdog read back as −1: the watchdog stopped the servo."""
_GOALS: Final = frozenset({"goal_pwm", "goal_current", "goal_velocity", "goal_position"})
"""Goal values, read-only while the Bus Watchdog error is set (e-manual)."""

_VEL_TICKS: Final = VELOCITY_UNIT_RPM / 60.0 * TICKS_PER_REV
"""Ticks/s per velocity unit (0.229 rev/min, e-manual)."""
_ACC_TICKS: Final = ACCELERATION_UNIT_RPM2 / 3600.0 * TICKS_PER_REV
"""Ticks/s² per Profile Acceleration unit (214.577 rev/min², e-manual)."""


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
    "id": (0, MAX_ID),
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
    "bus_watchdog": (0, 127),
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
    """One MX (2.0) servo: its control table, the e-manual's write rules, and its motor.

    Motion comes from :attr:`dynamics` (default: the trapezoidal profiles of
    :class:`~whexar.bus.emulator.dynamics.TrapezoidalProfile`), Present
    Current from :attr:`load_model` (default:
    :func:`~whexar.bus.emulator.dynamics.default_load`). Not modelled: Homing
    Offset, Drive Mode's reverse bit, Secondary ID, Present PWM (reads 0), the
    baud-rate register. A Reboot or a power-up makes it silent for
    :attr:`boot_time_s`; the Bus Watchdog (98) stops it as the e-manual says.
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
        if not 0 <= servo_id <= MAX_ID:
            raise UsageError(f"servo_id = {servo_id!r}: a Dynamixel ID in 0–{MAX_ID}")
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
        self.motion = Motion(float(position))
        """The horn: position, velocity and acceleration in ticks (unrounded)."""
        self.dynamics: ServoDynamics = TRAPEZOIDAL
        """How the horn moves between transactions (:mod:`whexar.bus.emulator.dynamics`);
        the physics world puts its joint here."""
        self._drive: Drive | None = None
        self.boot_time_s = BOOT_TIME_S
        """Silence after a Reboot or a power-up (:data:`BOOT_TIME_S` unless set)."""
        self._ready_at = 0.0
        self._heard_at = 0.0
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
        return self.motion.position

    @property
    def velocity(self) -> float:
        """Present velocity in ticks/s."""
        return self.motion.velocity

    @property
    def acceleration(self) -> float:
        """Acceleration of the current profile phase in ticks/s² (0 when steady)."""
        return self.motion.acceleration

    @property
    def goal(self) -> int:
        """Goal Position (116) in ticks."""
        return self._goal

    @property
    def time(self) -> float:
        """Bus time the dynamics have been advanced to."""
        return self._t

    @property
    def drive(self) -> Drive:
        """What the control table asks of the motor now (a physics world reads it)."""
        return self._drive or self._make_drive()

    def set_state(self, position: float, velocity: float = 0.0) -> None:
        """Put the horn at ``position`` ticks moving at ``velocity`` ticks/s (a hook's override)."""
        self.motion.position = float(position)
        self.motion.velocity = float(velocity)
        self.motion.acceleration = 0.0
        self._in_profile = (
            self._torque and self._mode in POSITION_MODES and self.motion.position != self._goal
        )
        self._drive = None
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
        # The supply's accepted band as :meth:`_supervise` compares it, every transaction.
        self._volts_lo, self._volts_hi = self._min_v - 1e-9, self._max_v + 1e-9
        self._pwm_limit, self._current_limit = struct.unpack_from("<HH", t, 36)
        (self._vel_limit,) = struct.unpack_from("<I", t, 44)
        self._max_pos, self._min_pos = struct.unpack_from("<ii", t, 48)
        self._shutdown = t[63]
        self._torque = bool(t[64])
        self._srl = t[68]
        (self._goal_velocity,) = struct.unpack_from("<i", t, 104)
        self._prof_acc, self._prof_vel = struct.unpack_from("<II", t, 108)
        self._watchdog = t[98] if t[98] < 128 else 0  # −1 (error) monitors nothing
        self._watchdog_s = self._watchdog * WATCHDOG_UNIT_S
        self._drive = None

    # ----------------------------------------------------------------- dynamics

    def advance(self, t: float) -> None:
        """Integrate the dynamics up to bus time ``t`` (earlier times are ignored).

        The firmware's supervision comes first (:meth:`_supervise`).
        """
        self._supervise(t)
        self._move(t)

    def _supervise(self, t: float) -> None:
        """The firmware's checks up to ``t``, before the horn moves there.

        Input Voltage Error follows the supply: it sets while the voltage is
        outside the limits and clears when it returns, unless Shutdown (63)
        latched it (default Shutdown 52 leaves it out, so torque stays on).
        The Bus Watchdog stops the servo at the moment it expires.
        """
        errors = self.table[70]
        if self._volts_lo <= self.input_voltage_v <= self._volts_hi:
            if errors & 1 and not self._shutdown & 1:
                self.table[70] &= ~1 & 0xFF
                self._dirty = True
        elif not errors & 1:
            self.raise_error(HardwareError.INPUT_VOLTAGE)
        if self.temperature_c > self._temp_limit and not self.table[70] & 4:
            self.raise_error(HardwareError.OVERHEATING)
        if self._watchdog and self._torque:
            expiry = self._heard_at + self._watchdog_s
            if expiry < t:
                self._move(expiry)
                self._trip_watchdog()

    def follow(self, t: float, position: float, velocity: float, acceleration: float) -> None:
        """Advance to bus time ``t`` with the horn where a physics world has put it.

        What :meth:`advance` does, with the motion given instead of asked of
        :attr:`dynamics`: a world that moves every joint at once
        (:attr:`ServoChain.mover <whexar.bus.emulator.chain.ServoChain.mover>`)
        hands each servo its joint's state without a call per servo into it.
        """
        self._supervise(t)
        if t <= self._t:
            return
        self._t = t
        self._dirty = True
        motion = self.motion
        motion.position = position
        motion.velocity = velocity
        motion.acceleration = acceleration
        if self._in_profile and position == self._goal and velocity == 0.0:
            self._in_profile = False
            self._drive = None

    def _move(self, t: float) -> None:
        dt = t - self._t
        if dt <= 0.0:
            return
        self._t = t
        self._dirty = True
        motion = self.motion
        self.dynamics.advance(motion, self._drive or self._make_drive(), dt)
        if self._in_profile and motion.position == self._goal and motion.velocity == 0.0:
            self._in_profile = False
            self._drive = None

    def _trip_watchdog(self) -> None:
        """Stop where the horn is, Profile Acceleration and Velocity taken as 0 (e-manual):
        Goal Position becomes the present one, Goal Velocity 0; goals turn read-only."""
        self.table[98] = _WATCHDOG_ERROR
        self.motion.velocity = self.motion.acceleration = 0.0
        self._goal = round(self.motion.position)
        self.table[116:120] = self._goal.to_bytes(4, "little", signed=True)
        self.table[104:108] = bytes(4)
        self._in_profile = False
        self._sync_params()
        self._dirty = True

    def heard(self, t: float) -> None:
        """An instruction packet addressed to this servo arrived at ``t`` (feeds the watchdog)."""
        self._heard_at = t

    def booting(self, t: float) -> bool:
        """Still silent at ``t`` after a Reboot or a power-up."""
        return t < self._ready_at

    def _make_drive(self) -> Drive:
        """The table's orders to the motor, kept until a write or a profile's end changes them."""
        self._drive = Drive(
            torque=self._torque,
            mode=self._mode,
            goal_position=self._goal,
            profile_active=self._in_profile,
            goal_velocity=max(-self._vel_limit, min(self._vel_limit, self._goal_velocity))
            * _VEL_TICKS,
            max_velocity=min(self._prof_vel or self._vel_limit, self._vel_limit) * _VEL_TICKS,
            max_acceleration=self._prof_acc * _ACC_TICKS if self._prof_acc else math.inf,
        )
        return self._drive

    def _refresh(self) -> None:
        if not self._dirty:
            return
        self._dirty = False
        amps = (self.load_model or default_load)(self, self._t)
        unit = self.model.current_unit_a
        current = round(amps / unit) if unit is not None else round(amps / LOAD_UNIT)
        limit = 1000 if unit is None else 32767
        current = max(-limit, min(limit, current))
        velocity = max(-(2**31), min(2**31 - 1, round(self.motion.velocity / _VEL_TICKS)))
        position = max(-(2**31), min(2**31 - 1, round(self.motion.position)))
        moving = self._in_profile or abs(velocity) > self._moving_threshold
        status = 0
        if self._mode in POSITION_MODES:
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
            if self.table[98] == _WATCHDOG_ERROR and (
                name in _GOALS or (name == "bus_watchdog" and value != 0)
            ):
                return StatusError.DATA_RANGE  # only writing 0 to 98 clears the error
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
            motion = self.motion
            self._in_profile = (
                self._torque
                and self._mode in POSITION_MODES
                and (motion.position != self._goal or motion.velocity != 0)
            )
        if self._mode != old_mode:
            self._goal = round(self.motion.position)
            self.table[116:120] = self._goal.to_bytes(4, "little", signed=True)
        if self._torque != was_torque:
            if self._torque:
                at_goal = self.motion.position == self._goal
                self._in_profile = self._mode in POSITION_MODES and not at_goal
            else:
                self.motion.velocity = self.motion.acceleration = 0.0
                self._in_profile = False
        self._drive = None
        self._dirty = True

    # ----------------------------------------------------------------- faults & instructions

    def raise_error(self, bits: HardwareError) -> None:
        """Latch ``bits`` in Hardware Error Status; bits also in Shutdown (63) turn torque off."""
        self.table[70] |= int(bits)
        if int(bits) & self._shutdown and self._torque:
            self.table[64] = 0
            self._after_write(64, 65)
        self._dirty = True

    def reboot(self, t: float | None = None) -> None:
        """RAM back to its initial values (torque off, errors cleared); EEPROM kept.

        The multi-turn count is lost, as at power-up: Present Position comes
        back within one revolution, and Goal Position is set to it. The servo
        then boots: it hears nothing for :attr:`boot_time_s` from ``t``
        (default: the time it was advanced to, that of the instruction).
        """
        self._ready_at = (self._t if t is None else t) + self.boot_time_s
        fresh = self._initial_table(self.id)
        self.table[64:] = fresh[64:]
        self.registered = None
        self.motion.position = float(round(self.motion.position) % TICKS_PER_REV)
        self.motion.velocity = self.motion.acceleration = 0.0
        self._goal = round(self.motion.position)
        self.table[116:120] = self._goal.to_bytes(4, "little", signed=True)
        self._in_profile = False
        self._sync_params()
        self._dirty = True

    def power_cycle(self, t: float, off_s: float = 0.0) -> None:
        """Power lost at ``t`` for ``off_s``, then a boot: RAM at its initial values, torque
        off, and silent until ``t + off_s + boot_time_s``."""
        self.reboot(t)
        self._ready_at += off_s

    def power_off(self, t: float) -> None:
        """Power lost at ``t`` until :meth:`power_on`: RAM gone (torque off, the horn free),
        and nothing heard or answered. Unlike a silenced servo (a fault plan's ``silent``),
        which keeps holding its goal, an unpowered one holds nothing."""
        self.reboot(t)
        self._ready_at = math.inf

    def power_on(self, t: float) -> None:
        """Power back at ``t``: the servo boots as at power-up (:meth:`reboot`: torque off
        until it is enabled again, Goal Position where the horn is, silent for
        :attr:`boot_time_s`)."""
        self.reboot(t)

    @property
    def powered(self) -> bool:
        """False between :meth:`power_off` and :meth:`power_on`."""
        return not math.isinf(self._ready_at)

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
        if self._in_profile or self.motion.velocity != 0.0:
            return StatusError.RESULT_FAIL
        self.motion.position = float(round(self.motion.position) % TICKS_PER_REV)
        self._dirty = True
        return 0

    def __repr__(self) -> str:
        return f"VirtualServo({self.id}, {self.model.name}, position={self.motion.position:.1f})"
