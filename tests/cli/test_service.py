"""``whexar run`` under a fake systemd, and ``whexar service``.

The run test starts a real ``python -m whexar.cli run`` of the servo bus graph (the
emulator, real time) with ``$NOTIFY_SOCKET`` naming a datagram socket of the test and
``$WATCHDOG_USEC`` set, as systemd does for ``Type=notify`` and ``WatchdogSec=``.
"""

from __future__ import annotations

import itertools
import os
import pwd
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from whexar.cli import main, service
from whexar.cli.service import UNIT

ROOT = Path(__file__).resolve().parents[2]
BUS = ROOT / "config" / "graphs" / "bus.toml"
WATCHDOG_S = 2.0
"""The period the fake systemd asks for: feeds are due every half of it."""


@pytest.mark.slow
@pytest.mark.serial  # the watchdog's feeds timed on the wall clock
def test_run_says_ready_feeds_the_watchdog_and_says_stopping_on_sigterm() -> None:
    with tempfile.TemporaryDirectory(prefix="sdn") as folder:  # AF_UNIX paths are short
        path = os.path.join(folder, "notify")
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        sock.bind(path)
        env = dict(os.environ, NOTIFY_SOCKET=path, WATCHDOG_USEC=str(int(WATCHDOG_S * 1e6)))
        proc = subprocess.Popen(
            [sys.executable, "-m", "whexar.cli", "run", str(BUS), "--no-record", "--quiet"],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        got: list[tuple[float, str]] = []
        try:
            sock.settimeout(30.0)  # start-up on a busy machine; a hang fails here
            while sum(text == "WATCHDOG=1" for _, text in got) < 3:
                got.append((time.monotonic(), sock.recv(4096).decode()))
            proc.send_signal(signal.SIGTERM)
            got.append((time.monotonic(), sock.recv(4096).decode()))
            out, err = proc.communicate(timeout=30)
        finally:
            proc.kill()
            sock.close()
    texts = [text for _, text in got]
    assert texts[0] == "READY=1\nSTATUS=running: 4 actors ready"
    assert texts[1:4] == ["WATCHDOG=1"] * 3
    assert texts[4] == "STOPPING=1\nSTATUS=stopping: signal SIGTERM"
    # Within the period (systemd's rule), and not a stream. Times are when the test read
    # them, so on a busy machine a late read shortens the next gap: the half-period rule
    # itself is tested on virtual time (tests/runtime/test_notify.py).
    gaps = [b - a for (a, _), (b, _) in itertools.pairwise(got[1:4])]
    assert all(WATCHDOG_S / 4 <= gap < WATCHDOG_S for gap in gaps), gaps
    assert proc.returncode == 0, err.decode()
    assert "stopped: signal SIGTERM" in out.decode()


def test_run_outside_systemd_sends_nothing_and_runs_as_before(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("NOTIFY_SOCKET", raising=False)
    demo = ROOT / "config" / "graphs" / "demo.toml"
    assert main(["run", str(demo), "--virtual", "--duration", "1", "--no-record"]) == 0
    assert "stopped: duration 1 s elapsed" in capsys.readouterr().out


# --------------------------------------------------------------------------- whexar service


def me() -> str:
    return pwd.getpwuid(os.getuid()).pw_name


def test_install_writes_the_unit_for_this_install(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    dest = tmp_path / "units"
    code = main(
        ["service", "install", str(BUS), "--dest", str(dest), "--user", me(),
         "--set", "bus.port=/dev/ttyUSB0"]
    )  # fmt: skip
    assert code == 0
    unit = (dest / UNIT).read_text()
    lines = unit.splitlines()
    exec_start = next(line for line in lines if line.startswith("ExecStart="))
    assert shlex.split(exec_start.removeprefix("ExecStart=")) == [
        sys.executable, "-m", "whexar.cli", "run", str(BUS), "--set", "bus.port=/dev/ttyUSB0"
    ]  # fmt: skip
    for setting in (
        "Type=notify",
        "NotifyAccess=main",
        "WatchdogSec=2",
        "Restart=on-failure",
        "RestartPreventExitStatus=1 2 4",
        "StartLimitBurst=3",
        "KillSignal=SIGTERM",
        f"User={me()}",
        f"WorkingDirectory={Path.cwd()}",
    ):
        assert setting in lines, setting
    assert "@" not in "".join(line for line in lines if not line.startswith("#"))
    # Four actors of 1 s each, the safe stop's too: longer than the run's own bound.
    assert "TimeoutStopSec=20" in lines
    out = capsys.readouterr().out
    assert "sudo systemctl enable --now whexar.service" in out


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="no systemd-analyze")
def test_the_installed_unit_is_one_systemd_accepts(tmp_path: Path) -> None:
    assert main(["service", "install", str(BUS), "--dest", str(tmp_path), "--user", me()]) == 0
    check = subprocess.run(
        ["systemd-analyze", "verify", str(tmp_path / UNIT)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert check.returncode == 0, check.stderr
    assert "ignoring" not in check.stderr, check.stderr  # an unknown key is only a warning


def test_install_refuses_a_malformed_set_and_a_missing_graph(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["service", "install", str(BUS), "--dest", str(tmp_path), "--set", "port"])
    assert exc.value.code == 2
    assert main(["service", "install", str(tmp_path / "nope.toml"), "--dest", str(tmp_path)]) == 1
    assert "nope.toml" in capsys.readouterr().err
    assert not (tmp_path / UNIT).exists()


def test_status_and_logs_say_so_where_systemd_is_absent(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("PATH", str(tmp_path))  # no systemctl, no journalctl
    assert main(["service", "status"]) == 1
    assert main(["service", "logs"]) == 1
    err = capsys.readouterr().err.splitlines()
    assert err == [
        "whexar: systemd is absent here (no systemctl on PATH)",
        "whexar: systemd is absent here (no journalctl on PATH)",
    ]


def test_status_says_so_where_systemd_is_not_the_init_system(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    for tool in ("systemctl", "journalctl"):  # present, but systemd not running
        fake = tmp_path / tool
        fake.write_text("#!/bin/sh\nexit 0\n")
        fake.chmod(0o755)
    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.setattr(service, "SYSTEMD_BOOTED", tmp_path / "no-such-folder")
    assert main(["service", "status"]) == 1
    assert "systemd is not running here" in capsys.readouterr().err
    monkeypatch.setattr(service, "SYSTEMD_BOOTED", tmp_path)
    assert main(["service", "status"]) == 0  # the fake systemctl's answer, passed on


def test_install_passes_a_checked_configuration_on(tmp_path: Path) -> None:
    dest = tmp_path / "units"
    config = tmp_path / "robot.toml"
    config.write_text("[imu]\naccel_offset_g = [0.01, 0.0, 0.0]\n")
    args = ["service", "install", str(BUS), "--dest", str(dest), "--user", me()]
    assert main([*args, "--config", str(config)]) == 0
    exec_start = next(
        line for line in (dest / UNIT).read_text().splitlines() if line.startswith("ExecStart=")
    )
    words = shlex.split(exec_start.removeprefix("ExecStart="))
    assert words[words.index("--config") + 1] == str(config.resolve())
    config.write_text("[imu]\naccel_offset_g = [0.0, 0.0, 0.5]\n")
    (dest / UNIT).unlink()
    assert main([*args, "--config", str(config)]) == 1  # named now, not at the next boot
    assert not (dest / UNIT).exists()
