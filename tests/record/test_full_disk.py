"""A full disk stops the recording with an event and the run goes on; what was written
stays readable: the file is cut back to its last whole record and ended there as far as
the disk lets (the summary, else a bare footer, else nothing more), in-process and in a
recording process of its own (disks filled by :class:`tests.record.fakes.FullDisk`)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from mcap.reader import make_reader

from tests.record.fakes import FullDisk
from whexar.actors.messages import RecordingStopped, ServoStates
from whexar.cli import main
from whexar.record.encoding import RecordingError
from whexar.record.reader import Recording
from whexar.record.sidecar import RecorderProcess
from whexar.record.writer import Recorder
from whexar.runtime.clock import monotonic, wait_until
from whexar.runtime.messages import Heartbeat
from whexar.testing import Harness, run_actors
from whexar.testing.bus import bus_graph

BEATS = 2000
# Small chunks and no timed flush: the same beats make the same bytes on any disk.
CHUNK = 1024


def _beat(seq: int) -> Heartbeat:
    return Heartbeat(t=seq / 100, source="beat", seq=seq)


def _record(path: Path, room: int | None, chunk_size: int = CHUNK) -> Recorder:
    opener = None if room is None else (lambda p: FullDisk(p, room))
    recorder = Recorder(path, opener=opener, chunk_size=chunk_size, flush_period_s=1e9)
    for seq in range(BEATS):
        recorder("beats", _beat(seq))
        if seq % 10 == 9:
            recorder.write_pending()
    return recorder


def _beats(path: Path) -> list[int]:
    return [r.value.seq for r in Recording(path).records() if r.topic == "/beats"]


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("disk") / "reference.mcap"
    _record(path, None).close()
    return path


@pytest.mark.parametrize("room", [*range(2_000, 40_000, 1_337), 40_000, 60_000])
def test_a_full_disk_keeps_every_whole_chunk_readable(
    room: int, reference: Path, tmp_path: Path
) -> None:
    path = tmp_path / "full.mcap"
    recorder = _record(path, room)  # nothing raises: the run would go on
    assert recorder.failure == "No space left on device"
    assert recorder.stats.pending == 0
    recorder("beats", _beat(BEATS))  # after the failure, nothing is kept
    assert recorder.stats.pending == 0
    with pytest.raises(RecordingError, match="No space left on device"):
        recorder.close()  # no event said so: the owner learns it here
    assert path.stat().st_size <= room
    # The reference cut at the same size reads whole chunks up to there (and perhaps one
    # whose indexes were cut off): the full disk's file holds the same, less that one.
    cut = tmp_path / "cut.mcap"
    with reference.open("rb") as src, cut.open("wb") as dst:
        dst.write(src.read(room))
    readable, expected = _beats(path), _beats(cut)
    assert readable == expected[: len(readable)]
    assert len(expected) - len(readable) <= CHUNK // 40  # one chunk at most
    assert readable  # the header, metadata and some chunks fitted
    recording = Recording(path)
    if recording.complete:  # ended with its summary, or a bare footer
        with path.open("rb") as f:
            plain = [m.log_time for _, _, m in make_reader(f).iter_messages()]
        assert len(plain) == len(list(recording.records()))
    else:
        assert recording.damage is not None
        assert recording.damage.offset == recording.size  # it ends at a whole record


def test_each_way_of_ending_a_full_disks_file_is_taken(tmp_path: Path) -> None:
    # What the cut frees (the part of the chunk that did not fit) holds the summary if
    # the chunks are large and few, else a bare footer, else nothing more.
    ends = set()
    sweeps = [(1024, range(20_000, 21_400, 23)), (16 * 1024, range(20_000, 40_000, 1_009))]
    for chunk_size, rooms in sweeps:
        for room in rooms:
            path = tmp_path / f"full-{chunk_size}-{room}.mcap"
            with pytest.raises(RecordingError):
                _record(path, room, chunk_size).close()
            recording = Recording(path)
            if "whexar.end" in recording.metadata:
                assert recording.complete
                assert recording.metadata["whexar.end"]["stopped"] == "No space left on device"
                ends.add("summary")
            else:
                ends.add("footer" if recording.complete else "none")
    assert ends == {"summary", "footer", "none"}


def test_a_disk_full_from_the_start_costs_the_recording_only(tmp_path: Path) -> None:
    path = tmp_path / "none.mcap"
    recorder = Recorder(path, opener=lambda p: FullDisk(p, 100))
    assert recorder.failure is not None
    recorder("beats", _beat(1))
    assert recorder.write_pending() == 0
    recorder.keep_budget()  # reported: close() has nothing more to say
    (stopped,) = recorder.events
    assert isinstance(stopped, RecordingStopped)
    assert stopped.reason == "cannot write: No space left on device"
    recorder.close()
    assert path.stat().st_size <= 100


def test_a_run_goes_on_when_the_disk_fills_and_the_file_reads_up_to_there(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "run.mcap"
    disk: list[FullDisk] = []

    def opener(p: Path) -> FullDisk:
        disk.append(FullDisk(p, 60_000))
        return disk[-1]

    recorder = Recorder(path, opener=opener)

    async def scenario(h: Harness) -> None:  # returns when the recording stops
        await recorder.run(h.sleep, runtime=h.runtime)

    result = run_actors(
        bus_graph("emulator", wiggle={}),
        duration=2.0,
        scenario=scenario,
        observers=[recorder],
        link_observer=recorder.link_bytes,
    )
    recorder.close()  # the stop was an event: nothing to raise
    assert result.exit_code == 0
    assert result.end_time >= 2.0
    (stopped,) = result.events(RecordingStopped)
    assert stopped.source == "recorder"
    assert stopped.reason == "cannot write: No space left on device"
    assert 0 < stopped.t < 1.5
    assert disk[0].refused >= 1
    # The servo bus went on to the end, long after the recording stopped.
    states = result.messages("state", of=ServoStates)
    assert states[-1].t > 1.9
    recorded = [r.value.t for r in Recording(path).records() if r.topic == "/state"]
    assert recorded == [s.t for s in states][: len(recorded)]
    assert recorded
    assert recorded[-1] <= stopped.t
    assert main(["log", "info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "/state" in out


@pytest.mark.slow
def test_a_full_disk_in_the_recording_process_ends_it_and_says_why(tmp_path: Path) -> None:
    path = tmp_path / "process.mcap"
    recorder = RecorderProcess(path, opener="tests.record.fakes:disk_of_100k", chunk_size=CHUNK)
    seq = 0
    deadline = monotonic() + 20.0
    while recorder.failure is None:  # the runtime goes on; it learns from the pipe
        for _ in range(200):
            recorder("beats", _beat(seq))
            seq += 1
        recorder.write_pending()
        wait_until(monotonic() + 0.005)
        assert monotonic() < deadline, "the recording process never failed"
    assert recorder.failure == "No space left on device"
    for _ in range(100):
        recorder("beats", _beat(seq))
        recorder.write_pending()  # nothing raises, nothing is kept
    assert recorder.stats.pending == 0
    recorder.keep_budget()
    (stopped,) = recorder.events
    assert isinstance(stopped, RecordingStopped)
    assert stopped.reason == "cannot write: No space left on device"
    stats = recorder.close()  # reported: no exception
    assert stats.messages > 0  # the recording process's own figures
    readable = _beats(path)
    assert readable == list(range(len(readable)))
    assert len(readable) > 500
    assert path.stat().st_size <= 100_000
    copy = tmp_path / "copy.mcap"
    shutil.copy(path, copy)
    assert main(["log", "recover", str(copy)]) == 0  # and it mends as any cut file


def test_a_disk_that_fills_with_the_summary_keeps_every_message(
    reference: Path, tmp_path: Path
) -> None:
    path = tmp_path / "summary.mcap"
    room = reference.stat().st_size - 100  # every chunk fits, the summary does not
    with pytest.raises(RecordingError, match="No space left on device"):
        _record(path, room).close()
    recording = Recording(path)
    assert recording.complete  # a bare footer after the data
    assert _beats(path) == list(range(BEATS))
    assert recording.metadata["whexar.end"]["messages"] == str(BEATS)
