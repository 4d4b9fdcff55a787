"""Control tables of the Dynamixel MX servos (MX (2.0) firmware, Protocol 2.0) and their units.

Addresses, sizes, access and initial values are the ROBOTIS e-manual's
"MX-28(2.0)", "MX-64(2.0)" and "MX-106(2.0)" control tables. The three models
share every address; the MX-28 has no current control, so it lacks Current
Limit (38) and Goal Current (102), and its register 126 is Present Load (0.1 %
units) rather than Present Current (about 3.36 mA units).

Register names are the e-manual's in snake case (``present_position``).
Conversions to SI live here too, so that one place knows every unit:
positions in rad (4096 ticks per revolution, 2048 at the centre), velocities
in rad/s (0.229 rev/min per unit), currents in A, voltages in V.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from enum import IntFlag
from typing import Final, Literal

from whexar.errors import UsageError

Access = Literal["R", "RW"]
Area = Literal["eeprom", "ram"]


@dataclass(frozen=True, slots=True)
class Register:
    """One control-table entry: ``size`` bytes at ``address``, little-endian."""

    name: str
    address: int
    size: int
    access: Access
    area: Area
    signed: bool = False
    initial: int | None = None

    @property
    def end(self) -> int:
        """The address just past this register."""
        return self.address + self.size

    def decode(self, data: bytes | bytearray | memoryview, offset: int = 0) -> int:
        """The register's value from ``data`` whose first byte is at address ``offset``."""
        start = self.address - offset
        return int.from_bytes(data[start : start + self.size], "little", signed=self.signed)

    def encode(self, value: int) -> bytes:
        """``value`` as the register's bytes; raises :class:`UsageError` if it does not fit."""
        try:
            return int(value).to_bytes(self.size, "little", signed=self.signed)
        except OverflowError:
            kind = "signed" if self.signed else "unsigned"
            raise UsageError(
                f"{self.name} = {value!r}: does not fit a {kind} {self.size}-byte register"
            ) from None


def _r(
    name: str,
    address: int,
    size: int,
    access: Access = "RW",
    *,
    signed: bool = False,
    initial: int | None = None,
) -> Register:
    # EEPROM ends at Shutdown (63); Torque Enable (64) opens the RAM area (e-manual).
    return Register(
        name, address, size, access, "eeprom" if address < 64 else "ram", signed, initial
    )


_COMMON: Final = (
    _r("model_number", 0, 2, "R"),
    _r("model_information", 2, 4, "R"),
    _r("firmware_version", 6, 1, "R"),
    _r("id", 7, 1, initial=1),
    _r("baud_rate", 8, 1, initial=1),
    _r("return_delay_time", 9, 1, initial=250),
    _r("drive_mode", 10, 1, initial=0),
    _r("operating_mode", 11, 1, initial=3),
    _r("secondary_id", 12, 1, initial=255),
    _r("protocol_type", 13, 1, initial=2),
    _r("homing_offset", 20, 4, signed=True, initial=0),
    _r("moving_threshold", 24, 4, initial=10),
    _r("temperature_limit", 31, 1, initial=80),
    _r("max_voltage_limit", 32, 2, initial=160),
    _r("min_voltage_limit", 34, 2, initial=95),
    _r("pwm_limit", 36, 2, initial=885),
    _r("acceleration_limit", 40, 4, initial=32767),
    _r("velocity_limit", 44, 4),  # per model, see MODELS
    _r("max_position_limit", 48, 4, initial=4095),
    _r("min_position_limit", 52, 4, initial=0),
    _r("shutdown", 63, 1, initial=52),
    _r("torque_enable", 64, 1, initial=0),
    _r("led", 65, 1, initial=0),
    _r("status_return_level", 68, 1, initial=2),
    _r("registered_instruction", 69, 1, "R", initial=0),
    _r("hardware_error_status", 70, 1, "R", initial=0),
    _r("velocity_i_gain", 76, 2, initial=1920),
    _r("velocity_p_gain", 78, 2, initial=100),
    _r("position_d_gain", 80, 2, initial=0),
    _r("position_i_gain", 82, 2, initial=0),
    _r("position_p_gain", 84, 2, initial=850),
    _r("feedforward_2nd_gain", 88, 2, initial=0),
    _r("feedforward_1st_gain", 90, 2, initial=0),
    _r("bus_watchdog", 98, 1, signed=True, initial=0),
    _r("goal_pwm", 100, 2, signed=True),
    _r("goal_velocity", 104, 4, signed=True),
    _r("profile_acceleration", 108, 4, initial=0),
    _r("profile_velocity", 112, 4, initial=0),
    _r("goal_position", 116, 4, signed=True),
    _r("realtime_tick", 120, 2, "R"),
    _r("moving", 122, 1, "R", initial=0),
    _r("moving_status", 123, 1, "R", initial=0),
    _r("present_pwm", 124, 2, "R", signed=True),
    _r("present_velocity", 128, 4, "R", signed=True),
    _r("present_position", 132, 4, "R", signed=True),
    _r("velocity_trajectory", 136, 4, "R", signed=True),
    _r("position_trajectory", 140, 4, "R", signed=True),
    _r("present_input_voltage", 144, 2, "R"),
    _r("present_temperature", 146, 1, "R"),
)
_CURRENT: Final = (
    _r("current_limit", 38, 2),
    _r("goal_current", 102, 2, signed=True),
    _r("present_current", 126, 2, "R", signed=True),
)
_LOAD: Final = (_r("present_load", 126, 2, "R", signed=True),)

TABLE_SIZE: Final = 662
"""Bytes of the MX (2.0) control table, up to Indirect Data 56 (661)."""


class HardwareError(IntFlag):
    """Bits of Hardware Error Status (70) and of Shutdown (63) (e-manual, MX (2.0))."""

    INPUT_VOLTAGE = 0x01
    OVERHEATING = 0x04
    MOTOR_ENCODER = 0x08
    ELECTRICAL_SHOCK = 0x10
    OVERLOAD = 0x20

    def describe(self) -> str:
        """``"overheating, overload"``; ``"none"`` for no bits."""
        names = [(f.name or "").lower().replace("_", " ") for f in HardwareError if f in self]
        return ", ".join(names) or "none"


@dataclass(frozen=True, slots=True)
class ServoModel:
    """One Dynamixel model: its number (address 0), registers and unit of register 126."""

    name: str
    model_number: int
    registers: Mapping[str, Register]
    current_unit_a: float | None
    """Present/Goal Current unit; ``None`` where 126 is Present Load (MX-28)."""
    fast_sync_read: bool = False
    """Whether the firmware is *known* to answer Fast Sync Read; MX is not (unconfirmed)."""

    def register(self, name: str) -> Register:
        """The register called ``name``; :class:`UsageError` lists the known ones if absent."""
        try:
            return self.registers[name]
        except KeyError:
            raise UsageError(
                f"{self.name} has no register {name!r}; "
                f"allowed: {', '.join(sorted(self.registers))}"
            ) from None

    def initial_table(self) -> bytearray:
        """A control table holding the e-manual's initial values (zeros elsewhere)."""
        table = bytearray(TABLE_SIZE)
        for reg in self.registers.values():
            if reg.initial is not None:
                table[reg.address : reg.end] = reg.encode(reg.initial)
        table[0:2] = self.model_number.to_bytes(2, "little")
        return table


def _model(name: str, number: int, current: bool, initial: Mapping[str, int]) -> ServoModel:
    regs = tuple(
        Register(r.name, r.address, r.size, r.access, r.area, r.signed, initial[r.name])
        if r.name in initial
        else r
        for r in (*_COMMON, *(_CURRENT if current else _LOAD))
    )
    table = {r.name: r for r in sorted(regs, key=lambda r: r.address)}
    # 3.36 mA per unit: e-manual, MX-64(2.0)/MX-106(2.0) Goal Current (102).
    return ServoModel(name, number, table, CURRENT_UNIT_A if current else None)


CURRENT_UNIT_A: Final = 0.00336
"""Present/Goal Current unit of the MX-64/106 (2.0), "about 3.36 mA" (e-manual)."""
LOAD_UNIT: Final = 0.001
"""Present Load unit of the MX-28 (2.0): 0.1 % of the maximum torque (e-manual)."""
TICKS_PER_REV: Final = 4096
"""Resolution of every MX (e-manual: 0.088°/tick, AS5045 12-bit encoder)."""
CENTER_TICKS: Final = 2048
"""Present Position of the horn's centre mark; joint angle 0 (Table 6.5's zero)."""
VELOCITY_UNIT_RPM: Final = 0.229
"""Velocity unit (Goal/Present Velocity, Profile Velocity): 0.229 rev/min (e-manual)."""
ACCELERATION_UNIT_RPM2: Final = 214.577
"""Profile Acceleration unit: 214.577 rev/min² (e-manual)."""
VOLTAGE_UNIT_V: Final = 0.1
"""Present Input Voltage and voltage limits: 0.1 V per unit (e-manual)."""
RETURN_DELAY_UNIT_S: Final = 2e-6
"""Return Delay Time: 2 µs per unit (e-manual)."""

MODELS: Final[Mapping[str, ServoModel]] = {
    "MX-28": _model("MX-28", 30, False, {"velocity_limit": 230}),
    "MX-64": _model("MX-64", 311, True, {"velocity_limit": 435, "current_limit": 1941}),
    "MX-106": _model("MX-106", 321, True, {"velocity_limit": 360, "current_limit": 2047}),
}
"""The MX (2.0) models by name; model numbers from the e-manual (address 0)."""

MODELS_BY_NUMBER: Final[Mapping[int, ServoModel]] = {m.model_number: m for m in MODELS.values()}


def model(name: str) -> ServoModel:
    """The model called ``name`` (``"MX-64"``); :class:`UsageError` lists the known ones."""
    try:
        return MODELS[name]
    except KeyError:
        raise UsageError(f"unknown servo model {name!r}; allowed: {', '.join(MODELS)}") from None


def model_name(number: int) -> str:
    """``"MX-64"`` for 311; ``"model 1234"`` for a number not in :data:`MODELS`."""
    known = MODELS_BY_NUMBER.get(number)
    return known.name if known else f"model {number}"


_STRUCT_CODES: Final = {
    (1, False): "B",
    (1, True): "b",
    (2, False): "H",
    (2, True): "h",
    (4, False): "I",
    (4, True): "i",
}


@dataclass(frozen=True, slots=True)
class Block:
    """A contiguous span of registers read or written in one transaction."""

    start: int
    length: int
    registers: tuple[Register, ...]
    """The registers asked for, in address order (the span may include others)."""
    _layout: struct.Struct = field(init=False, repr=False, compare=False)
    _names: tuple[str, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        # One precompiled little-endian layout: decoding a span is one C call.
        fmt, at = "<", self.start
        for r in self.registers:
            fmt += "x" * (r.address - at) + _STRUCT_CODES[r.size, r.signed]
            at = r.end
        fmt += "x" * (self.start + self.length - at)
        object.__setattr__(self, "_layout", struct.Struct(fmt))
        object.__setattr__(self, "_names", tuple(r.name for r in self.registers))

    def decode(self, data: bytes | bytearray | memoryview) -> dict[str, int]:
        """Every asked-for register's value from the span's bytes."""
        return dict(zip(self._names, self._layout.unpack_from(data), strict=True))


def block(names: Iterable[str], models: Iterable[ServoModel] = MODELS.values()) -> Block:
    """The smallest span covering registers ``names``, valid for every model in ``models``.

    Register 126 may be named ``present_current`` or ``present_load``: a span
    for mixed models reads the same two bytes, and each model decodes them in
    its own unit.
    """
    chosen: dict[str, Register] = {}
    wanted = list(names)
    if not wanted:
        raise UsageError("a register block needs at least one register")
    for name in wanted:
        for m in models:
            alias = {"present_current": "present_load", "present_load": "present_current"}
            reg = m.registers.get(name) or m.registers.get(alias.get(name, ""))
            if reg is None:
                raise UsageError(
                    f"register {name!r} does not exist on {m.name}; allowed: "
                    f"{', '.join(sorted(m.registers))}"
                )
            chosen.setdefault(
                name,
                Register(
                    name, reg.address, reg.size, reg.access, reg.area, reg.signed, reg.initial
                ),
            )
    regs = tuple(sorted(chosen.values(), key=lambda r: r.address))
    start = regs[0].address
    return Block(start, max(r.end for r in regs) - start, regs)


# --------------------------------------------------------------------------- units

_RAD_PER_TICK: Final = 2 * math.pi / TICKS_PER_REV
_RAD_S_PER_UNIT: Final = VELOCITY_UNIT_RPM * 2 * math.pi / 60


def ticks_to_rad(ticks: int, center: int = CENTER_TICKS) -> float:
    """Joint angle (rad) of a position in ticks, 0 at ``center``."""
    return (ticks - center) * _RAD_PER_TICK


def rad_to_ticks(angle: float, center: int = CENTER_TICKS) -> int:
    """Nearest position in ticks of a joint angle (rad)."""
    return center + round(angle / _RAD_PER_TICK)


def velocity_to_rad_s(units: int) -> float:
    """Present/Goal Velocity units (0.229 rev/min) to rad/s."""
    return units * _RAD_S_PER_UNIT


def rad_s_to_velocity(speed: float) -> int:
    """rad/s to the nearest velocity unit (0.229 rev/min)."""
    return round(speed / _RAD_S_PER_UNIT)


def current_to_a(units: int, servo: ServoModel) -> float:
    """Present Current in A; for the MX-28, Present Load as a fraction of full torque."""
    return units * (servo.current_unit_a if servo.current_unit_a is not None else LOAD_UNIT)


def a_to_current(amps: float, servo: ServoModel) -> int:
    """A to Goal Current units; :class:`UsageError` on a model without current control."""
    if servo.current_unit_a is None:
        raise UsageError(f"{servo.name} has no current control (no Goal Current register)")
    return round(amps / servo.current_unit_a)


def voltage_to_v(units: int) -> float:
    """Present Input Voltage units (0.1 V) to V."""
    return units * VOLTAGE_UNIT_V


def v_to_voltage(volts: float) -> int:
    """V to Present Input Voltage units (0.1 V)."""
    return round(volts / VOLTAGE_UNIT_V)


def return_delay_units(seconds: float) -> int:
    """Return Delay Time register value (2 µs units) for a delay in seconds."""
    return round(seconds / RETURN_DELAY_UNIT_S)
