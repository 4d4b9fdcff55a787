"""A fake I²C bus and a register-level LSM9DS1 accelerometer/gyroscope for tests and simulation.

Theory of operation
-------------------
:class:`FakeSMBus` stands in for ``smbus2.SMBus``: the same byte and block
calls, dispatched by address to devices in memory. An address where nothing
answers raises ``OSError(121, "Remote I/O error")``, which is what Linux's
i2c-dev reports when a device does not acknowledge (on the Raspberry Pi).

:class:`FakeLsm9ds1` is the chip as the host sees it: a 256-byte register
file with the datasheet's reset values, written and read by register
address, the same map as :mod:`whexar.sensors.lsm9ds1`. Its motion is two
settable vectors, :attr:`~FakeLsm9ds1.accel_g` and
:attr:`~FakeLsm9ds1.gyro_dps`; the output registers carry them quantised as
the chip does, by the full scale selected in CTRL_REG6_XL and CTRL_REG1_G,
saturating at the int16 limits.

The fake has no clock. While a sensor runs (its ODR code is not zero), a
transaction that finds the last sample read (its data-ready bits clear)
finds a new one: the outputs are refreshed from the vectors and XLDA (and
GDA, with the gyroscope on) set; reading a sensor's outputs clears its bit.
So each read of status, rate and acceleration gets one new sample, both
sensors' from the same instant: the chip as seen by a host that reads no
faster than the ODR, which is how the reader configures it. Powered down
(the reset state), or :meth:`frozen <FakeLsm9ds1.freeze>`, the outputs hold
and data-ready stays clear.

Modelled: WHO_AM_I, read-only registers ignoring writes, IF_ADD_INC for
block reads (off: every byte of the block is the first register), FS_XL and
FS_G scaling, SW_RESET, STATUS_REG (0x17, mirrored at 0x27). Not modelled:
filters and bandwidths, axis enables, FIFO, interrupts, the temperature
sensor, BOOT, BDU (a fake block read is atomic anyway).

Faults: :meth:`~FakeLsm9ds1.unplug` / :meth:`~FakeLsm9ds1.replug` (a
replugged chip has been powered off, so its registers are back at reset),
:meth:`~FakeLsm9ds1.power_cycle` (a brown-out: it answers, with its
configuration lost), :meth:`~FakeLsm9ds1.freeze` / :meth:`~FakeLsm9ds1.thaw`
(no new samples), and ``who_am_i`` (another device at the address).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Final, Protocol, TypeVar

from whexar.runtime.devices import DeviceKind
from whexar.sensors import lsm9ds1 as chip
from whexar.sensors.lsm9ds1 import I2CBus, Vector

EREMOTEIO: Final = 121
"""Linux's errno when an I²C device does not acknowledge ("Remote I/O error")."""
BLOCK_MAX: Final = 32
"""Longest SMBus block transfer (smbus2's ``I2C_SMBUS_BLOCK_MAX``)."""

I2C_BUS: Final = DeviceKind[I2CBus]("fake I²C bus", "fake")
"""Fake I²C buses in :data:`~whexar.runtime.devices.DEVICES`: ``device = "fake:NAME"``
of :class:`~whexar.actors.sensing.ImuReader` opens the one registered as NAME."""

_WRITABLE: Final = frozenset(
    [*range(0x04, 0x0E), *range(0x10, 0x14), *range(0x1E, 0x25), 0x2E, *range(0x30, 0x38)]
)
"""The accelerometer/gyroscope's r/w registers (datasheet Table 21); others ignore writes."""
_STATUS_MIRROR: Final = 0x27
_OUT_G: Final = range(chip.OUT_X_L_G, chip.OUT_X_L_G + 6)
_OUT_XL: Final = range(chip.OUT_X_L_XL, chip.OUT_X_L_XL + 6)
_ODR_MASK: Final = 0b111 << chip.ODR_SHIFT
_FS_MASK: Final = 0b11 << chip.FS_SHIFT
_ACCEL_BY_CODE: Final = dict(chip.ACCEL_SCALES.values())
_GYRO_BY_CODE: Final = dict(chip.GYRO_SCALES.values())
_GYRO_NOT_AVAILABLE: Final = 0b10
"""FS_G code 10 is "not available"; the fake reads it as ±245 dps."""


class FakeI2CDevice(Protocol):
    """What :class:`FakeSMBus` needs of a device: acknowledge, read, write."""

    def acknowledges(self) -> bool:
        """Whether the device answers its address now (False: the transaction fails)."""
        ...

    def read(self, register: int, length: int) -> list[int]:
        """One read transaction of ``length`` bytes from ``register``."""
        ...

    def write(self, register: int, value: int) -> None:
        """One write transaction of one byte to ``register``."""
        ...


D = TypeVar("D", bound=FakeI2CDevice)


def _nak(address: int) -> OSError:
    return OSError(EREMOTEIO, f"Remote I/O error (nothing acknowledged 0x{address:02x})")


class FakeSMBus:
    """An I²C bus in memory with ``smbus2.SMBus``'s byte and block calls.

    Register it for the reader with ``DEVICES.register(I2C_BUS, name, bus)``
    (:mod:`whexar.runtime.devices`); it outlives the actors, as hardware
    does. :attr:`closes` counts :meth:`close` calls, which leave
    the bus usable (the next open would find the same devices).
    """

    def __init__(self, number: int = 1) -> None:
        self.number = number
        """The ``/dev/i2c-N`` it stands for."""
        self.devices: dict[int, FakeI2CDevice] = {}
        self.closes = 0

    def attach(self, address: int, device: D) -> D:
        """Put ``device`` at ``address``; returns it."""
        self.devices[address] = device
        return device

    def _device(self, address: int) -> FakeI2CDevice:
        device = self.devices.get(address)
        if device is None or not device.acknowledges():
            raise _nak(address)
        return device

    def read_byte_data(self, i2c_addr: int, register: int, force: bool | None = None) -> int:
        """Read one register."""
        return self._device(i2c_addr).read(register, 1)[0]

    def write_byte_data(
        self, i2c_addr: int, register: int, value: int, force: bool | None = None
    ) -> None:
        """Write one register."""
        if not 0 <= value <= 0xFF:
            raise ValueError(f"value {value!r} is not a byte")
        self._device(i2c_addr).write(register, value)

    def read_i2c_block_data(
        self, i2c_addr: int, register: int, length: int, force: bool | None = None
    ) -> list[int]:
        """Read ``length`` bytes from ``register`` in one transaction (at most 32, as smbus2)."""
        if length > BLOCK_MAX:
            raise ValueError(f"Desired block length over {BLOCK_MAX} bytes")
        return self._device(i2c_addr).read(register, length)

    def close(self) -> None:
        """Count the close; the fake bus stays usable."""
        self.closes += 1


class FakeLsm9ds1:
    """The accelerometer/gyroscope of an LSM9DS1, register by register (see the module).

    ``accel_g`` and ``gyro_dps`` are the motion the chip senses, in its own
    axes; the default is at rest and level (+1 g on Z). ``who_am_i`` is what
    its WHO_AM_I register reads (0x68 for a real LSM9DS1).
    """

    def __init__(
        self,
        *,
        accel_g: Vector = (0.0, 0.0, 1.0),
        gyro_dps: Vector = (0.0, 0.0, 0.0),
        who_am_i: int = chip.WHO_AM_I_VALUE,
    ) -> None:
        self.accel_g = accel_g
        self.gyro_dps = gyro_dps
        self.who_am_i = who_am_i
        self.regs = bytearray(256)
        self.plugged = True
        self.frozen = False
        self.transactions = 0
        """Transactions the chip acknowledged."""
        self.refused = 0
        """Transactions addressed to it while unplugged."""
        self.resets = 0
        """Power-on and software resets since it was made."""
        self._reset()

    # ----------------------------------------------------------------- faults

    def unplug(self) -> None:
        """Disconnect: every transaction to it fails (errno 121) until :meth:`replug`."""
        self.plugged = False

    def replug(self, *, powered_off: bool = True) -> None:
        """Connect again; with ``powered_off`` (default) the registers are back at reset."""
        self.plugged = True
        if powered_off:
            self._reset()

    def power_cycle(self) -> None:
        """A brown-out: registers back at reset (powered down), still on the bus."""
        self._reset()

    def freeze(self) -> None:
        """Stop producing samples (a stuck sensor): outputs hold, data-ready stays clear."""
        self.frozen = True

    def thaw(self) -> None:
        """Produce samples again after :meth:`freeze`."""
        self.frozen = False

    # ----------------------------------------------------------------- inspection

    def register(self, address: int) -> int:
        """A register's value, without a transaction or its side effects."""
        return self.regs[address]

    @property
    def odr_code(self) -> int:
        """ODR_G, the code both sensors run at when the gyroscope is on (0: powered down)."""
        return (self.regs[chip.CTRL_REG1_G] & _ODR_MASK) >> chip.ODR_SHIFT

    @property
    def accel_odr_code(self) -> int:
        """ODR_XL (the accelerometer's rate when the gyroscope is off)."""
        return (self.regs[chip.CTRL_REG6_XL] & _ODR_MASK) >> chip.ODR_SHIFT

    def accel_g_per_lsb(self) -> float:
        """The accelerometer's sensitivity at the full scale FS_XL selects."""
        return _ACCEL_BY_CODE[(self.regs[chip.CTRL_REG6_XL] & _FS_MASK) >> chip.FS_SHIFT]

    def gyro_dps_per_lsb(self) -> float:
        """The gyroscope's sensitivity at the full scale FS_G selects."""
        code = (self.regs[chip.CTRL_REG1_G] & _FS_MASK) >> chip.FS_SHIFT
        return _GYRO_BY_CODE[chip.GYRO_SCALES[245][0] if code == _GYRO_NOT_AVAILABLE else code]

    # ----------------------------------------------------------------- the bus side

    def acknowledges(self) -> bool:
        """True while plugged in; a refused transaction is counted."""
        if not self.plugged:
            self.refused += 1
        return self.plugged

    def read(self, register: int, length: int) -> list[int]:
        """One read transaction: sample if running, then the registers (IF_ADD_INC honoured)."""
        self.transactions += 1
        self._sample()
        step = 1 if self.regs[chip.CTRL_REG8] & chip.IF_ADD_INC else 0
        addresses = [(register + k * step) & 0xFF for k in range(length)]
        data = [self.regs[a] for a in addresses]
        if any(a in _OUT_G for a in addresses):
            self._clear_status(chip.GDA)
        if any(a in _OUT_XL for a in addresses):
            self._clear_status(chip.XLDA)
        return data

    def write(self, register: int, value: int) -> None:
        """One write transaction; read-only and reserved registers ignore it."""
        self.transactions += 1
        if register not in _WRITABLE:
            return
        if register == chip.CTRL_REG8 and value & chip.SW_RESET:
            self._reset()  # SW_RESET clears itself with the rest
            return
        self.regs[register] = value

    # ----------------------------------------------------------------- internals

    def _reset(self) -> None:
        self.regs[:] = bytes(256)
        self.regs[chip.WHO_AM_I] = self.who_am_i
        self.regs[chip.CTRL_REG4] = chip.AXES_ENABLED
        self.regs[chip.CTRL_REG5_XL] = chip.AXES_ENABLED
        self.regs[chip.CTRL_REG8] = chip.CTRL_REG8_RESET
        self.resets += 1

    def _clear_status(self, bit: int) -> None:
        for address in (chip.STATUS_REG, _STATUS_MIRROR):
            self.regs[address] &= ~bit & 0xFF

    def _sample(self) -> None:
        if self.frozen:
            return
        gyro_on = self.odr_code != 0
        unread = self.regs[chip.STATUS_REG] & (chip.XLDA | (chip.GDA if gyro_on else 0))
        if unread:
            return  # the host has not read the last sample yet
        if gyro_on or self.accel_odr_code != 0:
            self._store(chip.OUT_X_L_XL, self.accel_g, self.accel_g_per_lsb())
            self._set_status(chip.XLDA)
        if gyro_on:
            self._store(chip.OUT_X_L_G, self.gyro_dps, self.gyro_dps_per_lsb())
            self._set_status(chip.GDA)

    def _set_status(self, bit: int) -> None:
        for address in (chip.STATUS_REG, _STATUS_MIRROR):
            self.regs[address] |= bit

    def _store(self, start: int, vector: Sequence[float], per_lsb: float) -> None:
        for axis, value in enumerate(vector):
            raw = quantise(value, per_lsb)
            self.regs[start + 2 * axis : start + 2 * axis + 2] = raw.to_bytes(
                2, "little", signed=True
            )


def lsm9ds1_bus(number: int, address: int) -> FakeSMBus:
    """A fake ``/dev/i2c-<number>`` with a fresh :class:`FakeLsm9ds1` at ``address``: the
    IMU where there is none (``imu.device = "fake"``, ``whexar doctor --imu fake``)."""
    bus = FakeSMBus(number)
    bus.attach(address, FakeLsm9ds1())
    return bus


def quantise(value: float, per_lsb: float) -> int:
    """The int16 output count for ``value`` at ``per_lsb`` units per count, saturating."""
    if math.isnan(value):
        raise ValueError("a fake sensor cannot sense NaN")
    if math.isinf(value):
        return 32767 if value > 0 else -32768
    return max(-32768, min(32767, round(value / per_lsb)))


__all__ = [
    "BLOCK_MAX",
    "EREMOTEIO",
    "I2C_BUS",
    "FakeI2CDevice",
    "FakeLsm9ds1",
    "FakeSMBus",
    "lsm9ds1_bus",
    "quantise",
]
