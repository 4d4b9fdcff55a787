"""Fakes of the recording tests: a disk that fills up, and a folder with a free space of
its own (importable by a recording process, which opens its file with
:func:`disk_of_100k`)."""

from __future__ import annotations

import errno
import io
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from whexar.record.budget import FileInfo

if TYPE_CHECKING:
    from _typeshed import ReadableBuffer

ENOSPC = OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


class FullDisk(io.FileIO):
    """A file on a disk with room for ``room`` bytes of it: a write past them writes what
    fits and says so (a short write), the next raises ``OSError(ENOSPC)``, as a real disk
    does; cutting the file back frees the room again."""

    def __init__(self, path: str | os.PathLike[str], room: int) -> None:
        super().__init__(path, "wb")
        self.room = room
        self.refused = 0
        """Writes refused for want of space."""

    def write(self, data: ReadableBuffer) -> int:
        view = memoryview(data).cast("B")
        fits = max(0, self.room - self.tell())
        if view.nbytes and not fits:
            self.refused += 1
            raise OSError(ENOSPC.errno, ENOSPC.strerror)
        return super().write(view[:fits])


def disk_of_100k(path: Path) -> FullDisk:
    """The opener a recording process is given (``tests.record.fakes:disk_of_100k``)."""
    return FullDisk(path, 100_000)


@dataclass
class FakeDisk:
    """A :class:`~whexar.record.budget.Disk` of files by path (size, last change), with
    ``free`` bytes free and the wall time ``now``; ``stuck`` files cannot be deleted."""

    files: dict[Path, tuple[int, float]] = field(default_factory=dict)
    free: int | None = 10**12
    now_s: float = 1e9
    stuck: set[Path] = field(default_factory=set)
    removed: list[Path] = field(default_factory=list)
    listings: int = 0

    def add(self, path: Path, size: int, age_s: float) -> Path:
        self.files[path] = (size, self.now_s - age_s)
        return path

    def listing(self, folder: Path) -> list[FileInfo]:
        self.listings += 1
        return [FileInfo(p, s, m) for p, (s, m) in self.files.items() if p.parent == folder]

    def size(self, path: Path) -> int:
        return self.files.get(path, (0, 0.0))[0]

    def free_bytes(self, folder: Path) -> int | None:
        return self.free

    def remove(self, path: Path) -> None:
        if path in self.stuck:
            raise PermissionError(errno.EACCES, "Permission denied", str(path))
        size, _ = self.files.pop(path)
        self.removed.append(path)
        if self.free is not None:
            self.free += size

    def now(self) -> float:
        return self.now_s
