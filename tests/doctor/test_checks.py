"""``whexar doctor``'s checks, each against its fake, and each fake broken in turn.

The servo checks talk to the servo emulator's chain through dynamixel-sdk's own
packet handler (an in-process :class:`EmulatedPort`); the latency timer reads a fake
sysfs tree; the sensor board is :class:`~whexar.testing.board.FakeBoard` on a fake
clock (``tests/doctor/test_board.py`` breaks it in every way); the IMU is the fake
LSM9DS1 on a fake I²C bus.
"""

from __future__ import annotations

import errno
import os
from collections.abc import Callable, Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from whexar.bus.emulator.chain import ServoChain
from whexar.bus.emulator.port import EmulatedPort
from whexar.config import RobotConfig, parse_config
from whexar.doctor import CheckResult, Environment, Status, ready, run_checks
from whexar.doctor.host import INSTALL_RULE, UDEV_RULE
from whexar.errors import DeviceGoneError
from whexar.sensors.imu_emulator import FakeLsm9ds1, FakeSMBus
from whexar.testing.board import FakeBoard

CFG = RobotConfig()
WHEELS = [leg.servo_ids[-1] for leg in CFG.legs]


def chain(models: Mapping[int, str] | None = None, *, baudrate: int = 1_000_000) -> ServoChain:
    """WHexaR's servos as start-up leaves them (Return Delay Time and wheel mode set)."""
    c = ServoChain.for_models(
        CFG.servos() if models is None else models,
        baudrate=baudrate,
        return_delay_us=CFG.bus.return_delay_time_us,
    )
    for sid in WHEELS:
        if sid in c.servos:
            c.servos[sid].set_register("operating_mode", 1)
    return c


def opener(c: ServoChain) -> Callable[[str, int], Any]:
    def open_port(name: str, baudrate: int) -> Any:
        port = EmulatedPort(c)
        assert port.setBaudRate(baudrate)
        return port

    return open_port


def fake_imu(who_am_i: int = 0x68, address: int = 0x6B) -> FakeSMBus:
    bus = FakeSMBus(1)
    bus.attach(address, FakeLsm9ds1(who_am_i=who_am_i))
    return bus


@pytest.fixture
def env(tmp_path: Path) -> Environment:
    """Every fake as a ready robot has it."""
    port = tmp_path / "dev" / "ttyUSB0"
    port.parent.mkdir()
    port.touch()
    timer = tmp_path / "sys" / "bus" / "usb-serial" / "devices" / "ttyUSB0" / "latency_timer"
    timer.parent.mkdir(parents=True)
    timer.write_text("1\n")
    rules = tmp_path / "udev"
    rules.mkdir()
    (rules / UDEV_RULE).write_text("")
    board = tmp_path / "dev" / "ttyACM0"
    board.touch()
    servos = chain()
    fake_board = FakeBoard()
    return Environment(
        config=CFG,
        port=str(port),
        sysfs=tmp_path / "sys",
        udev_rules_dirs=(rules,),
        access=lambda path, mode: True,
        device_gid=lambda path: 20,
        group_name=lambda gid: {20: "dialout", 1000: "robot"}[gid],
        process_groups=lambda: [1000, 20],
        user_groups=lambda: ["robot", "dialout"],
        open_servo_port=opener(servos),
        board_port=str(board),
        open_board_port=fake_board.open,
        now=fake_board.clock.now,
        open_i2c=lambda number: fake_imu(),
        recordings=lambda: tmp_path / "recordings",
        free_bytes=lambda path: 5_000_000_000,
        python_version=(3, 11, 7),
        version=lambda name: {"whexar": "0.1.0", "dynamixel-sdk": "4.1.2"}.get(name),
        requirements=lambda: ["dynamixel-sdk>=4.1", 'mujoco>=3.3; extra == "sim"'],
        native_bus=lambda: "",
    )


def results(env: Environment) -> dict[str, CheckResult]:
    return {r.name: r for r in run_checks(env)}


def with_chain(env: Environment, c: ServoChain) -> Environment:
    return replace(env, open_servo_port=opener(c))


def test_a_ready_robot_passes_every_check(env: Environment) -> None:
    got = run_checks(env)
    assert [r.name for r in got] == [
        "servo port",
        "latency timer",
        "baud rate",
        "servos",
        "eeprom",
        "voltage and temperature",
        "sensor board",
        "imu",
        "free disk",
        "versions",
    ]
    assert {r.name: r.status for r in got} == {r.name: Status.OK for r in got}, got
    assert ready(got)
    assert all(r.fix is None for r in got)


# ------------------------------------------------------------------ the port


def test_a_missing_port_fails_and_skips_the_servo_checks(env: Environment, tmp_path: Path) -> None:
    got = results(replace(env, port=str(tmp_path / "dev" / "ttyUSB1")))
    assert got["servo port"].status is Status.FAIL
    assert "does not exist" in got["servo port"].summary
    assert got["servo port"].fix
    assert "--port" in got["servo port"].fix
    for name in ("latency timer", "baud rate", "servos", "eeprom", "voltage and temperature"):
        assert got[name].status is Status.SKIPPED, name
    assert "servo port check, which failed" in got["baud rate"].summary
    assert "baud rate check, which was skipped" in got["servos"].summary
    # The checks that do not need the port still run.
    assert got["imu"].status is Status.OK
    assert not ready(list(got.values()))


def test_a_port_of_a_group_the_user_is_not_in_says_usermod(env: Environment) -> None:
    got = results(
        replace(
            env,
            access=lambda path, mode: False,
            process_groups=lambda: [1000],
            user_groups=lambda: ["robot"],
        )
    )
    assert got["servo port"].status is Status.FAIL
    assert "'dialout'" in got["servo port"].summary
    assert got["servo port"].fix == "sudo usermod -aG dialout $USER, then log out and in again"
    assert got["baud rate"].status is Status.SKIPPED


def test_a_group_joined_since_login_says_log_in_again(env: Environment) -> None:
    got = results(replace(env, access=lambda path, mode: False, process_groups=lambda: [1000]))
    assert got["servo port"].status is Status.FAIL
    assert got["servo port"].fix is not None
    assert "newgrp dialout" in got["servo port"].fix


def test_the_access_asked_is_read_and_write(env: Environment) -> None:
    asked: list[int] = []

    def access(path: Path, mode: int) -> bool:
        asked.append(mode)
        return True

    results(replace(env, access=access))
    assert asked == [os.R_OK | os.W_OK] * 2  # the servo port, the board's


# ------------------------------------------------------------------ latency timer


def _timer(env: Environment) -> Path:
    return env.sysfs / "bus" / "usb-serial" / "devices" / "ttyUSB0" / "latency_timer"


def test_a_16_ms_latency_timer_without_the_rule_says_install_it(env: Environment) -> None:
    _timer(env).write_text("16\n")
    got = results(replace(env, udev_rules_dirs=()))["latency timer"]
    assert got.status is Status.FAIL
    assert "16 ms on ttyUSB0 (want 1 ms)" in got.summary
    assert got.fix is not None
    assert got.fix.startswith(INSTALL_RULE)
    assert "echo 1 | sudo tee /sys/bus/usb-serial/devices/ttyUSB0/latency_timer" in got.fix


def test_a_16_ms_latency_timer_with_the_rule_says_replug(env: Environment) -> None:
    _timer(env).write_text("16\n")
    got = results(env)["latency timer"]
    assert got.status is Status.FAIL
    assert got.fix is not None
    assert got.fix.startswith("unplug and replug the adapter")


def test_1_ms_without_the_rule_is_a_warning(env: Environment) -> None:
    got = results(replace(env, udev_rules_dirs=()))
    assert got["latency timer"].status is Status.WARN
    assert got["latency timer"].fix == INSTALL_RULE
    assert ready(list(got.values()))


def test_a_port_with_no_latency_timer_is_skipped(env: Environment) -> None:
    _timer(env).unlink()
    got = results(env)
    assert got["latency timer"].status is Status.SKIPPED
    assert got["baud rate"].status is Status.OK


# ------------------------------------------------------------------ the bus


def test_servos_at_another_rate_are_found_and_named(env: Environment) -> None:
    got = results(with_chain(env, chain(baudrate=57_600)))
    assert got["baud rate"].status is Status.FAIL
    assert got["baud rate"].summary == ("no servo answers at 1000000 bps; 42 answer at 57600 bps")
    assert got["baud rate"].fix is not None
    assert got["baud rate"].fix.startswith("set [bus] baudrate = 57600, or set every servo's")
    for name in ("servos", "eeprom", "voltage and temperature"):
        assert got[name].status is Status.SKIPPED


def test_a_silent_bus_fails(env: Environment) -> None:
    got = results(with_chain(env, chain({})))
    assert got["baud rate"].status is Status.FAIL
    assert "at any rate" in got["baud rate"].summary


def test_a_port_that_cannot_be_opened_fails_in_one_line(env: Environment) -> None:
    def refuse(name: str, baudrate: int) -> Any:
        raise DeviceGoneError(f"servo port {name}: could not open it")

    got = results(replace(env, open_servo_port=refuse))["baud rate"]
    assert got.status is Status.FAIL
    assert got.summary.endswith("could not open it")


def test_the_port_is_closed_after_the_checks(env: Environment) -> None:
    ports: list[EmulatedPort] = []
    inner = env.open_servo_port

    def keep(name: str, baudrate: int) -> Any:
        ports.append(inner(name, baudrate))
        return ports[-1]

    results(replace(env, open_servo_port=keep))
    assert len(ports) == 1
    assert not ports[0].is_open


def test_a_missing_servo_fails_naming_it(env: Environment) -> None:
    models: dict[int, str] = dict(CFG.servos())
    del models[5]
    got = results(with_chain(env, chain(models)))
    assert got["baud rate"].status is Status.OK
    assert got["servos"].status is Status.FAIL
    assert got["servos"].details == (f"servo 5 ({CFG.servos()[5]}) does not answer",)
    assert "1 of 42 missing" in got["servos"].summary
    # The others' EEPROM and supply are still checked.
    assert got["eeprom"].status is Status.OK
    assert "41 servos" in got["eeprom"].summary


def test_a_servo_of_another_model_fails(env: Environment) -> None:
    models: dict[int, str] = dict(CFG.servos())
    assert models[1] != "MX-28"
    models[1] = "MX-28"
    got = results(with_chain(env, chain(models)))
    assert got["servos"].status is Status.FAIL
    assert got["servos"].details == (
        f"servo 1 is an MX-28; the configuration says {CFG.servos()[1]}",
    )
    assert got["eeprom"].summary.endswith("41 servos agrees with the configuration")


def test_a_servo_not_in_the_configuration_fails(env: Environment) -> None:
    models: dict[int, str] = {**CFG.servos(), 100: "MX-28"}
    got = results(with_chain(env, chain(models)))
    assert got["servos"].status is Status.FAIL
    assert got["servos"].details == ("servo 100 (MX-28) answers but is not in the configuration",)


def test_a_servo_at_the_wrong_id_is_named_with_its_fix(env: Environment) -> None:
    models: dict[int, str] = dict(CFG.servos())
    models[100] = models.pop(5)
    got = results(with_chain(env, chain(models)))
    assert got["servos"].status is Status.FAIL
    assert got["servos"].fix is not None
    assert got["servos"].fix.startswith(
        "servo 100 is likely servo 5 with the wrong ID: set its ID (7) to 5"
    )


def test_an_old_firmware_is_a_warning(env: Environment) -> None:
    c = chain()
    c.servos[3].table[6] = 40
    got = results(with_chain(env, c))
    assert got["servos"].status is Status.WARN
    assert got["servos"].details == (f"servo 3 ({CFG.servos()[3]}): firmware v40",)


def test_a_hardware_error_fails(env: Environment) -> None:
    c = chain()
    c.servos[9].table[70] = 0x20
    got = results(with_chain(env, c))
    assert got["servos"].status is Status.FAIL
    assert got["servos"].details == ("servo 9: hardware error overload",)


# ------------------------------------------------------------------ EEPROM


def test_a_reversed_drive_mode_fails(env: Environment) -> None:
    c = chain()
    c.servos[2].set_register("drive_mode", 1)
    got = results(with_chain(env, c))["eeprom"]
    assert got.status is Status.FAIL
    assert got.details[0].startswith("servo 2: Drive Mode (10) is 1, whexar needs 0")


def test_position_limits_narrower_than_the_joints_fail(env: Environment) -> None:
    c = chain()
    c.servos[4].set_register("min_position_limit", 1500)
    got = results(with_chain(env, c))["eeprom"]
    assert got.status is Status.FAIL
    assert got.details[0].startswith("servo 4: position limits 1500–4095 (48, 52) refuse goals")


def test_the_wheels_position_limits_do_not_matter(env: Environment) -> None:
    c = chain()
    c.servos[WHEELS[0]].set_register("max_position_limit", 2100)
    assert results(with_chain(env, c))["eeprom"].status is Status.OK


def test_voltage_limits_that_exclude_the_supply_fail(env: Environment) -> None:
    c = chain()
    c.servos[6].set_register("max_voltage_limit", 110)
    got = results(with_chain(env, c))["eeprom"]
    assert got.status is Status.FAIL
    assert got.details == ("servo 6: voltage limits 9.5–11.0 V (32, 34) exclude the 12.0 V supply",)


def test_settings_start_up_writes_are_a_warning(env: Environment) -> None:
    c = chain()
    c.servos[8].set_register("return_delay_time", 250)
    c.servos[WHEELS[1]].set_register("operating_mode", 3)
    got = results(with_chain(env, c))
    assert got["eeprom"].status is Status.WARN
    assert got["eeprom"].details == (
        "servo 8: Return Delay Time (9) 250, configured 10",
        f"servo {WHEELS[1]}: Operating Mode (11) 3, needs 1",
    )
    assert ready(list(got.values()))


# ------------------------------------------------------------------ supply and heat


def test_a_low_supply_fails(env: Environment) -> None:
    c = chain()
    c.servos[10].input_voltage_v = 9.0
    got = results(with_chain(env, c))["voltage and temperature"]
    assert got.status is Status.FAIL
    assert got.details == ("servo 10: 9.0 V, outside its limits 9.5–16.0 V",)


def test_a_sagging_supply_is_a_warning(env: Environment) -> None:
    c = chain()
    c.servos[10].input_voltage_v = 10.5
    got = results(with_chain(env, c))["voltage and temperature"]
    assert got.status is Status.WARN
    assert got.details == ("servo 10: 10.5 V, the supply is 12.0 V",)


def test_a_servo_at_its_temperature_limit_fails_and_near_it_warns(env: Environment) -> None:
    c = chain()
    c.servos[11].temperature_c = 80
    c.servos[12].temperature_c = 72
    got = results(with_chain(env, c))["voltage and temperature"]
    assert got.status is Status.FAIL
    assert got.details == (
        "servo 11: 80 °C, at its limit 80 °C",
        "servo 12: 72 °C, near its limit 80 °C",
    )


# ------------------------------------------------------------------ IMU


def test_no_imu_on_the_bus_fails(env: Environment) -> None:
    got = results(replace(env, open_i2c=lambda n: fake_imu(address=0x6A)))["imu"]
    assert got.status is Status.FAIL
    assert got.summary == "nothing answers at 0x6B on /dev/i2c-1"
    assert got.fix is not None
    assert "0x6A" in got.fix
    assert "i2cdetect -y 1" in got.fix


def test_another_chip_at_the_imus_address_fails(env: Environment) -> None:
    got = results(replace(env, open_i2c=lambda n: fake_imu(who_am_i=0x3D)))["imu"]
    assert got.status is Status.FAIL
    assert "WHO_AM_I 0x3D" in got.summary


def test_no_i2c_bus_fails_with_how_to_enable_it(env: Environment) -> None:
    def absent(number: int) -> Any:
        raise DeviceGoneError(f"cannot open /dev/i2c-{number}: no such file")

    got = results(replace(env, open_i2c=absent))["imu"]
    assert got.status is Status.FAIL
    assert got.fix is not None
    assert got.fix.startswith("sudo raspi-config nonint do_i2c 0")


def _imu_reading(accel_g: tuple[float, float, float], gyro_dps: tuple[float, float, float]) -> Any:
    bus = FakeSMBus(1)
    bus.attach(0x6B, FakeLsm9ds1(accel_g=accel_g, gyro_dps=gyro_dps))
    return bus


def test_the_imu_at_rest_gives_its_calibration(env: Environment) -> None:
    # An uncalibrated chip, 50 mg off in X and 30 mg in Z, still: the line to put in [imu].
    got = results(replace(env, open_i2c=lambda n: _imu_reading((0.05, 0.0, 1.03), (0, 0, 0))))
    imu = got["imu"]
    assert imu.status is Status.OK
    assert "accel_offset_g = [0.050, 0.000, 0.030]" in imu.details[1]
    # Calibrated by the configuration, the same chip reads level.
    cfg = parse_config({"imu": {"accel_offset_g": [0.05, 0.0, 0.03]}})
    calibrated = results(
        replace(env, config=cfg, open_i2c=lambda n: _imu_reading((0.05, 0.0, 1.03), (0, 0, 0)))
    )["imu"]
    assert "(+0.000, +0.000, +1.000) g" in calibrated.details[0]
    assert "accel_offset_g = [0.050, 0.000, 0.030]" in calibrated.details[1]


def test_a_gyroscope_that_turns_at_rest_is_a_warning(env: Environment) -> None:
    got = results(replace(env, open_i2c=lambda n: _imu_reading((0, 0, 1), (25.0, -3.0, 1.0))))
    imu = got["imu"]
    assert imu.status is Status.WARN
    assert "25.0 dps at rest" in imu.summary
    assert "gyro_offset_dps = [25.00, -3.00, 1.00]" in imu.details[1]
    assert ready(list(got.values()))  # a warning: the robot can still run


def test_a_disabled_imu_is_skipped(env: Environment) -> None:
    cfg = parse_config({"imu": {"enabled": False}})
    got = results(replace(env, config=cfg, open_i2c=lambda n: fake_imu(address=0x6A)))
    assert got["imu"].status is Status.SKIPPED
    assert ready(list(got.values()))


# ------------------------------------------------------------------ disk, versions


def test_too_little_free_disk_fails(env: Environment) -> None:
    got = results(replace(env, free_bytes=lambda path: 900_000_000))["free disk"]
    assert got.status is Status.FAIL
    assert "900 MB free" in got.summary
    assert "1000 MB" in got.summary


def test_the_free_disk_follows_min_free_mb(env: Environment) -> None:
    cfg = parse_config({"recording": {"min_free_mb": 800}})
    got = results(replace(env, config=cfg, free_bytes=lambda path: 900_000_000))
    assert got["free disk"].status is Status.OK


def test_an_old_python_fails(env: Environment) -> None:
    got = results(replace(env, python_version=(3, 10, 12)))["versions"]
    assert got.status is Status.FAIL
    assert got.summary == "Python 3.10.12; whexar needs 3.11 or newer"


def test_a_missing_or_old_package_fails(env: Environment) -> None:
    got = results(
        replace(
            env,
            requirements=lambda: ["dynamixel-sdk>=4.1", "smbus2>=0.4"],
            version=lambda name: {"dynamixel-sdk": "3.7.31"}.get(name),
        )
    )["versions"]
    assert got.status is Status.FAIL
    assert got.details == ("dynamixel-sdk 3.7.31 is older than 4.1", "smbus2 is not installed")


def test_a_bus_without_its_compiled_path_warns(env: Environment) -> None:
    got = results(replace(env, native_bus=lambda: "the compiled bus path is not built"))
    versions = got["versions"]
    assert versions.status is Status.WARN
    assert "python3-dev" in (versions.fix or "")
    assert versions.details == ("the compiled bus path is not built",)


def test_the_installed_packages_satisfy_the_real_requirements() -> None:
    got = results(Environment(port="/nonexistent/port"))["versions"]
    assert got.status is Status.OK, got


def test_a_port_that_fails_midway_fails_the_check(env: Environment) -> None:
    c = chain()
    c.faults.unplugged = True
    got = results(with_chain(env, c))["baud rate"]
    assert got.status is Status.FAIL
    assert errno.errorcode[errno.EIO] in got.summary
