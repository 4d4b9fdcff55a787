"""One owner per servo port: a lock that names the process holding it.

Two programs on one half-duplex bus interleave their packets and both read
garbage; a second ``whexar run`` (a service started twice, a test run beside the
service) must be refused before it writes a byte. A serial port has no owner
the kernel reports, so :class:`PortLock` takes an ``flock`` on a lock file named
after the port's real path (``/dev/serial/by-id/…`` and ``/dev/ttyUSB0`` are
one port) in ``/run/lock``, the folder the FHS gives device locks (else the
temporary folder), and writes its PID into it. The kernel drops the lock when
the process ends, however it ends: a stale file never blocks.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import tempfile
from pathlib import Path
from typing import Final

from whexar.errors import PortUnavailableError

LOCK_DIRS: Final = (Path("/run/lock"), Path(tempfile.gettempdir()))
"""Where the lock files go: the first that can be written (FHS 3.0, 5.9 ``/run/lock``)."""


_HELD: dict[Path, PortLock] = {}
"""The locks this process holds, by lock file."""


def lock_path(port: str, folder: Path | None = None) -> Path:
    """The lock file of ``port`` (by its real path) in ``folder`` or the first usable."""
    real = os.path.realpath(port)
    name = "whexar-" + real.strip("/").replace("/", "_") + ".lock"
    if folder is None:
        folder = next((d for d in LOCK_DIRS if os.access(d, os.W_OK)), LOCK_DIRS[-1])
    return folder / name


class PortLock:
    """This process's hold on a servo port (see the module docstring)."""

    def __init__(self, port: str, path: Path, fd: int) -> None:
        self.port = port
        self.path = path
        self._fd: int | None = fd

    @classmethod
    def take(cls, port: str, folder: Path | None = None) -> PortLock:
        """Hold ``port``; :class:`PortUnavailableError` naming the holder's PID if another
        process has it."""
        path = lock_path(port, folder)
        mine = _HELD.pop(path, None)
        if mine is not None:
            # This process already holds it: an earlier opening that was not closed (an
            # actor that failed before closing its port, then restarted). One process is
            # one owner; the lock is for other processes.
            mine.release()
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "unknown"
            os.close(fd)
            raise PortUnavailableError(
                f"servo port {port}: busy: process {holder} has it (its lock {path}); "
                f"stop that one first (systemctl stop whexar, if it is the service)"
            ) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        lock = cls(port, path, fd)
        _HELD[path] = lock
        return lock

    @property
    def held(self) -> bool:
        """Whether this lock still holds its port."""
        return self._fd is not None

    def release(self) -> None:
        """Let the port go (the file stays: removing it would race the next taker)."""
        if self._fd is None:
            return
        fd, self._fd = self._fd, None
        if _HELD.get(self.path) is self:
            del _HELD[self.path]
        with contextlib.suppress(OSError):
            os.ftruncate(fd, 0)
        os.close(fd)  # closing drops the flock


__all__ = ["LOCK_DIRS", "PortLock", "lock_path"]
