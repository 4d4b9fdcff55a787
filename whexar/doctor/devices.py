"""Checks of the other devices: the IMU on the Pi's I²C bus.

The sensor board (protocol and frame rate over its serial line) has no check yet.
"""

from __future__ import annotations

import contextlib

from whexar.doctor.environment import Environment
from whexar.doctor.report import CheckResult, Findings, fail, ok, skipped
from whexar.errors import DeviceGoneError
from whexar.sensors import lsm9ds1 as chip

EREMOTEIO = 121
"""Linux's errno when nothing acknowledges an I²C address ("Remote I/O error")."""
ENABLE_I2C = "sudo raspi-config nonint do_i2c 0, then reboot (or dtparam=i2c_arm=on in config.txt)"


def check_imu(env: Environment, found: Findings) -> CheckResult:
    """The LSM9DS1 answers at ``[imu] address`` on ``/dev/i2c-<[imu] i2c_bus>`` with its
    WHO_AM_I (0x68, datasheet §7.11)."""
    name = "imu"
    spec = env.config.imu
    if not spec.enabled:
        return skipped(name, "[imu] enabled = false")
    where = f"0x{spec.address:02X} on /dev/i2c-{spec.i2c_bus}"
    try:
        bus = env.open_i2c(spec.i2c_bus)
    except DeviceGoneError as exc:
        return fail(name, str(exc), ENABLE_I2C)
    except OSError as exc:
        return fail(name, f"cannot open /dev/i2c-{spec.i2c_bus}: {exc}", ENABLE_I2C)
    try:
        who = bus.read_byte_data(spec.address, chip.WHO_AM_I)
    except OSError as exc:
        if exc.errno == EREMOTEIO:
            other = chip.ADDRESS_ALT if spec.address == chip.ADDRESS else chip.ADDRESS
            return fail(
                name,
                f"nothing answers at {where}",
                f"check the IMU's wiring and supply (3.3 V); with SDO_AG low it is at "
                f"0x{other:02X}: set [imu] address; list the bus with: i2cdetect -y "
                f"{spec.i2c_bus}",
            )
        return fail(name, f"{where}: {exc}", None)
    finally:
        with contextlib.suppress(Exception):
            bus.close()
    if who != chip.WHO_AM_I_VALUE:
        return fail(
            name,
            f"the device at {where} says WHO_AM_I 0x{who:02X}, an LSM9DS1 says "
            f"0x{chip.WHO_AM_I_VALUE:02X}: another chip is at that address",
            f"set [imu] address to the LSM9DS1's (i2cdetect -y {spec.i2c_bus} lists what answers)",
        )
    return ok(name, f"LSM9DS1 answers at {where}")
