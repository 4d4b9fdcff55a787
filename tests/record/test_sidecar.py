"""The recorder in a process of its own writes what the in-process recorder writes, the
same bytes for every message type (a runtime killed beside it: test_sigkill.py); what
cannot cross to it, a dead or stalled recording process, are counted, logged, and
never stop the robot."""

from __future__ import annotations

import os
import signal
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader

from tests.record.test_encoding import FLOATS, _instance, _types
from whexar.record.encoding import RecordingError
from whexar.record.reader import Recording
from whexar.record.sidecar import RecorderProcess
from whexar.record.writer import Recorder
from whexar.runtime.messages import Heartbeat, Message

Same = Callable[[Any, Any], bool]


def _beat(seq: int) -> Heartbeat:
    return Heartbeat(t=seq / 100, source="beat", seq=seq)


def _payloads(path: Path) -> list[tuple[str, int, bytes]]:
    """Every message of an MCAP file as (topic, log time, bytes), by the plain reader."""
    with path.open("rb") as f:
        return [
            (channel.topic, message.log_time, message.data)
            for _, channel, message in make_reader(f).iter_messages(log_time_order=False)
        ]


def _feed(recorder: Recorder | RecorderProcess) -> None:
    recorder.robot_description("<robot name='x'/>")
    for k in range(len(FLOATS)):
        for filled in (True, False):
            for cls in _types():
                recorder(f"c{k % 3}", _instance(cls, filled, k))
            tx = bytearray(b"\xff\xff\xfd\x00")  # a link may hand over a bytearray
            recorder.link_bytes("bus", "tx", k / 10, tx)  # type: ignore[arg-type]
            recorder.link_bytes("bus", "rx", k / 10, bytes([k, 0, 255]))
            recorder.transform(k / 10, "world", "base", (k, 0.0, 0.3), (0.0, 0.0, 0.0, 1.0))
        recorder.write_pending()


@pytest.mark.slow
def test_every_message_type_is_written_as_the_in_process_recorder_writes_it(
    tmp_path: Path, same_value: Same
) -> None:
    with Recorder(tmp_path / "here.mcap") as here:
        _feed(here)
    with RecorderProcess(tmp_path / "there.mcap") as there:
        _feed(there)
    assert there.stats.errors == here.stats.errors == 0
    assert there.stats.messages == here.stats.messages > 60 * len(FLOATS)
    assert there.stats.records == here.stats.records
    assert there.stats.process_cpu_s > 0
    # The same payloads, byte for byte, on the same topics at the same times.
    assert _payloads(tmp_path / "there.mcap") == _payloads(tmp_path / "here.mcap")
    recording = Recording(tmp_path / "there.mcap")
    assert recording.complete
    back = [r.value for r in recording.records() if r.channel is not None]
    expected = [r.value for r in Recording(tmp_path / "here.mcap").records() if r.channel]
    assert len(back) == len(expected)
    assert all(same_value(a, b) for a, b in zip(back, expected, strict=True))


def test_what_cannot_cross_is_logged_and_the_rest_recorded(tmp_path: Path) -> None:
    @dataclass(frozen=True, slots=True, kw_only=True)
    class Local(Message):  # inside a function: the recording process cannot import it
        n: int

    path = tmp_path / "odd.mcap"
    with RecorderProcess(path) as recorder:
        recorder("local", Local(t=0.1, source="x", n=1))
        recorder("local", Local(t=0.2, source="x", n=2))
        recorder("beats", Heartbeat(t=0.3, source="x", seq=np.int64(3)))  # type: ignore[arg-type]
        recorder("beats", _beat(40))
    assert recorder.stats.errors == 3
    records = list(Recording(path).records())
    logs = [r.value["message"] for r in records if r.topic == "/log"]
    assert len(logs) == 2  # once per channel and type
    assert "cannot encode Local on /local" in logs[0]
    assert "cannot import it" in logs[0]
    assert "cannot encode Heartbeat on /beats" in logs[1]
    assert "handed to the recording process" in logs[1]
    assert [r.value.seq for r in records if r.topic == "/beats"] == [40]


def test_a_path_that_cannot_be_written_is_refused_at_once(tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match="cannot record to"):
        RecorderProcess(tmp_path / "missing" / "x.mcap")


def test_a_dead_recording_process_ends_the_recording_not_the_run(tmp_path: Path) -> None:
    recorder = RecorderProcess(tmp_path / "dead.mcap")
    recorder("beats", _beat(0))
    recorder.write_pending()
    recorder._child.kill()
    recorder._child.wait(timeout=10)
    for seq in range(1, 2000):  # the runtime goes on: nothing raises
        recorder("beats", _beat(seq))
        recorder.write_pending()
    assert recorder.failure is not None
    assert "recording process ended" in recorder.failure
    with pytest.raises(RecordingError, match="failed"):
        recorder.close()


@pytest.mark.slow
def test_a_stalled_recording_process_bounds_memory_and_counts_what_is_dropped(
    tmp_path: Path,
) -> None:
    path = tmp_path / "stalled.mcap"
    recorder = RecorderProcess(path, max_unsent_bytes=64 * 1024)
    os.kill(recorder._child.pid, signal.SIGSTOP)
    try:
        seq = 0
        while recorder.stats.dropped == 0:  # the pipe fills, then the frames kept
            for _ in range(100):
                recorder("beats", _beat(seq))
                seq += 1
            recorder.write_pending()
            assert seq < 1_000_000, "nothing was ever dropped"
        assert recorder._unsent <= 64 * 1024
    finally:
        os.kill(recorder._child.pid, signal.SIGCONT)
    recorder("beats", _beat(seq))
    stats = recorder.close()
    assert stats.dropped > 0
    recording = Recording(path)
    assert recording.complete
    assert recording.metadata["whexar.end"]["dropped"] == str(stats.dropped)
    kept = [r.value.seq for r in recording.records() if r.topic == "/beats"]
    assert len(kept) + stats.dropped == seq + 1
    assert kept[-1] == seq
    logs = [r.value["message"] for r in recording.records() if r.topic == "/log"]
    assert any("entries dropped" in text for text in logs)
