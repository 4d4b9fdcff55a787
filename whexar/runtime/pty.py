"""A pseudo-terminal that an emulator serves: the one way the device emulators open one.

The emulators behind a pty (:mod:`whexar.bus.emulator.pty`, :mod:`whexar.sensors.board_pty`)
serve its master side from a thread; a program opens :attr:`ServedPty.path` as it would
open the device's serial port. The slave stays open here, so the pty survives clients that
open and close it; it is raw, so that nothing is echoed or translated; the master does not
block; a pipe wakes the serving thread when the emulator closes.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import tty
from dataclasses import dataclass

__all__ = ["ServedPty"]


@dataclass(frozen=True, slots=True)
class ServedPty:
    """The file descriptors of a pty to serve, and the wake-up pipe of its server."""

    master: int
    slave: int
    path: str
    """The slave's device path: the port a client opens."""
    wake_r: int
    wake_w: int

    @classmethod
    def open(cls) -> ServedPty:
        """A new raw pty, its master non-blocking, and a wake-up pipe."""
        master, slave = os.openpty()
        tty.setraw(slave)
        flags = fcntl.fcntl(master, fcntl.F_GETFL)
        fcntl.fcntl(master, fcntl.F_SETFL, flags | os.O_NONBLOCK)
        wake_r, wake_w = os.pipe()
        return cls(master, slave, os.ttyname(slave), wake_r, wake_w)

    def wake(self) -> None:
        """Wake the serving thread (it waits on :attr:`wake_r` too)."""
        with contextlib.suppress(OSError):
            os.write(self.wake_w, b"x")

    def close(self) -> None:
        """Close every descriptor (those already closed are let be)."""
        for fd in (self.master, self.slave, self.wake_r, self.wake_w):
            with contextlib.suppress(OSError):
                os.close(fd)
