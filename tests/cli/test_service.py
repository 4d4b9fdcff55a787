"""``whexar run`` under a fake systemd, and ``whexar service``.

The run test starts a real ``python -m whexar.cli run`` of the servo bus graph (the
emulator, real time) with ``$NOTIFY_SOCKET`` naming a datagram socket of the test and
``$WATCHDOG_USEC`` set, as systemd does for ``Type=notify`` and ``WatchdogSec=``.
"""

from __future__ import annotations

import itertools
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from whexar.cli import main

ROOT = Path(__file__).resolve().parents[2]
BUS = ROOT / "config" / "graphs" / "bus.toml"
WATCHDOG_S = 2.0
"""The period the fake systemd asks for: feeds are due every half of it."""


@pytest.mark.slow
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
    # Never faster than half the period (the client's rule); well within the period
    # (systemd's), with room for a busy machine. Times are when the test read them.
    gaps = [b - a for (a, _), (b, _) in itertools.pairwise(got[:4])]
    assert all(WATCHDOG_S / 2 - 0.05 <= gap < WATCHDOG_S for gap in gaps), gaps
    assert proc.returncode == 0, err.decode()
    assert "stopped: signal SIGTERM" in out.decode()


def test_run_outside_systemd_sends_nothing_and_runs_as_before(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("NOTIFY_SOCKET", raising=False)
    demo = ROOT / "config" / "graphs" / "demo.toml"
    assert main(["run", str(demo), "--virtual", "--duration", "1", "--no-record"]) == 0
    assert "stopped: duration 1 s elapsed" in capsys.readouterr().out
