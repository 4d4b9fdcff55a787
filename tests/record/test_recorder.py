"""The recorder writes every message and every link byte of a run, typed, with a schema on
every channel, Foxglove's views beside them, and its memory bounded."""

from __future__ import annotations

import itertools
import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest
from mcap.reader import make_reader

from whexar import __version__
from whexar.actors.messages import ServoStates
from whexar.record.encoding import LinkBytes
from whexar.record.foxglove import URDF_JOINT_NAMES, event_level
from whexar.record.reader import Recording
from whexar.record.writer import JOINT_STATES_PERIOD_S, Recorder
from whexar.runtime.messages import Event, Heartbeat, Message
from whexar.runtime.wiring import EVENTS_CHANNEL

if TYPE_CHECKING:
    from tests.record.conftest import RecordedRun

Check = Callable[[Mapping[str, Any], Any], list[str]]


def test_a_recorded_run_reads_back_as_the_same_typed_messages(recorded_run: RecordedRun) -> None:
    recording = Recording(recorded_run.path)
    assert recording.complete
    assert recording.damage is None
    recording.check_compatible()
    records = list(recording.records())
    times = [r.log_time for r in records]
    assert times == sorted(times)
    assert min(times) >= 1  # never 0: Foxglove's timeline
    typed = [(r.channel, r.value) for r in records if r.channel is not None]
    # Log-time order, and publish order among equal times (a stable sort by t).
    expected = sorted(recorded_run.published, key=lambda cm: cm[1].t)
    assert typed == expected
    channels = {c for c, _ in typed}
    assert {"state", "goals", EVENTS_CHANNEL} <= channels
    assert {r.schema for r in records if r.topic == "/state"} == {"ServoStates"}


def test_link_bytes_come_back_with_their_times_in_each_direction(
    recorded_run: RecordedRun,
) -> None:
    got = [r.value for r in Recording(recorded_run.path).records(topics=["/links/bus"])]
    assert got
    assert all(isinstance(v, LinkBytes) for v in got)
    for direction in ("tx", "rx"):
        sent = [(t, d) for _, dr, t, d in recorded_run.link_bytes if dr == direction]
        back = [(v.t, v.data) for v in got if v.direction == direction]
        assert b"".join(d for _, d in back) == b"".join(d for _, d in sent)
        assert {t for t, _ in back} == {t for t, _ in sent}


def test_metadata_and_attachments_are_stored(recorded_run: RecordedRun) -> None:
    recording = Recording(recorded_run.path)
    assert recording.version == __version__
    assert recording.metadata["run"] == {"robot": "WHexaR", "command": "pytest"}
    assert recording.attachments["wiring.toml"].media_type == "application/toml"
    assert recording.attachments["wiring.toml"].text.startswith("[[actors]]")
    assert recording.attachments["blob.bin"].data == b"\x00\x01"
    end = recording.metadata["whexar.end"]
    assert end["dropped"] == "0"
    assert end["errors"] == "0"
    assert int(end["messages"]) == len(recorded_run.published)


def test_the_plain_mcap_reader_finds_a_schema_on_every_channel(
    recorded_run: RecordedRun, schema_problems: Check
) -> None:
    with open(recorded_run.path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        assert summary.channels
        for channel in summary.channels.values():
            schema = summary.schemas[channel.schema_id]
            assert schema.encoding == "jsonschema"
            assert channel.message_encoding == "json"
            assert json.loads(schema.data)["type"] == "object"
        count = 0
        for found, channel, msg in reader.iter_messages(log_time_order=True):
            assert found is not None
            problems = schema_problems(json.loads(found.data), json.loads(msg.data))
            assert problems == [], (channel.topic, problems)
            assert msg.log_time == msg.publish_time > 0
            count += 1
    topics = {c.topic for c in summary.channels.values()}
    assert {"/state", "/goals", "/events", "/links/bus", "/joint_states", "/log", "/tf"} <= topics
    assert count == len(list(Recording(recorded_run.path).records()))


def test_foxglove_views_joint_states_log_and_transforms(recorded_run: RecordedRun) -> None:
    records = list(Recording(recorded_run.path).records())
    states = [r for r in records if r.schema == "ServoStates"]
    views = [r for r in records if r.topic == "/joint_states"]
    # At most every JOINT_STATES_PERIOD_S of log time, each from the servo state of its time.
    assert views
    assert views[0].log_time == states[0].log_time
    gaps = [b.log_time - a.log_time for a, b in itertools.pairwise(views)]
    assert min(gaps) >= JOINT_STATES_PERIOD_S * 1e9 - 1
    assert {v.log_time for v in views} <= {s.log_time for s in states}
    # Not thinned more than needed: the next servo state after each period is written.
    state_gap = max(b.log_time - a.log_time for a, b in itertools.pairwise(states))
    assert max(gaps) < JOINT_STATES_PERIOD_S * 1e9 + state_gap
    assert states[-1].log_time - views[-1].log_time < JOINT_STATES_PERIOD_S * 1e9 + state_gap
    first, view = states[0].value, views[0].value
    assert isinstance(first, ServoStates)
    names = [URDF_JOINT_NAMES[7 * j.leg + j.joint] for j in first.joints]
    assert [j["name"] for j in view["joints"]] == names
    assert view["timestamp"]["sec"] * 10**9 + view["timestamp"]["nsec"] == states[0].log_time
    for state, joint in zip(first.joints, view["joints"], strict=True):
        assert joint.get("position") == state.position_rad
        assert joint.get("effort") == state.current_a
    events = [r for r in records if isinstance(r.value, Event)]
    logs = [r for r in records if r.topic == "/log"]
    assert [log.value["level"] for log in logs] == [event_level(e.schema) for e in events]
    assert logs[0].value["message"].startswith(events[0].schema + ": ")
    assert logs[0].value["name"] == events[0].value.source
    (tf,) = [r.value for r in records if r.topic == "/tf"]
    (transform,) = tf["transforms"]
    assert transform["parent_frame_id"] == "world"
    assert transform["child_frame_id"] == "base"
    assert transform["rotation"] == {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}


def test_the_urdf_names_the_joints_as_the_joint_states_do() -> None:
    from whexar.config import RobotConfig
    from whexar.sim.urdf import build_urdf

    urdf = build_urdf(RobotConfig())
    for name in URDF_JOINT_NAMES:
        assert f'<joint name="{name}" type="' in urdf


def _beat(t: float) -> Heartbeat:
    return Heartbeat(t=t, source="beat", seq=int(t * 100))


def test_memory_is_bounded_and_what_overflows_is_counted(tmp_path: Path) -> None:
    path = tmp_path / "full.mcap"
    recorder = Recorder(path, max_pending=10)
    for i in range(25):
        recorder("beats", _beat(i / 100))
    assert recorder.stats.pending == 10
    assert recorder.stats.dropped == 15
    stats = recorder.close()
    assert stats.messages == 10
    assert stats.dropped == 15
    recording = Recording(path)
    assert recording.metadata["whexar.end"]["dropped"] == "15"
    kept = [r.value.seq for r in recording.records() if isinstance(r.value, Heartbeat)]
    assert kept == list(range(15, 25))  # the oldest went
    (log,) = [r.value for r in recording.records() if r.topic == "/log"]
    assert log["level"] == 4
    assert "15 entries dropped" in log["message"]


def test_the_normal_path_drops_nothing(tmp_path: Path) -> None:
    with Recorder(tmp_path / "ok.mcap", max_pending=10) as recorder:
        for i in range(100):
            recorder("beats", _beat(i / 100))
            recorder.write_pending()
    assert recorder.stats.dropped == 0
    assert recorder.stats.messages == 100
    assert recorder.stats.max_pending == 1


@dataclass(frozen=True, slots=True, kw_only=True)
class _Odd(Message):
    items: list[int]


def test_a_message_that_cannot_be_encoded_is_logged_and_recording_goes_on(
    tmp_path: Path,
) -> None:
    path = tmp_path / "odd.mcap"
    with Recorder(path) as recorder:
        recorder("odd", _Odd(t=0.1, source="x", items=[1]))
        recorder("odd", _Odd(t=0.2, source="x", items=[2]))
        recorder("beats", _beat(0.3))
    assert recorder.stats.errors == 2
    records = list(Recording(path).records())
    assert [r.topic for r in records] == ["/log", "/beats"]
    assert "cannot encode _Odd on /odd" in records[0].value["message"]


def test_a_flush_makes_what_was_written_readable_before_the_end(tmp_path: Path) -> None:
    path = tmp_path / "live.mcap"
    recorder = Recorder(path, flush_period_s=1e-6)
    for i in range(1, 6):
        recorder("beats", _beat(i / 10))
    recorder.write_pending()
    live = Recording(path)  # still open: no footer yet
    assert not live.complete
    assert live.damage is not None
    assert "not closed" in live.damage.reason
    assert [r.value.seq for r in live.records()] == [10, 20, 30, 40, 50]
    recorder.close()
    assert Recording(path).complete


def test_write_pending_keeps_to_a_budget(tmp_path: Path) -> None:
    with Recorder(tmp_path / "budget.mcap") as recorder:
        for i in range(2000):
            recorder("beats", _beat(i / 1000))
        done = recorder.write_pending(budget_s=0.0)
        assert 0 < done < 2000
        assert recorder.stats.pending == 2000 - done


@pytest.mark.parametrize("bad", [{"compression": "gzip"}, {"chunk_size": 0}])
def test_bad_settings_are_refused(tmp_path: Path, bad: dict[str, Any]) -> None:
    from whexar.record.encoding import RecordingError

    with pytest.raises(RecordingError):
        Recorder(tmp_path / "x.mcap", **bad)


async def test_run_writes_pending_entries_until_cancelled(tmp_path: Path) -> None:
    import anyio

    recorder = Recorder(tmp_path / "loop.mcap")
    recorder("beats", _beat(0.1))
    with anyio.move_on_after(0.05):
        await recorder.run(anyio.sleep, period_s=0.01)
    assert recorder.stats.messages == 1
    assert recorder.stats.pending == 0
    recorder.close()
