"""The recordings' budget: the policy case by case and as a property, the guard on a fake
disk, the ``[recording]`` section, and a recorder that keeps the budget while it records
(deleting older recordings, then stopping, each an event) while the run goes on."""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import anyio
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tests.record.fakes import FakeDisk
from whexar.actors.messages import RecordingDeleted, RecordingStopped
from whexar.cli import main
from whexar.config import RecordingSpec, RobotConfig, parse_config
from whexar.errors import ConfigError
from whexar.record.budget import (
    IN_USE_S,
    MB,
    Budget,
    BudgetGuard,
    FileInfo,
    GuardThread,
    LocalDisk,
    Plan,
    plan,
    recordings_folder,
    report_line,
)
from whexar.record.encoding import RecordingError
from whexar.record.reader import Recording
from whexar.record.writer import Recorder
from whexar.runtime.clock import monotonic, wait_until
from whexar.runtime.messages import Heartbeat
from whexar.runtime.wiring import EVENTS_CHANNEL

if TYPE_CHECKING:
    from whexar.record.sidecar import RecorderProcess

NOW = 1_700_000_000.0
DAY = 86_400.0
DIR = Path("/r")
CURRENT = DIR / "now.mcap"


def _file(name: str, size_mb: float, age_s: float) -> FileInfo:
    return FileInfo(DIR / name, round(size_mb * MB), NOW - age_s)


def _names(found: object) -> list[str]:
    return [d.file.path.name for d in getattr(found, "deletions", ())]


# --------------------------------------------------------------------------- the policy


def test_within_budget_nothing_is_done() -> None:
    files = [_file("a.mcap", 10, 3 * DAY), _file("now.mcap", 1, 0)]
    found = plan(files, CURRENT, Budget(100 * MB, 30 * DAY, 10 * MB), 50 * MB, NOW)
    assert not found.acts
    assert plan(files, CURRENT, Budget(), 0, NOW) == found  # no limits at all


def test_recordings_past_the_age_go_and_younger_ones_stay() -> None:
    files = [
        _file("old.mcap", 1, 40 * DAY),
        _file("older.mcap", 1, 90 * DAY),
        _file("young.mcap", 1, 29 * DAY),
        _file("now.mcap", 1, 0),
    ]
    found = plan(files, CURRENT, Budget(max_age_s=30 * DAY), None, NOW)
    assert _names(found) == ["older.mcap", "old.mcap"]  # oldest first
    assert found.stop is None
    assert "90.0 days old, older than [recording] max_age_days = 30" in found.deletions[0].reason


def test_over_the_total_the_oldest_go_until_it_fits() -> None:
    files = [
        _file("b.mcap", 30, 2 * DAY),
        _file("a.mcap", 30, 3 * DAY),
        _file("c.mcap", 30, 1 * DAY),
        _file("now.mcap", 20, 0),
    ]
    # 110 MB against 60: a and b go (50 MB left), c stays.
    found = plan(files, CURRENT, Budget(max_total_bytes=60 * MB), None, NOW)
    assert _names(found) == ["a.mcap", "b.mcap"]
    assert found.stop is None
    assert (
        found.deletions[0].reason
    ) == "the recordings take 110.0 MB, over [recording] max_total_mb = 60"
    assert "80.0 MB" in found.deletions[1].reason  # the total as it stood then


def test_the_recording_being_written_is_never_deleted_and_stops_alone() -> None:
    files = [_file("a.mcap", 5, 3 * DAY), _file("now.mcap", 70, 0)]
    found = plan(files, CURRENT, Budget(max_total_bytes=60 * MB), None, NOW)
    assert _names(found) == ["a.mcap"]
    assert found.stop is not None
    assert found.stop.startswith("this recording alone takes 70.0 MB, over [recording]")


def test_an_old_recording_being_written_is_still_not_deleted() -> None:
    # A run that has gone on for longer than max_age_days: its file is the current one.
    files = [_file("now.mcap", 1, 0)]
    current = FileInfo(CURRENT, MB, NOW - 400 * DAY)
    found = plan([current], CURRENT, Budget(max_age_s=DAY), None, NOW)
    assert not found.acts
    assert plan(files, CURRENT, Budget(max_age_s=DAY), None, NOW) == found


def test_too_little_free_space_deletes_the_oldest_then_stops() -> None:
    files = [
        _file("a.mcap", 100, 3 * DAY),
        _file("b.mcap", 100, 2 * DAY),
        _file("c.mcap", 100, 1 * DAY),
        _file("now.mcap", 1, 0),
    ]
    budget = Budget(min_free_bytes=1000 * MB)
    found = plan(files, CURRENT, budget, 850 * MB, NOW)
    assert _names(found) == ["a.mcap", "b.mcap"]  # 850 → 950 → 1050 MB free
    assert found.stop is None
    assert "850.0 MB free on the disk, under [recording] min_free_mb = 1000" in (
        found.deletions[0].reason
    )
    found = plan(files, CURRENT, budget, 500 * MB, NOW)
    assert _names(found) == ["a.mcap", "b.mcap", "c.mcap"]
    assert found.stop is not None
    assert found.stop.startswith("800.0 MB free on the disk, under [recording] min_free_mb")


def test_only_recordings_count_and_only_they_are_deleted() -> None:
    files = [
        _file("notes.txt", 500, 99 * DAY),
        _file("plot.png", 500, 99 * DAY),
        _file(".hidden.mcap", 500, 99 * DAY),
        _file("run.mcap.part", 500, 99 * DAY),
        _file("a.mcap", 10, 99 * DAY),
        _file("a.recovered.mcap", 10, 98 * DAY),
        _file("now.mcap", 1, 0),
    ]
    found = plan(files, CURRENT, Budget(15 * MB, DAY, 10**9 * MB), 0, NOW)
    assert _names(found) == ["a.mcap", "a.recovered.mcap"]  # by age, then nothing else
    assert found.stop is not None  # too little free space, and nothing else may go
    only_size = plan(files, CURRENT, Budget(max_total_bytes=15 * MB), None, NOW)
    assert _names(only_size) == ["a.mcap"]  # 21 MB of recordings, not 2 GB of files


def test_a_recording_changed_within_a_minute_may_be_another_runs_and_stays() -> None:
    files = [
        _file("other.mcap", 50, IN_USE_S - 1),
        _file("done.mcap", 50, IN_USE_S + 1),
        _file("now.mcap", 1, 0),
    ]
    found = plan(files, CURRENT, Budget(max_total_bytes=10 * MB), None, NOW)
    assert _names(found) == ["done.mcap"]
    assert found.stop is not None
    assert found.stop.startswith("the recordings take 51.0 MB")  # not this one alone


def test_kept_files_are_counted_but_not_deleted() -> None:
    files = [_file("a.mcap", 50, 3 * DAY), _file("b.mcap", 50, 2 * DAY)]
    found = plan(files, CURRENT, Budget(max_total_bytes=60 * MB), None, NOW, keep={DIR / "a.mcap"})
    assert _names(found) == ["b.mcap"]
    assert found.stop is None


def test_equal_ages_go_by_name_and_a_recording_not_yet_written_counts_nothing() -> None:
    files = [_file("b.mcap", 10, DAY), _file("a.mcap", 10, DAY)]  # no now.mcap yet
    found = plan(files, CURRENT, Budget(max_total_bytes=5 * MB), None, NOW)
    assert _names(found) == ["a.mcap", "b.mcap"]
    assert found.stop is None


def test_a_recording_elsewhere_counts_whatever_its_name() -> None:
    elsewhere = Path("/tmp/field.log")
    found = plan([FileInfo(elsewhere, 9 * MB, NOW)], elsewhere, Budget(5 * MB), None, NOW)
    assert found.stop is not None
    assert "alone" in found.stop


_FILES = st.lists(
    st.tuples(
        st.sampled_from(["a.mcap", "b.mcap", "c.mcap", "d.mcap", "e.txt", ".f.mcap", "now.mcap"]),
        st.integers(0, 100 * MB),
        st.floats(0, 60 * DAY),
    ),
    max_size=7,
    unique_by=lambda f: f[0],
)


@given(
    files=_FILES,
    total=st.none() | st.integers(1, 300 * MB),
    age=st.none() | st.floats(1, 60 * DAY),
    least=st.none() | st.integers(1, 300 * MB),
    free=st.none() | st.integers(0, 300 * MB),
)
def test_the_plan_keeps_its_rules_whatever_the_folder(
    files: list[tuple[str, int, float]],
    total: int | None,
    age: float | None,
    least: int | None,
    free: int | None,
) -> None:
    infos = [FileInfo(DIR / n, size, NOW - a) for n, size, a in files]
    budget = Budget(total, age, least)
    found = plan(infos, CURRENT, budget, free, NOW)
    deleted = [d.file for d in found.deletions]
    assert len(set(deleted)) == len(deleted)
    for f in deleted:
        assert f.path != CURRENT
        assert f.path.suffix == ".mcap"
        assert not f.path.name.startswith(".")
        assert NOW - f.mtime >= IN_USE_S
    kept = [f for f in infos if f not in deleted]
    # What age spares goes oldest first: no kept deletable file is older than a
    # deletion made for the size or the free space.
    for d in found.deletions:
        if "max_age_days" not in d.reason:
            assert all(
                k.mtime >= d.file.mtime
                for k in kept
                if k.path != CURRENT and k.path.suffix == ".mcap" and NOW - k.mtime >= IN_USE_S
                if not k.path.name.startswith(".")
            )
    # Within the budget, or told to stop.
    left = sum(f.size for f in kept if f.path.suffix == ".mcap" and f.path.name[0] != ".")
    freed = sum(f.size for f in deleted)
    over = total is not None and left > total
    low = least is not None and free is not None and free + freed < least
    assert (found.stop is not None) == (over or low)


def test_the_budget_of_a_section_and_its_zeros() -> None:
    budget = Budget.from_spec(RecordingSpec())
    assert budget == Budget(8_000 * MB, 30 * DAY, 1_000 * MB)
    unlimited = Budget.from_spec(RecordingSpec(max_total_mb=0, max_age_days=0, min_free_mb=0))
    assert unlimited == Budget()
    assert not unlimited.limited


# --------------------------------------------------------------------------- the section


@pytest.mark.parametrize(
    ("key", "value", "allowed"),
    [
        ("max_total_mb", -1, "a finite number of MB ≥ 0 (0: no limit)"),
        ("max_age_days", float("inf"), "a finite number of days ≥ 0 (0: no limit)"),
        ("min_free_mb", float("nan"), "a finite number of MB ≥ 0 (0: no limit)"),
        ("min_free_mb", "lots", "Input should be a valid number"),
        ("max_files", 3, "unknown key; allowed here: max_total_mb, max_age_days, min_free_mb"),
    ],
)
def test_a_bad_budget_names_the_key_the_value_and_what_is_allowed(
    key: str, value: object, allowed: str
) -> None:
    with pytest.raises(ConfigError) as info:
        parse_config({"recording": {key: value}}, "robot.toml")
    (problem,) = info.value.problems
    assert problem.path == f"recording.{key}"
    assert repr(value) in str(problem) or str(value) in str(problem)
    assert allowed in str(problem)


def test_a_file_changes_one_key_of_the_budget() -> None:
    cfg = parse_config({"recording": {"max_age_days": 0}})
    assert cfg.recording == RecordingSpec(max_age_days=0)
    assert RobotConfig().recording.min_free_mb == 1000


# --------------------------------------------------------------------------- the guard


def test_the_guard_deletes_what_the_plan_says_and_lists_the_folder_only_when_needed() -> None:
    disk = FakeDisk(now_s=NOW)
    disk.add(DIR / "a.mcap", 40 * MB, 3 * DAY)
    disk.add(DIR / "b.mcap", 40 * MB, 2 * DAY)
    disk.add(DIR / "keep.txt", 900 * MB, 9 * DAY)
    guard = BudgetGuard(Budget(max_total_bytes=100 * MB), CURRENT, DIR, disk=disk, period_s=0)
    assert not guard.check().acts
    assert disk.listings == 1
    disk.files[CURRENT] = (10 * MB, NOW)
    for _ in range(3):
        assert not guard.check().acts  # the size of this one and the free space only
    assert disk.listings == 1
    disk.files[CURRENT] = (30 * MB, NOW)  # 110 MB: the folder is listed again, a goes
    found = guard.check()
    assert [d.file.path for d in found.deletions] == [DIR / "a.mcap"]
    assert disk.removed == [DIR / "a.mcap"]
    assert disk.listings == 2
    disk.files[CURRENT] = (70 * MB, NOW)
    found = guard.check()
    assert disk.removed == [DIR / "a.mcap", DIR / "b.mcap"]
    assert found.stop is None
    disk.files[CURRENT] = (101 * MB, NOW)
    assert guard.check().stop is not None
    assert DIR / "keep.txt" in disk.files


def test_a_recording_that_cannot_be_deleted_is_kept_and_the_next_goes() -> None:
    disk = FakeDisk(now_s=NOW)
    disk.add(DIR / "a.mcap", 40 * MB, 3 * DAY)
    disk.add(DIR / "b.mcap", 40 * MB, 2 * DAY)
    disk.files[CURRENT] = (30 * MB, NOW)
    disk.stuck.add(DIR / "a.mcap")
    guard = BudgetGuard(Budget(max_total_bytes=80 * MB), CURRENT, DIR, disk=disk)
    found = guard.check()
    assert [d.file.path for d in found.deletions] == [DIR / "b.mcap"]
    assert found.stop is None  # 70 MB left
    assert disk.removed == [DIR / "b.mcap"]


def test_a_guard_elsewhere_deletes_nothing_and_stops_on_a_low_disk() -> None:
    disk = FakeDisk(now_s=NOW, free=10 * MB)
    disk.add(DIR / "a.mcap", 40 * MB, 30 * DAY)
    guard = BudgetGuard(Budget(min_free_bytes=100 * MB), CURRENT, None, disk=disk)
    found = guard.check()
    assert found.deletions == ()
    assert found.stop is not None
    assert "10.0 MB free" in found.stop
    assert disk.listings == 0


def test_the_local_disk_lists_regular_files_and_knows_the_free_space(tmp_path: Path) -> None:
    (tmp_path / "a.mcap").write_bytes(b"x" * 10)
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "deep.mcap").write_bytes(b"x")
    (tmp_path / "link.mcap").symlink_to(tmp_path / "a.mcap")
    disk = LocalDisk()
    (found,) = disk.listing(tmp_path)
    assert (found.path, found.size) == (tmp_path / "a.mcap", 10)
    assert abs(found.mtime - os.stat(tmp_path / "a.mcap").st_mtime) < 1e-6
    assert disk.listing(tmp_path / "missing") == []
    assert disk.size(tmp_path / "missing") == 0
    free = disk.free_bytes(tmp_path)
    assert free is not None
    assert free > 0
    assert disk.now() > found.mtime - 5


def test_the_guard_recognises_the_recording_however_its_path_is_spelled(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    folder = tmp_path / "recordings"
    folder.mkdir()
    (folder / "now.mcap").write_bytes(b"x" * 2000)
    os.utime(folder / "now.mcap", (0, 0))  # looks old: only its being the current keeps it
    guard = BudgetGuard(Budget(max_total_bytes=1000), Path("recordings/now.mcap"), folder)
    found = guard.check()
    assert found.deletions == ()
    assert found.stop is not None
    assert (folder / "now.mcap").exists()


def test_a_plan_and_a_guard_travel_as_json(tmp_path: Path) -> None:
    found = plan(
        [_file("a.mcap", 30, 3 * DAY), _file("b.mcap", 30, 2 * DAY), _file("now.mcap", 70, 0)],
        CURRENT,
        Budget(max_total_bytes=60 * MB),
        None,
        NOW,
    )
    assert len(found.deletions) == 2
    assert found.stop is not None
    assert Plan.from_json(found.to_json()) == found
    assert Plan.from_json(Plan().to_json()) == Plan()
    guard = BudgetGuard(Budget(MB, DAY, None), "run.mcap", tmp_path, period_s=0.25)
    again = BudgetGuard.described(guard.describe())
    assert (again.budget, again.path, again.folder) == (guard.budget, guard.path, guard.folder)
    assert again.period_s == 0.25
    assert isinstance(again.disk, LocalDisk)
    fake = BudgetGuard(Budget(MB), CURRENT, DIR, disk=FakeDisk())
    with pytest.raises(TypeError):
        fake.describe()  # another process cannot see a test's fake disk
    from whexar.record.sidecar import RecorderProcess

    with pytest.raises(RecordingError, match="keeps no such budget"):
        RecorderProcess(tmp_path / "x.mcap", guard=fake)


class _SlowDisk(FakeDisk):
    """A fake disk whose deletions wait until they are let go, noting their thread."""

    def __init__(self) -> None:
        super().__init__(now_s=NOW)
        self.go = threading.Event()
        self.threads: list[int] = []

    def remove(self, path: Path) -> None:
        self.threads.append(threading.get_ident())
        assert self.go.wait(10.0)
        super().remove(path)


def test_the_guards_thread_deletes_while_the_loop_goes_on() -> None:
    disk = _SlowDisk()
    disk.add(DIR / "a.mcap", 40 * MB, 3 * DAY)
    disk.add(DIR / "b.mcap", 40 * MB, 2 * DAY)
    guard = BudgetGuard(Budget(max_total_bytes=100 * MB), CURRENT, DIR, disk=disk, period_s=0)
    disk.files[CURRENT] = (90 * MB, NOW)  # 170 MB: a and b go, on the thread
    checks = GuardThread(guard)
    plans = checks.poll()  # the check starts, and is left to run
    deadline = monotonic() + 10.0
    while not disk.threads:
        plans += checks.poll()
        assert monotonic() < deadline
    for _ in range(100):  # the deletion waits: the caller does not
        start = monotonic()
        plans += checks.poll()
        assert monotonic() - start < 0.05
    assert disk.removed == []
    disk.go.set()
    while not any(p.acts for p in plans):
        plans += checks.poll()
        assert monotonic() < deadline
    (acted,) = [p for p in plans if p.acts]
    assert [d.file.path for d in acted.deletions] == [DIR / "a.mcap", DIR / "b.mcap"]
    assert disk.removed == [DIR / "a.mcap", DIR / "b.mcap"]
    assert set(disk.threads) == {disk.threads[0]} != {threading.get_ident()}
    assert checks.finish() in ([], [Plan()])


def test_a_check_under_way_at_close_is_reported_in_the_file(tmp_path: Path) -> None:
    folder = tmp_path / "recordings"
    folder.mkdir()
    path = folder / "new.mcap"
    guard = BudgetGuard(Budget(max_total_bytes=4000), path, folder, period_s=0)
    recorder = Recorder(path, guard=guard)  # the first check: nothing to delete
    old = folder / "old.mcap"
    old.write_bytes(b"x" * 5000)
    os.utime(old, (1, 1))
    guard._others = None  # as if the budget had been passed: the next check lists
    recorder.keep_budget()  # the check starts on its thread; close() waits for it
    recorder.close()
    assert not old.exists()
    (deleted,) = recorder.events
    assert isinstance(deleted, RecordingDeleted)
    assert (deleted.path, deleted.size_bytes) == (str(old), 5000)
    recorded = [r.value for r in Recording(path).records() if r.topic == f"/{EVENTS_CHANNEL}"]
    assert recorded == [deleted]


# --------------------------------------------------------------------------- a recorder


def _beat(seq: int) -> Heartbeat:
    return Heartbeat(t=seq / 100, source="beat", seq=seq)


def _feed_until(
    recorder: RecorderProcess, done: Callable[[], bool], why: str, beats: int = 1
) -> int:
    """Hand ``recorder`` ``beats`` heartbeats at a time, write them and keep its budget,
    as a runtime does, until ``done()`` (within 20 s, else ``why``); the next sequence
    number."""
    seq = 0
    deadline = monotonic() + 20.0
    while not done():
        for _ in range(beats):
            recorder("beats", _beat(seq))
            seq += 1
        recorder.write_pending()
        recorder.keep_budget()
        wait_until(monotonic() + 0.005)
        assert monotonic() < deadline, why
    return seq


def test_a_recorder_deletes_before_it_writes_and_reports_it(tmp_path: Path) -> None:
    folder = tmp_path / "recordings"
    folder.mkdir()
    old = folder / "old.mcap"
    old.write_bytes(b"x" * 5000)
    os.utime(old, (1, 1))
    path = folder / "new.mcap"
    guard = BudgetGuard(Budget(max_age_s=DAY), path, folder)
    recorder = Recorder(path, guard=guard)
    assert not old.exists()  # gone before the new file was made
    assert recorder.events == []  # reported once it runs

    async def briefly() -> None:
        with anyio.move_on_after(0.05):
            await recorder.run(anyio.sleep, period_s=0.01)

    anyio.run(briefly)
    (deleted,) = recorder.events
    assert isinstance(deleted, RecordingDeleted)
    assert (deleted.path, deleted.size_bytes, deleted.source) == (str(old), 5000, "recorder")
    recorder.close()
    (recorded,) = [r.value for r in Recording(path).records() if r.topic == f"/{EVENTS_CHANNEL}"]
    assert recorded == deleted
    line = report_line(deleted)
    assert line is not None
    assert line.startswith(f"recording: deleted {old} (0.0 MB): ")


def test_a_recorder_over_its_budget_stops_cleanly_with_an_event(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "big.mcap"
    guard = BudgetGuard(Budget(max_total_bytes=20_000), path, None, period_s=0)
    recorder = Recorder(path, guard=guard, chunk_size=1024)
    seq = 0

    async def record() -> None:
        nonlocal seq
        async with anyio.create_task_group() as tg:
            tg.start_soon(recorder.run, anyio.sleep, 0.001)
            while seq < 5000:  # the run goes on after the recording stopped
                recorder("beats", _beat(seq))
                seq += 1
                await anyio.sleep(0)

    anyio.run(record)
    assert seq == 5000
    (stopped,) = recorder.events
    assert isinstance(stopped, RecordingStopped)
    assert stopped.path == str(path)
    assert "this recording alone takes" in stopped.reason
    assert recorder.stopped == stopped.reason
    assert recorder.failure is None
    stats = recorder.close()  # nothing to raise: the stop was reported
    recording = Recording(path)
    assert recording.complete
    assert recording.metadata["whexar.end"]["stopped"] == stopped.reason
    records = list(recording.records())
    beats = [r.value.seq for r in records if r.topic == "/beats"]
    assert beats == list(range(len(beats)))  # every one up to the stop, in order
    assert 0 < len(beats) < 5000
    assert stats.messages == len(beats) + 1
    assert [r.value for r in records if r.topic == f"/{EVENTS_CHANNEL}"] == [stopped]
    assert main(["log", "info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "RecordingStopped" in out  # quoted as an error: the rest was not recorded
    assert f"recording stopped before the run's end: {stopped.reason}" in out


@pytest.mark.slow
def test_a_recording_process_over_its_budget_stops_and_ends_its_file(tmp_path: Path) -> None:
    from whexar.record.sidecar import RecorderProcess

    path = tmp_path / "process.mcap"
    guard = BudgetGuard(Budget(max_total_bytes=30_000), path, None, period_s=0)
    recorder = RecorderProcess(path, guard=guard, chunk_size=1024, flush_period_s=0.01)
    # The runtime goes on; the file grows in the child.
    seq = _feed_until(
        recorder, lambda: recorder.stopped is not None, "the budget never stopped it", 100
    )
    for _ in range(10):
        recorder("beats", _beat(seq))
        recorder.write_pending()  # let go: nothing is kept, and the pipe closes
    assert recorder.stats.pending == 0
    (stopped,) = recorder.events
    assert isinstance(stopped, RecordingStopped)
    assert "this recording alone takes" in stopped.reason
    stats = recorder.close()
    recording = Recording(path)
    assert recording.complete
    assert recording.metadata["whexar.end"]["stopped"] == stopped.reason
    beats = [r.value.seq for r in recording.records() if r.topic == "/beats"]
    assert beats == list(range(len(beats)))
    assert stats.messages == len(beats) + 1  # and the event, written last
    events = [r.value for r in recording.records() if r.topic == f"/{EVENTS_CHANNEL}"]
    assert events == [stopped]


def _no_disk_work_here(monkeypatch: pytest.MonkeyPatch) -> None:
    """From now on this process may neither delete a file nor list a folder."""
    here = os.getpid()

    def refused(*args: object, **kwargs: object) -> None:
        raise AssertionError(f"the runtime's process {here} touched the folder: {args}")

    monkeypatch.setattr(os, "unlink", refused)
    monkeypatch.setattr(os, "remove", refused)
    monkeypatch.setattr(os, "scandir", refused)
    monkeypatch.setattr(os, "listdir", refused)


@pytest.mark.slow
def test_a_recording_process_deletes_in_its_own_process_and_reports_here(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from whexar.record.sidecar import RecorderProcess

    folder = tmp_path / "recordings"
    folder.mkdir()
    olds = [folder / "b.mcap", folder / "a.mcap", folder / "c.mcap"]
    for k, old in enumerate(olds):
        old.write_bytes(b"x" * (1000 + k))
        os.utime(old, (k + 1, k + 1))
    path = folder / "now.mcap"
    guard = BudgetGuard(Budget(max_age_s=DAY), path, folder, period_s=0)
    _no_disk_work_here(monkeypatch)
    recorder = RecorderProcess(path, guard=guard, flush_period_s=0.01)
    # The run goes on; the deletions come when done.
    _feed_until(recorder, lambda: len(recorder.events) >= 3, "the recording process never reported")
    assert not any(old.exists() for old in olds)
    deleted = [e for e in recorder.events if isinstance(e, RecordingDeleted)]
    assert deleted == recorder.events
    assert [(e.path, e.size_bytes, e.source) for e in deleted] == [
        (str(old), 1000 + k, "recorder")
        for k, old in enumerate(olds)  # the oldest first
    ]
    assert "older than [recording] max_age_days = 1" in deleted[0].reason
    recorder.close()
    recorded = [r.value for r in Recording(path).records() if r.topic == f"/{EVENTS_CHANNEL}"]
    assert recorded == recorder.events
    # Closed at once: what the first check did is still told, here and in the file.
    late = folder / "late.mcap"
    late.write_bytes(b"x" * 77)
    os.utime(late, (1, 1))
    other = folder / "other.mcap"
    again = RecorderProcess(other, guard=BudgetGuard(Budget(max_age_s=DAY), other, folder))
    again.close()
    (told,) = again.events
    assert isinstance(told, RecordingDeleted)
    assert (told.path, told.size_bytes) == (str(late), 77)
    recorded = [r.value for r in Recording(other).records() if r.topic == f"/{EVENTS_CHANNEL}"]
    assert recorded == [told]


class _Live:
    """A live view that shows nothing: the recorder then writes in-process."""

    def add_channel(self, channel_id: int, topic: str, schema_name: str, schema: bytes) -> None:
        pass

    def log(self, channel_id: int, ns: int, data: bytes) -> None:
        pass


def test_the_budget_covers_the_recordings_folder_and_nothing_else(tmp_path: Path) -> None:
    from whexar.record.runs import run_recorder

    folder = recordings_folder()  # the test's own (tests/conftest.py)
    folder.mkdir(parents=True)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    for where in (folder, elsewhere):
        (where / "old.mcap").write_bytes(b"x" * 100)
        os.utime(where / "old.mcap", (1, 1))
    cfg = RobotConfig()  # a month at most: 1970's recordings go
    for path in (elsewhere / "run.mcap", folder / "run.mcap"):
        run_recorder(path, cfg, None, {}, {}, _Live()).close()
    assert (elsewhere / "old.mcap").exists()
    assert not (folder / "old.mcap").exists()
    live = run_recorder(os.devnull, cfg, None, {}, {}, _Live())
    assert live._guard is None  # --no-record with a live view: no budget to keep
    live.close()
    unlimited = parse_config(
        {"recording": {"max_total_mb": 0, "max_age_days": 0, "min_free_mb": 0}}
    )
    recorder = run_recorder(folder / "free.mcap", unlimited, None, {}, {}, _Live())
    assert recorder._guard is None
    recorder.close()


@pytest.mark.slow
def test_a_run_reports_each_deletion_and_replays_without_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = Path(__file__).resolve().parents[2]
    folder = recordings_folder()
    folder.mkdir(parents=True)
    old = folder / "walk-19700101-000001.mcap"
    old.write_bytes(b"x" * 1234)
    os.utime(old, (1, 1))
    log = folder / "walk.mcap"
    graph = root / "config" / "graphs" / "walk.toml"
    script = root / "config" / "commands" / "tour.jsonl"
    args = ["run", str(graph), "--virtual", "--duration", "2", "--record", str(log)]
    assert main([*args, "--commands", str(script)]) == 0
    out = capsys.readouterr().out
    (line,) = [x for x in out.splitlines() if "RecordingDeleted" in x]
    assert f"path='{old.resolve()}'" in line
    assert "size_bytes=1234" in line
    assert "older than [recording] max_age_days = 30" in line
    assert f"recording: {log}\n" in out
    assert not old.exists()
    recorded = [r.value for r in Recording(log).records() if isinstance(r.value, RecordingDeleted)]
    assert len(recorded) == 1
    # The deletion is the disk's, not the robot's: the replay agrees all the same.
    assert main(["replay", str(log), "--check"]) == 0
    assert main(["log", "diff", str(log), str(log)]) == 0


@pytest.mark.slow
def test_whexar_sim_prints_what_the_budget_did(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "robot.toml"
    config.write_text("[recording]\nmin_free_mb = 1e12\n")  # no disk has that: a stop at once
    path = recordings_folder() / "tiny.mcap"
    recordings_folder().mkdir(parents=True)
    scenario = tmp_path / "scenario.toml"
    scenario.write_text('name = "tiny"\nduration_s = 1.0\nconfig = "robot.toml"\n')
    assert main(["sim", "--scenario", str(scenario), "--record", str(path), "--json"]) == 0
    err = capsys.readouterr().err
    assert "recording stopped at t = " in err
    assert "the run goes on: " in err
    assert "free on the disk, under [recording] min_free_mb = 1e+12" in err
    recording = Recording(path)
    assert recording.complete
    assert "free on the disk" in recording.metadata["whexar.end"]["stopped"]
    assert recording.attachments["config.toml"].data == config.read_bytes()
