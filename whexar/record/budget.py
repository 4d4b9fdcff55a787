"""Recordings that never fill the disk: the recordings folder kept within a budget.

Theory of operation
-------------------
The budget (``[recording]``, :class:`~whexar.config.RecordingSpec`) bounds what the
recordings folder holds (``max_total_mb``), for how long (``max_age_days``), and the
free space every recording leaves on its disk (``min_free_mb``). :func:`plan` is the
policy, pure: given the folder's files (path, size, last change), the recording being
written, the budget, the free space and the wall time, it says which recordings to
delete and whether the one being written must stop. :class:`BudgetGuard` is its shell:
it reads the folder and the disk through a :class:`Disk`, deletes what the plan says,
and answers the recorder, which checks before it writes anything and then every
:data:`CHECK_PERIOD_S` of wall time while it records
(:meth:`whexar.record.writer.HandOver.run`); the recorder turns the answers into
:class:`~whexar.actors.messages.RecordingDeleted` and
:class:`~whexar.actors.messages.RecordingStopped` events.

Where the checks run: never in the control loop, since listing the folder and deleting
a large file take milliseconds (deleting a 100 MB file stalled the loop by 6.5 ms). A
recorder in a process of its own (:mod:`whexar.record.sidecar`, what ``whexar sim`` and
``whexar run`` record with) hands the guard's description (:meth:`BudgetGuard.describe`)
to that process, which keeps the budget and reports each :class:`Plan` that acts
(:meth:`Plan.to_json`); an in-process recorder (a live view, the tests) runs its checks
on a thread of their own (:class:`GuardThread`), its first before the file is made.

The rules, in order; every deletion takes the oldest first (by last change):

1. only recordings count and only they are ever deleted: ``*.mcap`` files directly in
   the folder (``whexar log recover`` writes its ``.recovered.mcap`` there too, a
   recording like the others; nothing else is written beside a recording), not hidden
   ones, not links, not subfolders;
2. never the recording being written, nor one changed within :data:`IN_USE_S`: it
   may be another run's, still open, and deleting an open file frees nothing until
   its writer closes it;
3. recordings older than ``max_age_days`` go;
4. then, while all recordings take more than ``max_total_mb``, the oldest go;
5. then, while the disk has less than ``min_free_mb`` free, the oldest go;
6. if that still leaves the folder over ``max_total_mb`` (the recording being written
   grew past it alone) or the disk under ``min_free_mb``, the recording stops.

The budget covers the recordings folder (:func:`recordings_folder`). A recording
written elsewhere (``--record FILE``) deletes nothing, but stops all the same when it
alone passes ``max_total_mb`` or its disk runs low.

Cost: a check reads the size of the recording being written and the
disk's free space, two system calls; the folder is listed at the start, and again only
when the budget is passed (it asks for deletions or a stop), before anything is done.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Collection, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final, Protocol

from whexar.runtime.clock import monotonic, wall_time

if TYPE_CHECKING:
    from whexar.config import RecordingSpec
    from whexar.runtime.messages import Message

__all__ = [
    "CHECK_PERIOD_S",
    "IN_USE_S",
    "RECORDINGS",
    "Budget",
    "BudgetGuard",
    "Deletion",
    "Disk",
    "FileInfo",
    "GuardThread",
    "LocalDisk",
    "Plan",
    "is_recording",
    "plan",
    "recordings_folder",
    "report_line",
]

RECORDINGS: Final = "recordings"
"""The folder runs are recorded into by default, relative to the working directory;
the environment variable ``WHEXAR_RECORDINGS`` names another."""
SUFFIX: Final = ".mcap"
CHECK_PERIOD_S: Final = 5.0
"""Wall seconds between two checks while recording: at the 0.24 MB a second of a
recorded course, 1.2 MB, far within any free space worth keeping."""
IN_USE_S: Final = 60.0
"""A recording changed within this many seconds may still be open (recorders write
every 0.5 s at the least): it is never deleted."""
MB: Final = 1_000_000
"""The budget's megabyte: 10⁶ bytes, as disks are sold."""
_DAY_S: Final = 86_400.0


def recordings_folder() -> Path:
    """The recordings folder: ``WHEXAR_RECORDINGS`` if set, else :data:`RECORDINGS`."""
    return Path(os.environ.get("WHEXAR_RECORDINGS") or RECORDINGS)


def report_line(event: Message) -> str | None:
    """One line for a person about a recorder's event (a deletion, a stop), else ``None``."""
    from whexar.actors.messages import RecordingDeleted, RecordingStopped

    if isinstance(event, RecordingDeleted):
        return f"recording: deleted {event.path} ({_mb(event.size_bytes)}): {event.reason}"
    if isinstance(event, RecordingStopped):
        return (
            f"recording stopped at t = {event.t:.1f} s, the run goes on: {event.reason} "
            f"({event.path} reads up to there)"
        )
    return None


# --------------------------------------------------------------------------- the policy


@dataclass(frozen=True, slots=True)
class FileInfo:
    """One file of the folder: its path, size in bytes and last change (wall s)."""

    path: Path
    size: int
    mtime: float


@dataclass(frozen=True, slots=True)
class Budget:
    """The limits of a recordings folder, in bytes and seconds; ``None``: no limit."""

    max_total_bytes: int | None = None
    max_age_s: float | None = None
    min_free_bytes: int | None = None

    @classmethod
    def from_spec(cls, spec: RecordingSpec) -> Budget:
        """The budget of a ``[recording]`` section (0 there: no limit)."""
        return cls(
            max_total_bytes=round(spec.max_total_mb * MB) or None,
            max_age_s=spec.max_age_days * _DAY_S or None,
            min_free_bytes=round(spec.min_free_mb * MB) or None,
        )

    @property
    def limited(self) -> bool:
        """Any limit at all."""
        return (self.max_total_bytes, self.max_age_s, self.min_free_bytes) != (None,) * 3


@dataclass(frozen=True, slots=True)
class Deletion:
    """A recording to delete, and why."""

    file: FileInfo
    reason: str


@dataclass(frozen=True, slots=True)
class Plan:
    """What keeps the folder within its budget: the recordings to delete (oldest
    first), and why the recording being written must stop (``None``: it goes on)."""

    deletions: tuple[Deletion, ...] = ()
    stop: str | None = None

    @property
    def acts(self) -> bool:
        """Something is to be done."""
        return bool(self.deletions) or self.stop is not None

    def to_json(self) -> dict[str, Any]:
        """The plan as JSON values (a recording process tells its runtime what it did)."""
        return {
            "deletions": [
                [str(d.file.path), d.file.size, d.file.mtime, d.reason] for d in self.deletions
            ],
            "stop": self.stop,
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Plan:
        """The plan :meth:`to_json` made."""
        deletions = tuple(
            Deletion(FileInfo(Path(path), int(size), float(mtime)), str(reason))
            for path, size, mtime, reason in data["deletions"]
        )
        stop = data["stop"]
        return cls(deletions, None if stop is None else str(stop))


def is_recording(path: Path) -> bool:
    """A whexar recording by its name: ``*.mcap``, not hidden."""
    return path.suffix == SUFFIX and not path.name.startswith(".")


def _mb(size: float) -> str:
    return f"{size / MB:.1f} MB"


def plan(
    files: Sequence[FileInfo],
    current: Path | None,
    budget: Budget,
    free_bytes: int | None,
    now: float,
    keep: Collection[Path] = (),
) -> Plan:
    """What keeps the folder of ``files`` within ``budget`` (the module's rules).

    ``current`` is the recording being written (among ``files`` once it exists),
    ``free_bytes`` the disk's free space (``None``: unknown, no free-space rule),
    ``now`` the wall time files are stamped in, ``keep`` files that must stay (a
    deletion that failed). No I/O.
    """
    recordings = [f for f in files if is_recording(f.path) or f.path == current]
    deletable = sorted(
        (
            f
            for f in recordings
            if f.path != current and f.path not in keep and now - f.mtime >= IN_USE_S
        ),
        key=lambda f: (f.mtime, str(f.path)),
    )
    deletions: list[Deletion] = []
    left = deletable
    if budget.max_age_s is not None:
        days = budget.max_age_s / _DAY_S
        # Oldest first: the old ones are a prefix.
        old = next((k for k, f in enumerate(deletable) if now - f.mtime <= budget.max_age_s), None)
        left = deletable[len(deletable) if old is None else old :]
        for f in deletable[: len(deletable) - len(left)]:
            age = (now - f.mtime) / _DAY_S
            why = f"{age:.1f} days old, older than [recording] max_age_days = {days:g}"
            deletions.append(Deletion(f, why))
    freed = sum(d.file.size for d in deletions)
    total = sum(f.size for f in recordings) - freed
    free = None if free_bytes is None else free_bytes + freed
    limit, least = budget.max_total_bytes, budget.min_free_bytes
    for f in left:  # then the oldest, while over the total or short of free space
        if limit is not None and total > limit:
            why = (
                f"the recordings take {_mb(total)}, over [recording] max_total_mb = {limit / MB:g}"
            )
        elif free is not None and least is not None and free < least:
            why = f"{_mb(free)} free on the disk, under [recording] min_free_mb = {least / MB:g}"
        else:
            break
        deletions.append(Deletion(f, why))
        total -= f.size
        if free is not None:
            free += f.size
    stop = None
    if limit is not None and total > limit:
        alone = total == next((f.size for f in recordings if f.path == current), None)
        what = "this recording alone takes" if alone else "the recordings take"
        stop = (
            f"{what} {_mb(total)}, over [recording] max_total_mb = {limit / MB:g}, "
            "with nothing older left to delete"
        )
    elif free is not None and least is not None and free < least:
        stop = (
            f"{_mb(free)} free on the disk, under [recording] min_free_mb = {least / MB:g}, "
            "with nothing older left to delete"
        )
    return Plan(tuple(deletions), stop)


# --------------------------------------------------------------------------- the shell


class Disk(Protocol):
    """What :class:`BudgetGuard` reads and changes on the disk (a test's fake, or
    :class:`LocalDisk`)."""

    def listing(self, folder: Path) -> list[FileInfo]:
        """Every regular file directly in ``folder`` (links not followed)."""
        ...

    def size(self, path: Path) -> int:
        """The size of ``path`` in bytes (0 if it is not there)."""
        ...

    def free_bytes(self, folder: Path) -> int | None:
        """The space free to the user on ``folder``'s disk (``None``: unknown)."""
        ...

    def remove(self, path: Path) -> None:
        """Delete ``path``; raises :class:`OSError`."""
        ...

    def now(self) -> float:
        """The wall time files are stamped in (seconds since the epoch)."""
        ...


class LocalDisk:
    """The machine's own file system."""

    def listing(self, folder: Path) -> list[FileInfo]:
        """Every regular file directly in ``folder`` (none if it cannot be read)."""
        found = []
        with contextlib.suppress(OSError), os.scandir(folder) as entries:
            for entry in entries:
                with contextlib.suppress(OSError):  # gone meanwhile
                    if entry.is_file(follow_symlinks=False):
                        st = entry.stat(follow_symlinks=False)
                        found.append(FileInfo(Path(folder, entry.name), st.st_size, st.st_mtime))
        return found

    def size(self, path: Path) -> int:
        """The size of ``path`` (0 if it is not there)."""
        try:
            return os.stat(path).st_size
        except OSError:
            return 0

    def free_bytes(self, folder: Path) -> int | None:
        """``statvfs``: the blocks free to an unprivileged user."""
        try:
            st = os.statvfs(folder)
        except OSError:
            return None
        return st.f_bavail * st.f_frsize

    def remove(self, path: Path) -> None:
        """``unlink``."""
        os.unlink(path)

    def now(self) -> float:
        """The wall clock (:func:`whexar.runtime.clock.wall_time`)."""
        return wall_time()


class BudgetGuard:
    """Keeps the folder of recording ``path`` within ``budget`` (see the module).

    ``folder`` is the recordings folder the budget covers, ``None`` for a recording
    written elsewhere (nothing is deleted then; the recording alone counts).
    :meth:`check` reads, deletes and answers; :meth:`due` says when the next check is,
    every ``period_s`` of wall time.
    """

    def __init__(
        self,
        budget: Budget,
        path: str | os.PathLike[str],
        folder: Path | None,
        *,
        disk: Disk | None = None,
        period_s: float = CHECK_PERIOD_S,
    ) -> None:
        self.budget = budget
        # Absolute, as the listing names files: the recording being written must be
        # recognised among them whatever the caller's spelling.
        self.path = Path(os.path.abspath(path))
        self.folder = None if folder is None else Path(os.path.abspath(folder))
        self.disk: Disk = disk if disk is not None else LocalDisk()
        self.period_s = period_s
        self._others: list[FileInfo] | None = None
        """The folder's other files at the last listing (they do not grow; this one does)."""
        self._total = 0
        """What the other recordings take, at the last listing."""
        self._oldest = float("inf")
        """The last change of the oldest other recording, at the last listing."""
        self._undeletable: set[Path] = set()
        self._last = -float("inf")

    def due(self) -> bool:
        """A check is due (``period_s`` of wall time since the last)."""
        return monotonic() - self._last >= self.period_s

    def describe(self) -> dict[str, Any]:
        """What makes this guard again elsewhere (:meth:`described`), as JSON values: a
        recording process keeps the budget of its recording on the local disk."""
        if not isinstance(self.disk, LocalDisk):
            raise TypeError("only a guard of the local disk can be described")
        b = self.budget
        return {
            "budget": [b.max_total_bytes, b.max_age_s, b.min_free_bytes],
            "path": str(self.path),
            "folder": None if self.folder is None else str(self.folder),
            "period_s": self.period_s,
        }

    @classmethod
    def described(cls, data: dict[str, Any]) -> BudgetGuard:
        """The guard :meth:`describe` described, on the local disk."""
        total, age, free = data["budget"]
        folder = data["folder"]
        return cls(
            Budget(total, age, free),
            data["path"],
            None if folder is None else Path(folder),
            period_s=float(data["period_s"]),
        )

    def check(self) -> Plan:
        """Keep the budget now: delete what :func:`plan` says (deletions that fail are
        left out, and kept from then on) and return what was deleted and whether the
        recording must stop."""
        self._last = monotonic()
        disk = self.disk
        where = self.folder if self.folder is not None else self.path.parent
        listed = self._others is None
        if listed:
            self._list()
        while True:
            now = disk.now()
            current = FileInfo(self.path, disk.size(self.path), now)
            free = disk.free_bytes(where)
            if self._fits(current.size, free, now):
                return Plan()  # the steady state: no walk over the folder's files
            assert self._others is not None
            found = plan(
                [*self._others, current], self.path, self.budget, free, now, self._undeletable
            )
            if not found.acts or listed:
                break
            self._list()  # the budget is passed: decide on what is there now
            listed = True
        done = []
        for deletion in found.deletions:
            try:
                disk.remove(deletion.file.path)
            except FileNotFoundError:
                pass  # gone meanwhile: as good as deleted, but not by us
            except OSError:
                self._undeletable.add(deletion.file.path)
                continue
            else:
                done.append(deletion)
            self._forget(deletion.file.path)
        if len(done) == len(found.deletions):
            return Plan(tuple(done), found.stop)
        # Some could not be deleted: decide again without them (they stay kept).
        again = self.check()
        return Plan((*done, *again.deletions), again.stop)

    def _fits(self, size: int, free: int | None, now: float) -> bool:
        """Within every limit, by the last listing's figures: nothing for :func:`plan`
        to do (a quick look, not a decision; when in doubt, :func:`plan` decides)."""
        b = self.budget
        return (
            (b.max_total_bytes is None or self._total + size <= b.max_total_bytes)
            and (b.min_free_bytes is None or free is None or free >= b.min_free_bytes)
            and (b.max_age_s is None or now - self._oldest <= b.max_age_s)
        )

    def _list(self) -> None:
        files = self.disk.listing(self.folder) if self.folder is not None else []
        self._others = [f for f in files if f.path != self.path]
        self._forget(None)

    def _forget(self, path: Path | None) -> None:
        """``path`` gone from the folder (``None``: none); the other recordings' figures."""
        assert self._others is not None
        self._others = [f for f in self._others if f.path != path]
        recordings = [f for f in self._others if is_recording(f.path)]
        self._total = sum(f.size for f in recordings)
        self._oldest = min((f.mtime for f in recordings), default=float("inf"))


class GuardThread:
    """Runs a :class:`BudgetGuard`'s checks on a thread of their own, for a recorder in
    the runtime's process: :meth:`poll`, called between control cycles, never waits on
    the disk. Listing and deleting are system calls that let go of the interpreter
    lock; deciding (:func:`plan`, 2–4 ms for 1,000 recordings) holds it, and may delay
    the event loop by up to the interpreter's switch interval (5 ms) each time the
    budget is passed."""

    def __init__(self, guard: BudgetGuard) -> None:
        self.guard = guard
        self._pool: ThreadPoolExecutor | None = None
        self._running: Future[Plan] | None = None
        self._stopped = False

    def poll(self) -> list[Plan]:
        """The plans of the checks done since the last call; starts the next check when
        one is due (none after a plan that stops the recording). Raises what a check
        raised."""
        found: list[Plan] = []
        running = self._running
        if running is not None:
            if not running.done():
                return found
            self._running = None
            found.append(running.result())
            self._stopped = found[-1].stop is not None
        if not self._stopped and self.guard.due():
            if self._pool is None:
                self._pool = ThreadPoolExecutor(1, thread_name_prefix="whexar-budget")
            self._running = self._pool.submit(self.guard.check)
        return found

    def finish(self) -> list[Plan]:
        """Wait for the check under way, if any, and end the thread; its plan."""
        running, self._running = self._running, None
        self._stopped = True
        found = [] if running is None else [running.result()]
        if self._pool is not None:
            self._pool.shutdown(wait=True)
        return found
