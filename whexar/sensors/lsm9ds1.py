"""The LSM9DS1 accelerometer and gyroscope on I²C: register map, configuration, conversions.

The thesis reads the IMU's accelerometer from the Raspberry Pi over I²C with
a Python library (Žák 2023, 5.3.4, 5.4); this is that library, small enough
to check against the datasheet line by line. Every constant cites STMicro's
LSM9DS1 datasheet (DocID025715): the register map is its section 6
(Table 21), each register's bits its section 7, the sensitivities Table 3.

Theory of operation
-------------------
* **Sans-clock.** The driver never sleeps nor reads a clock: each method is a
  short, fixed sequence of bus transactions. Timing (how often to read, when
  to retry) belongs to the caller, :class:`whexar.actors.sensing.ImuReader`.
* **Injected bus.** :class:`Lsm9ds1` drives any object with smbus2's three
  byte and block calls (:class:`SMBusLike`): ``smbus2.SMBus`` on the robot,
  :class:`whexar.sensors.imu_emulator.FakeSMBus` in tests and simulation.
* **Configure = write a known state, then read it back.** :func:`settings`
  computes, purely, the value of every register that shapes the output
  (rates, full scales, filters, axis signs, FIFO off), so a chip left in any
  state by another program ends in ours; :meth:`Lsm9ds1.configure` writes
  them and refuses a chip that does not hold them.
* **One sample, two block reads.** STATUS_REG (0x17) sits just before the
  gyroscope's outputs (0x18–0x1D), so one 7-byte read gives the data-ready
  bits and the angular rate; a second 6-byte read gives the acceleration
  (0x28–0x2D; the two output blocks are not contiguous). Block Data Update
  keeps each axis's two bytes from one sample; the two reads may straddle a
  sample boundary, which at the rates used here (≤ 1 ODR period apart) is
  immaterial.
* **Errors at the edge.** ``OSError`` from the bus (a NAK is errno 121 on
  Linux, a missing ``/dev/i2c-N`` errno 2) becomes
  :class:`~whexar.errors.DeviceGoneError`; a chip that answers wrongly (wrong
  WHO_AM_I, a register that does not keep its value) is
  :class:`~whexar.errors.DeviceError`; a wrong argument is
  :class:`~whexar.errors.UsageError`.

The magnetometer (its own I²C address, 0x1E/0x1C) is not used.
"""

from __future__ import annotations

import contextlib
import math
import struct
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Final, Protocol, TypeVar

from whexar.errors import DeviceError, DeviceGoneError, UsageError
from whexar.runtime.channels import LinkTap

T = TypeVar("T")

# --------------------------------------------------------------------------- addresses

ADDRESS: Final = 0x6B
"""I²C address of the accelerometer/gyroscope with SDO_AG high (breakout default; §6.1.1)."""
ADDRESS_ALT: Final = 0x6A
"""I²C address with SDO_AG low (§6.1.1)."""
WHO_AM_I_VALUE: Final = 0x68
"""What WHO_AM_I reads on an LSM9DS1 accelerometer/gyroscope (§7.11)."""

# --------------------------------------------------------------------------- register map
# Accelerometer and gyroscope registers (§6, Table 21).

WHO_AM_I: Final = 0x0F
CTRL_REG1_G: Final = 0x10
"""ODR_G (bits 7:5), FS_G (4:3), BW_G (1:0) (§7.12)."""
CTRL_REG2_G: Final = 0x11
"""INT_SEL, OUT_SEL: which filters feed the gyroscope's outputs (§7.13)."""
CTRL_REG3_G: Final = 0x12
"""Low-power mode and the gyroscope's high-pass filter (§7.14)."""
ORIENT_CFG_G: Final = 0x13
"""Sign of each gyroscope axis and orientation (§7.15)."""
STATUS_REG: Final = 0x17
"""Data-ready bits; mirrored at 0x27 (§7.18, §7.30)."""
OUT_X_L_G: Final = 0x18
"""Angular rate X, Y, Z: little-endian int16 at 0x18–0x1D (§7.19–7.21)."""
CTRL_REG4: Final = 0x1E
"""Gyroscope axis enables Zen_G, Yen_G, Xen_G (bits 5:3) (§7.22)."""
CTRL_REG5_XL: Final = 0x1F
"""Decimation (7:6) and accelerometer axis enables (5:3) (§7.23)."""
CTRL_REG6_XL: Final = 0x20
"""ODR_XL (bits 7:5), FS_XL (4:3), BW_SCAL_ODR (2), BW_XL (1:0) (§7.24)."""
CTRL_REG7_XL: Final = 0x21
"""High-resolution mode and the accelerometer's filters (§7.25)."""
CTRL_REG8: Final = 0x22
"""BOOT, BDU, interface options, IF_ADD_INC, SW_RESET (§7.26)."""
CTRL_REG9: Final = 0x23
"""Gyroscope sleep, FIFO enable, I2C_DISABLE (§7.27)."""
OUT_X_L_XL: Final = 0x28
"""Acceleration X, Y, Z: little-endian int16 at 0x28–0x2D (§7.31–7.33)."""
FIFO_CTRL: Final = 0x2E
"""FIFO mode and threshold (§7.34)."""

REGISTER_NAMES: Final[Mapping[int, str]] = {
    WHO_AM_I: "WHO_AM_I",
    CTRL_REG1_G: "CTRL_REG1_G",
    CTRL_REG2_G: "CTRL_REG2_G",
    CTRL_REG3_G: "CTRL_REG3_G",
    ORIENT_CFG_G: "ORIENT_CFG_G",
    STATUS_REG: "STATUS_REG",
    OUT_X_L_G: "OUT_X_L_G",
    CTRL_REG4: "CTRL_REG4",
    CTRL_REG5_XL: "CTRL_REG5_XL",
    CTRL_REG6_XL: "CTRL_REG6_XL",
    CTRL_REG7_XL: "CTRL_REG7_XL",
    CTRL_REG8: "CTRL_REG8",
    CTRL_REG9: "CTRL_REG9",
    OUT_X_L_XL: "OUT_X_L_XL",
    FIFO_CTRL: "FIFO_CTRL",
}
"""Register names for error messages."""

# --------------------------------------------------------------------------- bits

XLDA: Final = 0x01
"""STATUS_REG bit 0: a new acceleration sample is available (§7.18)."""
GDA: Final = 0x02
"""STATUS_REG bit 1: a new angular-rate sample is available (§7.18)."""
SW_RESET: Final = 0x01
"""CTRL_REG8 bit 0: reset the registers to their defaults; clears itself (§7.26)."""
IF_ADD_INC: Final = 0x04
"""CTRL_REG8 bit 2: auto-increment the register address in block access; default 1 (§7.26)."""
BDU: Final = 0x40
"""CTRL_REG8 bit 6: outputs not updated until both bytes of the last sample are read (§7.26)."""
CTRL_REG8_RESET: Final = IF_ADD_INC
"""CTRL_REG8's reset value, 0x04 (Table 21)."""
AXES_ENABLED: Final = 0x38
"""X, Y, Z enabled (bits 5:3): the reset value of CTRL_REG4 and CTRL_REG5_XL (§7.22, §7.23)."""
ODR_SHIFT: Final = 5
FS_SHIFT: Final = 3

ODR_HZ: Final[tuple[float, ...]] = (14.9, 59.5, 119.0, 238.0, 476.0, 952.0)
"""Output data rates of ODR codes 1–6 with the gyroscope on (§7.12, Table 46).

With the gyroscope on, both sensors run at ODR_G; the same code in ODR_XL
(Table 68 lists 10, 50, 119… Hz for the accelerometer alone) keeps the two
registers consistent, as ST's own driver writes them (``LSM9DS1_IMU_59Hz5`` =
code 2 in both). Code 0 is power-down.
"""

ACCEL_SCALES: Final[Mapping[int, tuple[int, float]]] = {
    2: (0b00, 0.061e-3),
    4: (0b10, 0.122e-3),
    8: (0b11, 0.244e-3),
    16: (0b01, 0.732e-3),
}
"""Accelerometer full scale (±g) → (FS_XL code, g per LSB) (§7.24; Table 3, LA_So in mg/LSB).

The codes are not in order: 01 is ±16 g.
"""

GYRO_SCALES: Final[Mapping[int, tuple[int, float]]] = {
    245: (0b00, 8.75e-3),
    500: (0b01, 17.50e-3),
    2000: (0b11, 70e-3),
}
"""Gyroscope full scale (±dps) → (FS_G code, dps per LSB) (§7.12; Table 3, G_So in mdps/LSB).

FS_G code 10 is "not available".
"""

_XYZ = struct.Struct("<3h")
"""Three little-endian int16: X_L, X_H, Y_L, Y_H, Z_L, Z_H (§7.19–7.21, §7.31–7.33)."""

Vector = tuple[float, float, float]


class SMBusLike(Protocol):
    """The three calls of ``smbus2.SMBus`` the driver makes; anything with them will do."""

    def read_byte_data(self, i2c_addr: int, register: int, /) -> int: ...

    def write_byte_data(self, i2c_addr: int, register: int, value: int, /) -> None: ...

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int, /) -> list[int]: ...


class I2CBus(SMBusLike, Protocol):
    """An opened I²C adapter: the driver's calls, and ``close``."""

    def close(self) -> None: ...


class TappedBus:
    """An :class:`I2CBus` that reports each transaction to ``tap`` (``("tx" | "rx",
    now(), bytes)``: a recorder, :meth:`whexar.runtime.actor.Actor.tap`).

    What goes out is the address and the register, and for a write the value; what
    comes back is the bytes read. A transaction that fails reports what went out, then
    ``error`` with ``"ERRNO:message"``: what a replay raises again.
    """

    def __init__(self, inner: I2CBus, tap: LinkTap, now: Callable[[], float]) -> None:
        self.inner = inner
        self._tap = tap
        self._now = now

    def read_byte_data(self, i2c_addr: int, register: int, /) -> int:
        """Read one register."""
        self._tap("tx", self._now(), bytes((i2c_addr, register)))
        with self._failing():
            value = self.inner.read_byte_data(i2c_addr, register)
        self._tap("rx", self._now(), bytes((value,)))
        return value

    def write_byte_data(self, i2c_addr: int, register: int, value: int, /) -> None:
        """Write one register."""
        self._tap("tx", self._now(), bytes((i2c_addr, register, value)))
        with self._failing():
            self.inner.write_byte_data(i2c_addr, register, value)

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int, /) -> list[int]:
        """Read ``length`` registers from ``register`` on."""
        self._tap("tx", self._now(), bytes((i2c_addr, register)))
        with self._failing():
            data = self.inner.read_i2c_block_data(i2c_addr, register, length)
        self._tap("rx", self._now(), bytes(data))
        return data

    def close(self) -> None:
        """Close the adapter under it."""
        self.inner.close()

    @contextlib.contextmanager
    def _failing(self) -> Iterator[None]:
        try:
            yield
        except OSError as exc:
            self._tap("error", self._now(), f"{exc.errno}:{exc.strerror}".encode())
            raise


# --------------------------------------------------------------------------- pure helpers


def choose_odr(rate_hz: float) -> tuple[int, float]:
    """The lowest output data rate at or above ``rate_hz``: (ODR code, Hz).

    Sampling the chip no faster than it produces data means every read can
    find a new sample.
    """
    if not (isinstance(rate_hz, int | float) and math.isfinite(rate_hz) and rate_hz > 0):
        raise UsageError(f"rate_hz = {rate_hz!r}: must be a finite number > 0")
    for code, hz in enumerate(ODR_HZ, start=1):
        if hz >= rate_hz:
            return code, hz
    raise UsageError(f"rate_hz = {rate_hz!r}: the LSM9DS1 produces at most {ODR_HZ[-1]} Hz")


def accel_scale(range_g: int) -> tuple[int, float]:
    """(FS_XL code, g per LSB) of accelerometer full scale ``±range_g``."""
    if range_g not in ACCEL_SCALES:
        raise UsageError(f"accel_range_g = {range_g!r}: must be one of {sorted(ACCEL_SCALES)}")
    return ACCEL_SCALES[range_g]


def gyro_scale(range_dps: int) -> tuple[int, float]:
    """(FS_G code, dps per LSB) of gyroscope full scale ``±range_dps``."""
    if range_dps not in GYRO_SCALES:
        raise UsageError(f"gyro_range_dps = {range_dps!r}: must be one of {sorted(GYRO_SCALES)}")
    return GYRO_SCALES[range_dps]


def decode_xyz(data: Sequence[int], scale: float) -> Vector:
    """Three little-endian int16 output values (6 bytes), times ``scale`` (units per LSB)."""
    if len(data) != 6:
        raise UsageError(f"data has {len(data)} bytes: an output block is 6 (X, Y, Z as int16)")
    x, y, z = _XYZ.unpack(bytes(data))
    return x * scale, y * scale, z * scale


@dataclass(frozen=True, slots=True)
class Settings:
    """A configuration of the chip: what was asked, what the chip will do, and its registers."""

    rate_hz: float
    """The rate the host reads at."""
    odr_hz: float
    """The rate the chip samples at (the lowest ODR ≥ ``rate_hz``)."""
    accel_range_g: int
    gyro_range_dps: int
    accel_g_per_lsb: float
    gyro_dps_per_lsb: float
    registers: tuple[tuple[int, int], ...]
    """(register, value) in write order: set-up first, ODR last (it starts the sensors)."""

    def value(self, register: int) -> int:
        """The value this configuration writes to ``register``."""
        for reg, value in self.registers:
            if reg == register:
                return value
        raise UsageError(f"register 0x{register:02X} is not part of the configuration")


def settings(rate_hz: float, accel_range_g: int, gyro_range_dps: int) -> Settings:
    """The register values for reading at ``rate_hz`` with the given full scales (pure)."""
    code, odr_hz = choose_odr(rate_hz)
    fs_xl, g_per_lsb = accel_scale(accel_range_g)
    fs_g, dps_per_lsb = gyro_scale(gyro_range_dps)
    registers = (
        # BDU: a sample's two bytes are never from two samples; IF_ADD_INC: block reads.
        (CTRL_REG8, BDU | IF_ADD_INC),
        (CTRL_REG9, 0x00),  # no FIFO, gyroscope awake, I²C on
        (FIFO_CTRL, 0x00),  # bypass mode
        (ORIENT_CFG_G, 0x00),  # no axis sign flips
        (CTRL_REG2_G, 0x00),  # outputs after LPF1 only
        (CTRL_REG3_G, 0x00),  # normal mode, high-pass filter off
        (CTRL_REG4, AXES_ENABLED),
        (CTRL_REG5_XL, AXES_ENABLED),  # no decimation
        (CTRL_REG7_XL, 0x00),  # no high-resolution filter, no high-pass
        # Anti-aliasing bandwidth set by the ODR (BW_SCAL_ODR = 0).
        (CTRL_REG6_XL, code << ODR_SHIFT | fs_xl << FS_SHIFT),
        (CTRL_REG1_G, code << ODR_SHIFT | fs_g << FS_SHIFT),
    )
    return Settings(
        rate_hz=float(rate_hz),
        odr_hz=odr_hz,
        accel_range_g=accel_range_g,
        gyro_range_dps=gyro_range_dps,
        accel_g_per_lsb=g_per_lsb,
        gyro_dps_per_lsb=dps_per_lsb,
        registers=registers,
    )


def register_name(register: int) -> str:
    """``CTRL_REG1_G (0x10)``: a register as error messages show it."""
    name = REGISTER_NAMES.get(register)
    return f"{name} (0x{register:02X})" if name else f"register 0x{register:02X}"


@dataclass(frozen=True, slots=True)
class Reading:
    """One read of the outputs: acceleration (g), angular rate (dps) and STATUS_REG."""

    accel_g: Vector
    gyro_dps: Vector
    status: int

    @property
    def new(self) -> bool:
        """True when the chip had a sample the host had not read yet (XLDA or GDA)."""
        return bool(self.status & (XLDA | GDA))


@dataclass(frozen=True, slots=True)
class Calibration:
    """A chip's zero-g and zero-rate levels (``imu.accel_offset_g``, ``imu.gyro_offset_dps``),
    taken off its readings: an uncalibrated LSM9DS1 is typically off by ±90 mg and ±30 dps
    per axis (Table 3, "typical zero-g level offset accuracy", "zero-rate level")."""

    accel_offset_g: Vector = (0.0, 0.0, 0.0)
    gyro_offset_dps: Vector = (0.0, 0.0, 0.0)

    def apply(self, reading: Reading) -> Reading:
        """``reading`` less the offsets (the status bits as read)."""
        a, g = reading.accel_g, reading.gyro_dps
        oa, og = self.accel_offset_g, self.gyro_offset_dps
        return Reading(
            accel_g=(a[0] - oa[0], a[1] - oa[1], a[2] - oa[2]),
            gyro_dps=(g[0] - og[0], g[1] - og[1], g[2] - og[2]),
            status=reading.status,
        )


# --------------------------------------------------------------------------- the driver


class Lsm9ds1:
    """The accelerometer/gyroscope half of an LSM9DS1 at ``address`` on an injected bus.

    ``name`` labels errors (the reader passes its link name, ``i2c-1:0x6b``).
    Not thread-safe: one caller at a time, as the bus has one owner.
    """

    def __init__(self, bus: SMBusLike, address: int = ADDRESS, *, name: str | None = None) -> None:
        self.bus = bus
        self.address = address
        self.name = name or f"0x{address:02x}"
        self.settings: Settings | None = None
        """What :meth:`configure` last wrote; :meth:`read` scales by it."""

    def _io(self, what: str, call: Callable[[], T]) -> T:
        try:
            return call()
        except OSError as exc:
            raise DeviceGoneError(f"{self.name}: {what}: {exc}") from exc

    def read_register(self, register: int) -> int:
        """One register's value."""
        return self._io(
            f"reading {register_name(register)}",
            lambda: self.bus.read_byte_data(self.address, register),
        )

    def write_register(self, register: int, value: int) -> None:
        """Write one register."""
        self._io(
            f"writing 0x{value:02X} to {register_name(register)}",
            lambda: self.bus.write_byte_data(self.address, register, value),
        )

    def read_block(self, register: int, length: int) -> list[int]:
        """``length`` registers from ``register`` in one transaction (needs IF_ADD_INC)."""
        data = self._io(
            f"reading {length} bytes from {register_name(register)}",
            lambda: self.bus.read_i2c_block_data(self.address, register, length),
        )
        if len(data) != length:
            raise DeviceError(
                f"{self.name}: asked {length} bytes from {register_name(register)}, got {len(data)}"
            )
        return list(data)

    def probe(self) -> None:
        """Check that an LSM9DS1 answers: WHO_AM_I must read 0x68.

        Raises :class:`DeviceGoneError` if nothing answers and
        :class:`DeviceError` naming both values if something else does.
        """
        found = self.read_register(WHO_AM_I)
        if found != WHO_AM_I_VALUE:
            raise DeviceError(
                f"{self.name}: WHO_AM_I (0x{WHO_AM_I:02X}) reads 0x{found:02X}, "
                f"expected 0x{WHO_AM_I_VALUE:02X} (LSM9DS1 accelerometer/gyroscope): "
                "another device is at this address"
            )

    def configure(self, rate_hz: float, accel_range_g: int, gyro_range_dps: int) -> Settings:
        """Write :func:`settings` and read every register back; the settings in force.

        Raises :class:`DeviceError` naming each register that did not keep its value.
        """
        wanted = settings(rate_hz, accel_range_g, gyro_range_dps)
        for register, value in wanted.registers:
            self.write_register(register, value)
        wrong = self.mismatches(wanted)
        if wrong:
            raise DeviceError(f"{self.name}: configuration did not hold: {'; '.join(wrong)}")
        self.settings = wanted
        return wanted

    def mismatches(self, wanted: Settings) -> list[str]:
        """Each register whose value differs from ``wanted``'s, as ``NAME = 0x.., expected 0x..``.

        Empty when the chip holds the configuration; a chip that reset itself
        (a brown-out) reads its defaults instead.
        """
        wrong = []
        for register, value in wanted.registers:
            found = self.read_register(register)
            if found != value:
                wrong.append(f"{register_name(register)} = 0x{found:02X}, expected 0x{value:02X}")
        return wrong

    def read(self) -> Reading:
        """One sample: STATUS_REG and the angular rate in one block, the acceleration in another."""
        current = self.settings
        if current is None:
            raise UsageError(f"{self.name}: read() before configure(): the scales are unknown")
        head = self.read_block(STATUS_REG, 7)  # STATUS_REG, then OUT_X_L_G … OUT_Z_H_G
        accel = self.read_block(OUT_X_L_XL, 6)
        return Reading(
            accel_g=decode_xyz(accel, current.accel_g_per_lsb),
            gyro_dps=decode_xyz(head[1:], current.gyro_dps_per_lsb),
            status=head[0],
        )


__all__ = [
    "ACCEL_SCALES",
    "ADDRESS",
    "ADDRESS_ALT",
    "AXES_ENABLED",
    "BDU",
    "CTRL_REG1_G",
    "CTRL_REG2_G",
    "CTRL_REG3_G",
    "CTRL_REG4",
    "CTRL_REG5_XL",
    "CTRL_REG6_XL",
    "CTRL_REG7_XL",
    "CTRL_REG8",
    "CTRL_REG8_RESET",
    "CTRL_REG9",
    "FIFO_CTRL",
    "FS_SHIFT",
    "GDA",
    "GYRO_SCALES",
    "IF_ADD_INC",
    "ODR_HZ",
    "ODR_SHIFT",
    "ORIENT_CFG_G",
    "OUT_X_L_G",
    "OUT_X_L_XL",
    "REGISTER_NAMES",
    "STATUS_REG",
    "SW_RESET",
    "WHO_AM_I",
    "WHO_AM_I_VALUE",
    "XLDA",
    "Calibration",
    "I2CBus",
    "Lsm9ds1",
    "Reading",
    "SMBusLike",
    "Settings",
    "Vector",
    "accel_scale",
    "choose_odr",
    "decode_xyz",
    "gyro_scale",
    "register_name",
    "settings",
]
