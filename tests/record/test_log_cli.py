"""`whexar log info` and `whexar log recover` on recordings, whole and cut short."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

from whexar.cli import main
from whexar.record.reader import Recording
from whexar.record.writer import Recorder
from whexar.runtime.messages import ActorFailed, ActorStarting

if TYPE_CHECKING:
    from tests.record.conftest import RecordedRun


def test_info_tells_duration_channels_rates_gaps_and_completeness(
    recorded_run: RecordedRun, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["log", "info", str(recorded_run.path)]) == 0
    out = capsys.readouterr().out
    assert "recorded by whexar" in out
    assert "\ncomplete\n" in out
    assert "run: robot = WHexaR, command = pytest" in out
    assert "attachments: wiring.toml" in out
    lines = out.splitlines()
    (state,) = [line for line in lines if line.startswith("/state ")]
    fields = state.split()
    assert fields[1] == "ServoStates"
    assert int(fields[2]) > 10
    assert 20 < float(fields[3]) < 200  # a bus cycle every few ms of bus time
    assert "s at t = " in state  # the longest gap
    assert any(line.startswith("/links/bus ") for line in lines)
    assert "errors: none" in out
    assert "recorder: 0 dropped" in out


def test_info_quotes_errors_and_says_where_a_cut_file_ends(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "failing.mcap"
    with Recorder(path) as recorder:
        recorder("events", ActorStarting(t=0.1, source="runtime", actor="bus", incarnation=0))
        for i in range(3):
            recorder(
                "events",
                ActorFailed(
                    t=1.0 + i,
                    source="runtime",
                    actor="bus",
                    incarnation=i,
                    phase="run",
                    error="OSError: port gone",
                    traceback="Traceback …\nOSError: port gone",
                ),
            )
    assert main(["log", "info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "events: 4 (3 error, 1 info)" in out
    assert "errors: 3" in out
    assert "t = 1.000 s  ERROR  ActorFailed: actor='bus', incarnation=0, phase='run'" in out
    assert "      OSError: port gone" in out

    cut = tmp_path / "cut.mcap"
    data = path.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    assert main(["log", "info", str(cut)]) == 0
    out = capsys.readouterr().out
    assert "the recording ends early: readable up to byte" in out

    assert main(["log", "info", "--json", str(path)]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["complete"] is True
    assert info["problem_count"] == 3
    assert {c["schema"] for c in info["channels"]} == {
        "ActorStarting",
        "ActorFailed",
        "foxglove.Log",
    }


def test_recover_rewrites_a_cut_file_and_says_what_it_saved(
    recorded_run: RecordedRun, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cut = tmp_path / "run.mcap"
    data = recorded_run.path.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    assert main(["log", "recover", str(cut)]) == 0
    captured = capsys.readouterr()
    assert "the recording ends early" in captured.err
    assert captured.out.startswith("recovered ")
    fixed = tmp_path / "run.recovered.mcap"
    assert Recording(fixed).complete
    assert main(["log", "recover", str(fixed)]) == 0
    assert "is complete: nothing to recover" in capsys.readouterr().out


def test_a_file_that_is_not_a_recording_is_bad_input(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "notes.mcap"
    path.write_text("not a recording\n")
    assert main(["log", "info", str(path)]) == 2
    assert "not an MCAP file" in capsys.readouterr().err
    assert main(["log", "recover", str(tmp_path / "none.mcap")]) == 2
    assert "cannot read" in capsys.readouterr().err
