"""The doctor's sensor-board check against :class:`FakeBoard`, broken in every way.

The board speaks ``firmware/PROTOCOL.md``'s bytes on a fake clock; the real firmware in
simavr is checked in ``tests/sensors/test_firmware_e2e.py`` and the emulated board on a
pty in ``tests/doctor/test_cli.py``.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from whexar.config import RobotConfig, parse_config
from whexar.doctor import CheckResult, Environment, Findings, Status
from whexar.doctor.board import FIRST_FRAME_S, MEASURE_S, check_sensor_board
from whexar.testing.board import FakeBoard, FakeBoardPort


@pytest.fixture
def port(tmp_path: Path) -> Path:
    path = tmp_path / "ttyACM0"
    path.touch()
    return path


def env_for(port: Path, board: FakeBoard, config: RobotConfig | None = None) -> Environment:
    return Environment(
        config=config or RobotConfig(),
        board_port=str(port),
        access=lambda path, mode: True,
        open_board_port=board.open,
        now=board.clock.now,
    )


def check(port: Path, board: FakeBoard, config: RobotConfig | None = None) -> CheckResult:
    found = Findings()
    result = check_sensor_board(env_for(port, board, config), found)
    for close in found.closers:
        close()
    return result


def with_board(**values: object) -> RobotConfig:
    return parse_config({"sensor_board": values})


def test_whexars_firmware_at_the_asked_rate_passes(port: Path) -> None:
    board = FakeBoard()
    got = check(port, board, with_board(frame_rate_hz=50))
    assert got.status is Status.OK, got
    assert got.summary.startswith(f"checked frames on {port} at 50.0 Hz (asked 50)")
    assert "IR and force sensors, no accelerometer" in got.summary
    assert board.commands == [b"rate=50#"]
    assert board.opened == [1_000_000]
    # The first frame after the boot, one to take the rate, then the measurement.
    assert board.clock.t == pytest.approx(1.0 + MEASURE_S + 3 / 20, abs=0.05)
    assert got.details[0] == "last frame: ir1=80 ir2=80, fsr 0,12,230,251,0,198"


def test_a_missing_port_names_the_setting(tmp_path: Path) -> None:
    got = check(tmp_path / "ttyACM9", FakeBoard())
    assert got.status is Status.FAIL
    assert "does not exist: the sensor board is not plugged in" in got.summary
    assert got.fix is not None
    assert "--board-port DEVICE or set [sensor_board] port" in got.fix


def test_a_port_of_another_group_says_usermod(port: Path) -> None:
    env = replace(
        env_for(port, FakeBoard()),
        access=lambda path, mode: False,
        device_gid=lambda path: 20,
        group_name=lambda gid: {20: "dialout", 1000: "robot"}[gid],
        process_groups=lambda: [1000],
        user_groups=lambda: ["robot"],
    )
    got = check_sensor_board(env, Findings())
    assert got.status is Status.FAIL
    assert got.name == "sensor board"
    assert got.fix == "sudo usermod -aG dialout $USER, then log out and in again"


def test_a_port_that_cannot_open_says_why(port: Path) -> None:
    def refuse(name: str, baudrate: int) -> FakeBoardPort:
        raise OSError(16, "Device or resource busy")

    got = check_sensor_board(
        replace(env_for(port, FakeBoard()), open_board_port=refuse), Findings()
    )
    assert got.status is Status.FAIL
    assert got.summary == f"cannot open {port}: Device or resource busy (EBUSY)"


def test_a_silent_board_says_flash_the_firmware(port: Path) -> None:
    board = FakeBoard(silent=True)
    got = check(port, board)
    assert got.status is Status.FAIL
    assert (
        got.summary
        == f"{port} sent nothing in {FIRST_FRAME_S:g} s: the board's firmware is not running"
    )
    assert got.fix is not None
    assert got.fix.startswith("flash whexar's firmware")
    assert board.clock.t == pytest.approx(FIRST_FRAME_S, abs=0.05)


def test_another_baud_rate_is_found_and_named(port: Path) -> None:
    board = FakeBoard(baudrate=500_000)
    got = check(port, board)
    assert got.status is Status.FAIL
    assert "bytes but no frame at 1000000 bps; its frames decode at 500000 bps" in got.summary
    assert got.fix is not None
    assert got.fix.startswith("set [sensor_board] baudrate = 500000")
    assert board.opened == [1_000_000, 76_800, 250_000, 500_000]


def test_garbage_at_every_rate_is_not_whexars_firmware(port: Path) -> None:
    board = FakeBoard(baudrate=115_200)  # not a rate the firmware can run at
    got = check(port, board)
    assert got.status is Status.FAIL
    assert "but no frame at any of 76800, 250000, 500000, 1000000, 2000000 bps" in got.summary
    assert len(board.opened) == 5


def test_plain_thesis_frames_fail_the_checked_protocol(port: Path) -> None:
    got = check(port, FakeBoard(plain=True))
    assert got.status is Status.FAIL
    assert "the thesis's plain frames (no seq, no crc)" in got.summary
    assert got.fix is not None
    assert 'set [sensor_board] protocol = "thesis"' in got.fix


def test_plain_thesis_frames_pass_the_thesis_protocol(port: Path) -> None:
    got = check(port, FakeBoard(plain=True), with_board(protocol="thesis"))
    assert got.status is Status.OK, got
    assert got.summary.startswith("plain frames")


def test_frames_without_force_sensors_are_not_whexars(port: Path) -> None:
    got = check(port, FakeBoard(fsr=False))
    assert got.status is Status.FAIL
    assert "carry no fsr0…fsr5" in got.summary


def test_a_board_deaf_to_the_rate_command_fails(port: Path) -> None:
    got = check(port, FakeBoard(rate_hz=10, obeys_rate=False))
    assert got.status is Status.FAIL
    assert "sends 10.0 frames/s after rate=20#" in got.summary


def test_corrupted_frames_are_a_warning_with_counts(port: Path) -> None:
    got = check(port, FakeBoard(corrupt_every=5))
    assert got.status is Status.WARN
    assert "frames lost and 6 rejected" in got.summary
    assert got.fix is not None
    assert "USB cable" in got.fix


def test_an_unplugged_rangefinder_is_a_warning(port: Path) -> None:
    got = check(port, FakeBoard(ir=(0, 80)))
    assert got.status is Status.WARN
    assert "ir1 (rangefinder on the right front leg) reads 0 counts" in got.summary


def test_an_accelerometer_mismatch_is_a_warning_both_ways(port: Path) -> None:
    sent = check(port, FakeBoard(accelerometer=True))
    assert sent.status is Status.WARN
    assert "fitted = false: the reader makes no tilt of them" in sent.summary
    missing = check(port, FakeBoard(), with_board(accelerometer={"fitted": True}))
    assert missing.status is Status.WARN
    assert "fitted = true, but the frames carry no acc*" in missing.summary
    both = check(port, FakeBoard(accelerometer=True), with_board(accelerometer={"fitted": True}))
    assert both.status is Status.OK
    assert "force sensors, accelerometer" in both.summary
