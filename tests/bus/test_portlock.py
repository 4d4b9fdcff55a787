"""One owner per servo port: a second process is refused with the holder's PID."""

from __future__ import annotations

import os
import pty
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from whexar.bus.portlock import PortLock, lock_path
from whexar.bus.sdk import open_port
from whexar.errors import DeviceUnavailableError, PortUnavailableError

HOLD = """
import sys, time
from pathlib import Path
from whexar.bus.portlock import PortLock
from whexar.bus.sdk import open_port
if sys.argv[2] == "-":
    port = open_port(sys.argv[1], 1_000_000)
else:
    lock = PortLock.take(sys.argv[1], Path(sys.argv[2]))
print("held", flush=True)
time.sleep(30)
"""


def _holder(port: str, folder: str) -> subprocess.Popen[str]:
    proc = subprocess.Popen(
        [sys.executable, "-c", HOLD, port, folder], stdout=subprocess.PIPE, text=True
    )
    assert proc.stdout is not None
    assert proc.stdout.readline().strip() == "held"
    return proc


@pytest.fixture
def pty_port() -> Iterator[str]:
    master, slave = pty.openpty()
    yield os.ttyname(slave)
    os.close(master)
    os.close(slave)


def test_a_second_process_is_refused_with_the_holders_pid(tmp_path: Path) -> None:
    proc = _holder("/dev/ttyUSB0", str(tmp_path))
    try:
        with pytest.raises(PortUnavailableError) as err:
            PortLock.take("/dev/ttyUSB0", tmp_path)
        assert f"process {proc.pid} has it" in str(err.value)
        assert isinstance(err.value, DeviceUnavailableError)  # no restart helps
    finally:
        proc.kill()
        proc.wait()
    # The holder gone, however it ended, the port is free again.
    PortLock.take("/dev/ttyUSB0", tmp_path).release()


def test_one_process_is_one_owner(tmp_path: Path) -> None:
    first = PortLock.take("/dev/ttyUSB0", tmp_path)
    second = PortLock.take("/dev/ttyUSB0", tmp_path)  # a restart before the close
    assert not first.held
    assert second.held
    second.release()
    assert lock_path("/dev/ttyUSB0", tmp_path).read_text() == ""


def test_open_port_holds_the_port_until_it_is_closed(pty_port: str) -> None:
    proc = _holder(pty_port, "-")
    try:
        with pytest.raises(PortUnavailableError, match=f"busy: process {proc.pid}"):
            open_port(pty_port, 1_000_000)
    finally:
        proc.kill()
        proc.wait()
    port = open_port(pty_port, 1_000_000)
    assert port.lock is not None
    assert port.lock.held
    lock = port.lock
    port.closePort()
    assert not lock.held
