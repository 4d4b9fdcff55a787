"""``whexar doctor`` from the command line: one line per check, a fix under it, JSON."""

from __future__ import annotations

import json
import os
import selectors
import subprocess
import sys
from pathlib import Path

import pytest

from whexar.cli import main

ROOT = Path(__file__).resolve().parents[2]


def test_a_missing_port_is_one_line_not_a_traceback(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    assert main(["doctor", "--port", str(tmp_path / "ttyUSB9")]) == 1
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    lines = out.splitlines()
    assert lines[0].startswith("✗ servo port ")
    assert lines[0].endswith(
        f"{tmp_path / 'ttyUSB9'} does not exist: the U2D2 is not plugged in, or is another device"
    )
    assert lines[1].startswith("    fix: plug the U2D2 in")
    assert lines[2].startswith("- latency timer ")
    assert lines[-1] == "not ready"


def test_json_is_one_object(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["doctor", "--json", "--port", str(tmp_path / "ttyUSB9")]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc["ready"] is False
    first = doc["checks"][0]
    assert first["name"] == "servo port"
    assert first["status"] == "fail"
    assert {c["status"] for c in doc["checks"][1:6]} == {"skipped"}


DOCTOR = [sys.executable, "-m", "whexar.cli", "doctor", "--json", "--imu", "fake"]
"""The doctor with the emulated IMU, as a subprocess."""


def _emulate(*args: str) -> tuple[subprocess.Popen[str], dict[str, str]]:
    """``whexar emulate ARGS`` and the ptys its first lines name ("servo", "board")."""
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(
        [sys.executable, "-m", "whexar.cli", "emulate", *args],
        stdout=subprocess.PIPE,
        text=True,
        cwd=ROOT,
        env=env,
    )
    assert proc.stdout is not None
    ptys: dict[str, str] = {}
    with selectors.DefaultSelector() as sel:
        sel.register(proc.stdout, selectors.EVENT_READ)
        assert sel.select(20.0), "whexar emulate printed no pty"
    # The pty lines are printed together, first of all (the rest is buffered: no select).
    while len(ptys) < (2 if "--board" in args else 1):
        line = proc.stdout.readline()
        what = "board" if line.startswith("sensor board emulator:") else "servo"
        ptys[what] = line.split(" on ", 1)[1].split(" at ")[0]
    return proc, ptys


@pytest.mark.slow
@pytest.mark.serial  # the emulators on real time, the board's rate measured
def test_doctor_on_the_emulators_finds_the_robot_ready(tmp_path: Path) -> None:
    proc, ptys = _emulate("--no-realtime", "--board")
    try:
        done = subprocess.run(
            [*DOCTOR, "--port", ptys["servo"], "--board-port", ptys["board"]],
            capture_output=True,
            text=True,
            cwd=ROOT,
            env=dict(os.environ, PYTHONUNBUFFERED="1"),
            timeout=60,
        )
    finally:
        proc.kill()
        proc.wait()
    checks = {c["name"]: c for c in json.loads(done.stdout)["checks"]}
    assert checks["servo port"]["status"] == "ok"
    assert checks["latency timer"]["status"] == "skipped"  # a pty has none
    assert checks["baud rate"]["summary"] == "42 servos answer at 1000000 bps"
    assert checks["servos"]["status"] == "ok"
    # The emulator's wheels start in position mode, as a factory-fresh servo: start-up
    # writes velocity mode, so this is a warning, never a failure.
    assert checks["eeprom"]["status"] == "warn"
    assert checks["voltage and temperature"]["status"] == "ok"
    board = checks["sensor board"]
    assert board["status"] == "ok", board
    assert board["summary"].startswith(f"checked frames on {ptys['board']} at ")
    assert "(asked 20), IR and force sensors, no accelerometer" in board["summary"]
    assert checks["imu"]["status"] == "ok"  # the emulated LSM9DS1
    # Against the emulators every check passes or warns: the robot is ready.
    assert done.returncode == 0
    assert json.loads(done.stdout)["ready"] is True


@pytest.mark.slow
def test_a_board_port_where_nothing_answers_fails_and_names_the_fix(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    # A pty that nobody writes: a board that is plugged in but runs no firmware. (No servo
    # port: its checks fail at once instead of scanning every baud rate.)
    master, slave = os.openpty()
    try:
        board = os.ttyname(slave)
        code = main(["doctor", "--port", str(tmp_path / "ttyUSB9"), "--board-port", board])
    finally:
        os.close(master)
        os.close(slave)
    out = capsys.readouterr().out
    assert code == 1
    (line,) = [ln for ln in out.splitlines() if ln.startswith("✗ sensor board")]
    assert line.endswith("sent nothing in 3 s: the board's firmware is not running")
    fix = out.splitlines()[out.splitlines().index(line) + 1]
    assert fix.startswith("    fix: flash whexar's firmware")
