"""Replay: a recorded simulated run played back through the same actors agrees with the
recording message for message; a changed threshold is found and named."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import pytest

from whexar.cli import main
from whexar.config import RobotConfig
from whexar.record import replay as replay_module
from whexar.record.encoding import RecordingError
from whexar.record.reader import Recording
from whexar.record.replay import Divergence, compare, replay
from whexar.record.writer import Recorder
from whexar.runtime.streams import Dealer
from whexar.sim.run import SimResult, simulate
from whexar.testing.walk import command

ROOT = Path(__file__).resolve().parents[2]
COMMANDS = [(0.0, command(gait="tripod")), (2.5, command(mode="ride", vx_m_s=0.1))]
DURATION_S = 3.0


@pytest.fixture(scope="module")
def recorded_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, SimResult]:
    """Three seconds of the simulated robot: standing up, then riding off."""
    path = tmp_path_factory.mktemp("replay") / "run.mcap"
    return path, simulate(commands=COMMANDS, duration=DURATION_S, record=path)


@pytest.fixture
def recorded(recorded_run: tuple[Path, SimResult]) -> Path:
    return recorded_run[0]


@pytest.mark.slow
def test_a_replay_delivers_what_the_run_delivered(recorded_run: tuple[Path, SimResult]) -> None:
    # No channel drops a message the run did not: the same counts, channel by channel.
    path, run = recorded_run
    result = replay(path)
    for name, stats in run.run.stats.items():
        again = result.channels[name]
        assert (again.published, dict(again.dropped)) == (stats.published, dict(stats.dropped))


@pytest.mark.slow
def test_a_replay_reads_its_recording_as_it_goes(
    recorded: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Read up front, an hour of device bytes would be held at once (about 15 MB a
    # minute): the replay holds what lies between its readers, a cycle's worth.
    held: list[int] = []
    read = [0]
    deal = Dealer.deal

    def counted(dealer: Dealer[Any, Any]) -> bool:
        before = sum(len(h.queue) for h in dealer._hands.values())
        more = deal(dealer)
        held.append(sum(len(h.queue) for h in dealer._hands.values()))
        read[0] += held[-1] - before
        return more

    monkeypatch.setattr(Dealer, "deal", counted)
    result = replay(recorded, check=True)
    assert result.divergence is None
    assert read[0] > 3_000  # every byte of three seconds went through the dealer
    assert max(held) < 500  # a sensor frame's worth of bus bytes, however long the log


def _config(tmp_path: Path, old: str, new: str) -> Path:
    """The shipped configuration with one line changed."""
    text = (ROOT / "config" / "whexar.toml").read_text()
    assert old in text
    path = tmp_path / "changed.toml"
    path.write_text(text.replace(old, new, 1))
    return path


def _json(capsys: pytest.CaptureFixture[str]) -> dict[str, object]:
    out = capsys.readouterr().out
    return dict(json.loads(out.strip().splitlines()[-1]))


@pytest.mark.slow
def test_a_replay_agrees_with_its_recording(
    recorded: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["replay", str(recorded), "--check", "--json"]) == 0
    summary = _json(capsys)
    assert summary["divergence"] is None
    assert summary["replayed_s"] == DURATION_S
    compared = summary["compared"]
    assert isinstance(compared, int)
    # Every message the recording holds but the fed commands, the runtime's events too.
    published = sum(
        1
        for r in Recording(recorded).records()
        if r.topic not in ("/commands", "/joint_states", "/tf", "/log", "/robot_description")
        and not r.topic.startswith("/links/")
    )
    assert compared == published
    assert summary["fed"] == {"commands": 2}
    links = summary["links"]
    assert isinstance(links, dict)
    assert re.match(r"(\d+)/\1 recorded packets written, 0 differing, 0 waits", links["bus"])


@pytest.mark.slow
def test_a_changed_threshold_is_found_and_named(
    recorded: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # The force sensors' contact threshold (6.7.3): a foot touches sooner.
    changed = _config(tmp_path, "contact_on_counts = 200", "contact_on_counts = 150")
    assert main(["replay", str(recorded), "--check", "--config", str(changed)]) == 1
    out = capsys.readouterr().out
    assert "config        fsr.contact_on_counts: 200 → 150" in out
    found = re.search(r"diverged at t = ([0-9.]+) s on (\S+): (\S+) differs", out)
    assert found is not None, out
    t, channel, what = float(found[1]), found[2], found[3]
    # Within the recording: the run goes on sitting down after its duration.
    assert 0 < t <= max(r.log_time for r in Recording(recorded).records()) / 1e9
    assert channel == "loads"
    assert what.startswith("LegLoads.contacts[")
    assert "recorded: False" in out
    assert "replayed: True" in out


@pytest.mark.slow
def test_the_recorded_configuration_must_be_this_versions(
    recorded: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # As if this whexar's built-in robot had another IMU tolerance than the recording's.
    data = RobotConfig().model_dump()
    data["imu"]["gravity_tolerance_g"] = 0.3
    monkeypatch.setattr(replay_module, "RobotConfig", lambda: RobotConfig.model_validate(data))
    assert main(["replay", str(recorded)]) == 2
    err = capsys.readouterr().err
    assert "another robot configuration" in err
    assert "imu.gravity_tolerance_g: 0.2 → 0.3" in err
    assert "--config FILE" in err


@pytest.mark.slow
def test_the_recordings_budget_is_no_configuration_a_replay_refuses(
    recorded: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Where recordings go and how many are kept changes nothing the actors do.
    data = RobotConfig().model_dump()
    data["recording"]["max_age_days"] = 0.0
    monkeypatch.setattr(replay_module, "RobotConfig", lambda: RobotConfig.model_validate(data))
    result = replay(recorded, stop=0.5, check=True)
    assert result.divergence is None


@pytest.mark.slow
def test_a_window_checks_what_is_in_it(recorded: Path) -> None:
    whole = replay(recorded, check=True)
    window = replay(recorded, check=True, start=1.0, stop=2.0)
    assert whole.divergence is None
    assert window.divergence is None, window.divergence and window.divergence.describe()
    assert window.duration_s == 2.0
    assert 0 < window.compared < whole.compared
    ticks: list[float] = []
    replay(recorded, stop=1.5, progress=lambda t, end: ticks.append(t))
    assert ticks == sorted(ticks)
    assert ticks[-1] == 1.5


@pytest.mark.slow
def test_a_cut_recording_replays_up_to_where_it_ends(recorded: Path, tmp_path: Path) -> None:
    cut = tmp_path / "cut.mcap"
    data = recorded.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    result = replay(cut, check=True)
    assert result.damage is not None
    assert "ends" in result.damage or "footer" in result.damage
    assert result.divergence is None, result.divergence and result.divergence.describe()
    assert 0 < result.duration_s < DURATION_S
    assert result.compared > 0


@pytest.mark.slow
def test_a_run_of_a_wiring_file_replays_without_its_command_source(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = tmp_path / "walk.mcap"
    graph = ROOT / "config" / "graphs" / "walk.toml"
    script = ROOT / "config" / "commands" / "tour.jsonl"
    args = ["run", str(graph), "--virtual", "--duration", "3", "--quiet", "--record", str(log)]
    assert main([*args, "--commands", str(script)]) == 0
    capsys.readouterr()
    assert main(["replay", str(log), "--check", "--json"]) == 0
    summary = _json(capsys)
    assert summary["divergence"] is None
    fed = summary["fed"]
    assert isinstance(fed, dict)
    assert fed["commands"] >= 1  # what the script said, fed at its times


@pytest.mark.slow
def test_a_run_with_faults_replays_its_faults(tmp_path: Path) -> None:
    # A femur that goes silent (the bus stops the robot), the board's cable out and back,
    # corrupted frames, the IMU unplugged: all of it is in the bytes, and replays.
    from whexar.sim.faults import SensorFault

    path = tmp_path / "faults.mcap"
    sensor_faults = [
        SensorFault(at_s=0.8, kind="unplug", device="board", duration_s=0.5),
        SensorFault(at_s=1.6, kind="corrupt", frames=2),
        SensorFault(at_s=0.5, kind="unplug", device="imu", duration_s=0.4),
    ]
    simulate(
        commands=COMMANDS,
        duration=DURATION_S,
        faults=ROOT / "config" / "faults" / "dead-femur.toml",
        sensor_faults=sensor_faults,
        record=path,
    )
    directions = {
        r.value.direction for r in Recording(path).records(["/links/sensors", "/links/imu"])
    }
    assert {"gone", "open", "error"} <= directions
    result = replay(path, check=True)
    assert result.divergence is None, result.divergence.describe()
    assert "0 differing, 0 waits not recorded" in result.links["bus"]


def test_what_cannot_be_replayed_says_why(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bare = tmp_path / "bare.mcap"
    Recorder(bare).close()
    assert main(["replay", str(bare)]) == 2
    assert "holds no wiring" in capsys.readouterr().err
    assert main(["replay", str(tmp_path / "missing.mcap")]) == 2


@pytest.mark.slow
@pytest.mark.parametrize("check", [False, True])
def test_a_message_that_cannot_be_read_mid_replay_is_an_error_not_a_silent_end(
    recorded: Path, monkeypatch: pytest.MonkeyPatch, check: bool
) -> None:
    # The recording is read while the actors run, inside the bus's calls to its port:
    # an error there must not pass for the bus's own, nor end the replay quietly.
    made = Recording._made
    count = [0]

    def failing(self: Recording, item: Any, channels: Any, decode: bool) -> Any:
        count[0] += 1
        if count[0] == 500:
            raise RecordingError("a message does not fit its type (a test)")
        return made(self, item, channels, decode)

    monkeypatch.setattr(Recording, "_made", failing)
    with pytest.raises(RecordingError, match="does not fit its type"):
        replay(recorded, check=check)


def test_the_comparison_names_the_field() -> None:
    from whexar.actors.messages import BodyTilt

    def tilt(roll: float, pitch: float) -> BodyTilt:
        return BodyTilt(
            t=1.0,
            source="imu",
            seq=3,
            sensor="imu",
            roll_rad=roll,
            pitch_rad=pitch,
            accel_g=(0.0, 0.0, 1.0),
        )

    assert compare(tilt(0.1, 0.2), tilt(0.1 + 1e-12, 0.2)) is None  # within the tolerance
    assert compare(tilt(0.1, 0.2), tilt(0.1, 0.25), "BodyTilt") == ("BodyTilt.pitch_rad", 0.2, 0.25)
    assert compare(["replay:bus x"], ["emulator:sim x"]) is not None
    assert (
        compare(["emulator:sim x"], ["replay:bus x"], aliases={"replay:bus": "emulator:sim"})
        is None
    )
    text = Divergence("message", "tilt", 1.0, "BodyTilt.pitch", "0.2", "0.25").describe()
    assert text.startswith("diverged at t = 1.000000 s on tilt: BodyTilt.pitch differs")


def test_equal_messages_compare_at_once_and_every_field_counts() -> None:
    """``compare`` first asks ``==``: what it finds equal must be what the field walk
    finds equal, so no message type may leave a field out of ``==``; NaN, and int
    against float, still go through the walk."""
    import dataclasses

    from whexar.runtime.messages import MESSAGE_TYPES

    for name, kind in MESSAGE_TYPES.items():
        skipped = [f.name for f in dataclasses.fields(kind) if not f.compare]
        assert not skipped, f"{name}: fields left out of ==: {skipped}"
    assert compare((1.0, math.nan), (1.0, math.nan)) is None
    assert compare({"a": [1, 2.0]}, {"a": [1.0, 2]}) is None
    assert compare([1], (1,)) == ("", [1], (1,))


def test_the_command_line_tolerance_is_the_replays() -> None:
    from whexar.cli import replay as cli_replay
    from whexar.record.replay import FLOAT_TOLERANCE

    assert cli_replay.FLOAT_TOLERANCE == FLOAT_TOLERANCE
    assert compare(1.0, 1.0 + 1e-6) is not None
    assert compare(1.0, 1.0 + 1e-6, tolerance=1e-5) is None


@pytest.mark.slow
def test_a_replay_serves_the_live_view_and_can_be_paced(
    recorded: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    again = tmp_path / "again.mcap"
    args = ["replay", str(recorded), "--to", "1", "--speed", "50", "--live", "0"]
    assert main([*args, "--record", str(again)]) == 0
    assert "live view: ws://127.0.0.1:" in capsys.readouterr().err
    # The replay's own recording is a recording like any other: it replays too.
    assert Recording(again).metadata["run"]["kind"] == "replay"
    assert replay(again, check=True).divergence is None
