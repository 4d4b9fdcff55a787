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


@pytest.mark.slow
def test_doctor_on_the_emulators_finds_the_robot_ready(tmp_path: Path) -> None:
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(
        [sys.executable, "-m", "whexar.cli", "emulate", "--no-realtime"],
        stdout=subprocess.PIPE,
        text=True,
        cwd=ROOT,
        env=env,
    )
    try:
        assert proc.stdout is not None
        with selectors.DefaultSelector() as sel:
            sel.register(proc.stdout, selectors.EVENT_READ)
            assert sel.select(20.0), "whexar emulate printed nothing"
        first = proc.stdout.readline()
        path = first.split(" on ", 1)[1].split(" at ")[0]
        done = subprocess.run(
            [*DOCTOR, "--port", path],
            capture_output=True,
            text=True,
            cwd=ROOT,
            env=env,
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
    assert checks["imu"]["status"] == "ok"  # the emulated LSM9DS1
    # Against the emulators every check passes or warns: the robot is ready.
    assert done.returncode == 0
    assert json.loads(done.stdout)["ready"] is True
