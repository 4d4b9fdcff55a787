"""A servo port that cannot be opened at start: one line naming it and the fix."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import pytest

from whexar.bus import sdk
from whexar.bus.sdk import UNAVAILABLE, open_port
from whexar.errors import DeviceGoneError, DeviceUnavailableError, PortUnavailableError


def test_a_missing_port_is_unavailable_and_names_the_doctor(tmp_path: Path) -> None:
    missing = str(tmp_path / "ttyUSB7")
    with pytest.raises(PortUnavailableError) as err:
        open_port(missing, 1_000_000)
    text = str(err.value)
    assert text.startswith(f"servo port {missing}: no such device")
    assert f"whexar doctor --port {missing}" in text
    # Still a gone device for the code that catches those, and no restart for the runtime.
    assert isinstance(err.value, DeviceGoneError)
    assert isinstance(err.value, DeviceUnavailableError)


@pytest.mark.parametrize(
    ("code", "says"),
    [(errno.EACCES, "permission denied"), (errno.EBUSY, "busy: another program has it open")],
)
def test_a_port_not_permitted_or_busy_is_unavailable(
    monkeypatch: pytest.MonkeyPatch, code: int, says: str
) -> None:
    # As pyserial raises them (SerialException is an OSError with the open's errno).
    def refuse(self: object) -> bool:
        raise OSError(code, os.strerror(code))

    monkeypatch.setattr(sdk.WaitingPortHandler, "openPort", refuse)
    with pytest.raises(PortUnavailableError, match=says):
        open_port("/dev/ttyUSB0", 1_000_000)


def test_what_each_errno_says() -> None:
    assert "plugged in" in UNAVAILABLE[errno.ENOENT]
    assert "dialout" in UNAVAILABLE[errno.EACCES]
    assert "another program" in UNAVAILABLE[errno.EBUSY]


def test_another_failure_to_open_stays_a_gone_device(tmp_path: Path) -> None:
    # A plain file is no serial port: a failure, but not one of the unavailable kinds.
    plain = tmp_path / "not-a-tty"
    plain.write_text("")
    with pytest.raises(DeviceGoneError) as err:
        open_port(str(plain), 1_000_000)
    assert not isinstance(err.value, DeviceUnavailableError)
