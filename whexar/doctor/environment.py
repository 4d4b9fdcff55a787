"""Everything the checks touch, in one injected object: the real machine by default,
a fake sysfs tree, a fake group database, an emulated servo port, a fake I²C bus in tests."""

from __future__ import annotations

import grp
import os
import shutil
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from whexar.bus import wire
from whexar.config import RobotConfig
from whexar.runtime.clock import monotonic
from whexar.sensors.lsm9ds1 import I2CBus


class BoardPort(Protocol):
    """The sensor board's serial port as the check uses it (a ``serial.Serial``)."""

    def read(self, size: int) -> bytes:
        """Up to ``size`` bytes, or fewer (none) once the port's read timeout passes."""
        ...

    def write(self, data: bytes) -> int | None: ...

    def reset_input_buffer(self) -> None: ...

    def close(self) -> None: ...


BOARD_READ_TIMEOUT_S = 0.02
"""A read of the board's port returns after this with what arrived (a frame is 2 ms long)."""


def _open_board_port(name: str, baudrate: int) -> BoardPort:
    import serial

    try:
        return serial.Serial(name, baudrate, timeout=BOARD_READ_TIMEOUT_S)
    except serial.SerialException as exc:
        cause = exc.__context__
        raise cause if isinstance(cause, OSError) else OSError(str(exc)) from exc


def _open_servo_port(name: str, baudrate: int) -> Any:
    from whexar.bus.sdk import open_port

    return open_port(name, baudrate)


def _open_i2c(number: int) -> I2CBus:
    from whexar.actors.sensing.imu import open_bus

    return open_bus(number)


def _group_name(gid: int) -> str:
    try:
        return grp.getgrgid(gid).gr_name
    except KeyError:
        return str(gid)


def _free_bytes(path: Path) -> int:
    # The folder may not exist yet: the recorder makes it; its disk is its parent's.
    while not path.exists() and path != path.parent:
        path = path.parent
    return shutil.disk_usage(path).free


def _version(package: str) -> str | None:
    from importlib import metadata

    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return None


def _requirements() -> Sequence[str]:
    from importlib import metadata

    try:
        return metadata.requires("whexar") or ()
    except metadata.PackageNotFoundError:
        return ()


def _recordings() -> Path:
    from whexar.record.budget import recordings_folder

    return recordings_folder()


UDEV_RULES_DIRS = (
    Path("/etc/udev/rules.d"),
    Path("/lib/udev/rules.d"),
    Path("/usr/lib/udev/rules.d"),
)
"""Where udev looks for rules (udev(7)); the shipped rule belongs in the first."""


@dataclass(slots=True)
class Environment:
    """The machine as the checks see it; every field can be replaced by a test."""

    config: RobotConfig = field(default_factory=RobotConfig)
    port: str | None = None
    """The servo port; ``None``: the configuration's ``[bus] port``."""
    sysfs: Path = Path("/sys")
    udev_rules_dirs: Sequence[Path] = UDEV_RULES_DIRS
    access: Callable[[Path, int], bool] = os.access
    """``os.access``: whether this process may read and write a device."""
    device_gid: Callable[[Path], int] = lambda path: path.stat().st_gid
    group_name: Callable[[int], str] = _group_name
    process_groups: Callable[[], Sequence[int]] = os.getgroups
    """The groups this process runs with (a group joined since login is not among them)."""
    user_groups: Callable[[], Sequence[str]] = field(default=lambda: _user_groups())
    """The groups the user belongs to in the group database (joined, maybe not yet active)."""
    open_servo_port: Callable[[str, int], Any] = _open_servo_port
    """Open the servo port at a rate; raises ``DeviceGoneError`` or ``OSError``."""
    board_port: str | None = None
    """The sensor board's port; ``None``: the configuration's ``[sensor_board] port``."""
    open_board_port: Callable[[str, int], BoardPort] = _open_board_port
    """Open the board's port at a rate, reads returning after a short timeout; raises
    ``OSError``."""
    now: Callable[[], float] = monotonic
    """Seconds, for the checks that time what a device sends (the board's frame rate)."""
    open_i2c: Callable[[int], I2CBus] = _open_i2c
    recordings: Callable[[], Path] = _recordings
    free_bytes: Callable[[Path], int] = _free_bytes
    python_version: tuple[int, ...] = tuple(sys.version_info[:3])
    version: Callable[[str], str | None] = _version
    """The installed version of a distribution, ``None`` when it is not installed."""
    requirements: Callable[[], Sequence[str]] = _requirements
    """whexar's requirements as its metadata lists them (``"dynamixel-sdk>=4.1"``)."""
    native_bus: Callable[[], str] = wire.why_not
    """Why the compiled bus path (:mod:`whexar.bus.wire`) is not loaded; empty when it is."""

    @property
    def servo_port(self) -> str:
        """The servo port the checks use."""
        return self.port if self.port is not None else self.config.bus.port

    @property
    def board_port_name(self) -> str:
        """The sensor board's port the checks use."""
        return self.board_port if self.board_port is not None else self.config.sensor_board.port


def _user_groups() -> list[str]:
    import getpass

    user = getpass.getuser()
    names = [g.gr_name for g in grp.getgrall() if user in g.gr_mem]
    try:
        import pwd

        names.append(_group_name(pwd.getpwnam(user).pw_gid))
    except KeyError:
        pass
    return names
