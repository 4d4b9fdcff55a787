"""Checks of the other devices: the IMU on the Pi's I²C bus (the sensor board's check is
:mod:`whexar.doctor.board`)."""

from __future__ import annotations

import contextlib
from typing import Final

from whexar.config import ImuSpec
from whexar.doctor.environment import Environment
from whexar.doctor.report import CheckResult, Findings, Status, fail, ok, skipped, warn
from whexar.errors import DeviceGoneError, WhexarError
from whexar.runtime.clock import monotonic, wait_until
from whexar.sensors import lsm9ds1 as chip
from whexar.sensors.lsm9ds1 import I2CBus

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
        rest = _at_rest(bus, spec.address, spec) if who == chip.WHO_AM_I_VALUE else None
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
    summary = f"LSM9DS1 answers at {where}"
    if rest is None:
        return ok(name, summary)
    accel, gyro = rest
    raw_a = tuple(a + o for a, o in zip(accel, spec.accel_offset_g, strict=True))
    raw_g = tuple(g + o for g, o in zip(gyro, spec.gyro_offset_dps, strict=True))
    level = (raw_a[0], raw_a[1], raw_a[2] - 1.0)
    details = (
        f"at rest, calibrated: {_xyz(accel, 'g', 3)}, {_xyz(gyro, 'dps', 2)}",
        f"on level ground its calibration would be: accel_offset_g = [{_list(level, 3)}], "
        f"gyro_offset_dps = [{_list(raw_g, 2)}]",
    )
    drift = max(abs(g) for g in gyro)
    if drift > GYRO_AT_REST_DPS:
        return warn(
            name,
            f"{summary}; its gyroscope reads {drift:.1f} dps at rest: not calibrated",
            "with the robot still, put the gyro_offset_dps above into [imu]",
            details,
        )
    return CheckResult(name, Status.OK, summary, None, details)


GYRO_AT_REST_DPS: Final = 3.0
"""A calibrated gyroscope at rest reads within this of zero; the LSM9DS1's uncalibrated
zero-rate level is typically ±30 dps (datasheet Table 3)."""
REST_SAMPLES: Final = 25
"""Samples averaged for the resting reading (half a second at the default 50 Hz)."""
REST_WAIT_S: Final = 2.0
"""Longest the resting reading waits for its samples (four times what 50 Hz needs)."""
POLL_S: Final = 0.005
"""Between two reads that found no new sample: a quarter of a 50 Hz period."""


def _at_rest(
    bus: I2CBus, address: int, spec: ImuSpec
) -> tuple[tuple[float, float, float], tuple[float, float, float]] | None:
    """The mean calibrated acceleration (g) and rate (dps) of :data:`REST_SAMPLES` new
    samples, ``None`` when the chip gave none (its configuration did not hold)."""
    driver = chip.Lsm9ds1(bus, address)
    try:
        driver.configure(spec.rate_hz, spec.accel_range_g, spec.gyro_range_dps)
    except WhexarError:
        return None
    calibration = chip.Calibration(spec.accel_offset_g, spec.gyro_offset_dps)
    got: list[chip.Reading] = []
    deadline = monotonic() + REST_WAIT_S
    while len(got) < REST_SAMPLES and monotonic() < deadline:
        reading = driver.read()
        if reading.new:
            got.append(calibration.apply(reading))
        else:
            wait_until(monotonic() + POLL_S)
    if not got:
        return None
    n = len(got)
    a = tuple(sum(r.accel_g[i] for r in got) / n for i in range(3))
    g = tuple(sum(r.gyro_dps[i] for r in got) / n for i in range(3))
    return (a[0], a[1], a[2]), (g[0], g[1], g[2])


def _xyz(v: tuple[float, ...], unit: str, digits: int) -> str:
    return "(" + ", ".join(f"{x:+.{digits}f}" for x in v) + f") {unit}"


def _list(v: tuple[float, ...], digits: int) -> str:
    return ", ".join(f"{x:.{digits}f}" for x in v)
