"""Field logs — the robot's graph recorded on a real clock against the emulator over a pty —
replay by time to their end; unchanged they agree with the recording, changed they do not,
and the report names the joints and the time."""

from __future__ import annotations

import functools
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from whexar.cli import main
from whexar.record.reader import Recording
from whexar.record.replay import ReplayResult, recorded_clock, replay
from whexar.testing.field import ROOT, record_field_log, write_script

# Each log takes as long as it records, on the wall clock, against the emulator over a pty.
pytestmark = [pytest.mark.slow, pytest.mark.serial]

WALK: list[dict[str, object]] = [{"t": 3.0, "vx_m_s": 0.08}]
RIDE: list[dict[str, object]] = [{"t": 3.0, "mode": "ride", "vx_m_s": 0.1}]
FAULTS = ROOT / "config" / "faults"


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> Callable[[str], Path]:
    """Field logs by name, each recorded once for the module."""
    folder = tmp_path_factory.mktemp("field")
    made: dict[str, Path] = {}
    plans: dict[str, tuple[list[dict[str, object]], float, Path | None]] = {
        "walk": (WALK, 6.0, None),
        "ride": (RIDE, 6.0, None),
        "overload": (WALK, 7.0, FAULTS / "overload.toml"),
        "brownout": (WALK, 7.0, FAULTS / "brownout.toml"),  # the supply sags from 5 s to 6 s
    }

    def get(name: str) -> Path:
        if name not in made:
            commands, duration, faults = plans[name]
            script = write_script(folder / f"{name}.jsonl", commands)
            made[name] = record_field_log(
                folder / f"{name}.mcap", script=script, duration_s=duration, faults=faults
            )
        return made[name]

    return get


@pytest.fixture(scope="module")
def checked(logs: Callable[[str], Path]) -> Callable[[str], ReplayResult]:
    """The unchanged replay of each field log with ``--check``, made once for the module."""
    return functools.cache(lambda name: replay(logs(name), check=True))


@pytest.mark.parametrize("name", ["walk", "ride", "overload", "brownout"])
def test_a_field_log_replays_to_its_end_and_agrees_with_itself(
    logs: Callable[[str], Path], checked: Callable[[str], ReplayResult], name: str
) -> None:
    assert recorded_clock(Recording(logs(name))) == "real"
    result = checked(name)
    assert result.clock == "real"
    assert result.ended_early is None, result.ended_early
    assert result.duration_s == pytest.approx(result.recorded_s, abs=0.05)
    assert result.report is not None
    assert result.report.agrees, result.report.table()
    assert result.report.compared > 10_000
    assert result.agrees


def test_the_overload_log_replays_the_servos_fault_and_its_recovery(
    checked: Callable[[str], ReplayResult],
) -> None:
    result = checked("overload")
    assert result.report is not None
    kinds = {e.kind for e in result.report.events}
    assert {"HardwareFault", "ServoRebooted", "ServoRestored"} <= kinds, kinds


def changed(tmp_path: Path, text: str) -> Path:
    config = tmp_path / "changed.toml"
    config.write_text(text)
    return config


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ("[locomotion]\nstep_height_mm = 100.0\n", "position_rad"),
        ("[stances.default]\nheight_mm = 250.0\n", "position_rad"),
        ('[locomotion]\ngait = "ripple"\n', "position_rad"),
    ],
    ids=["step height", "stance height", "gait"],
)
def test_a_changed_configuration_fails_the_check_naming_the_joints_and_the_time(
    logs: Callable[[str], Path], tmp_path: Path, change: str, field: str
) -> None:
    result = replay(logs("walk"), check=True, config=changed(tmp_path, change))
    assert result.ended_early is None
    assert result.report is not None
    assert not result.report.agrees
    first = result.report.first_beyond
    assert first is not None
    assert first.first_beyond_key is not None
    joints = [r for r in result.report.fields if r.field == field and not r.agrees]
    assert joints, result.report.table()
    assert any("joint" in (r.first_beyond_key or "") for r in joints)
    assert first.first_beyond_t is not None
    assert first.first_beyond_t > 0.0


def test_the_command_line_replays_a_field_log_and_draws_the_report(
    logs: Callable[[str], Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "report"
    assert main(["replay", str(logs("walk")), "--check", "--report", str(out)]) == 0
    text = capsys.readouterr().out
    assert "devices       by time (a log of a real clock)" in text
    assert "agree with the recording within tolerance" in text
    assert (out / "joints-RF.png").stat().st_size > 10_000
    assert (out / "events.png").exists()
    # Changed, the report says where: exit 1, the rows beyond tolerance named.
    config = changed(tmp_path, "[locomotion]\nstep_height_mm = 100.0\n")
    code = main(["replay", str(logs("walk")), "--check", "--config", str(config), "--json"])
    assert code == 1
    data = json.loads(capsys.readouterr().out, parse_constant=lambda c: pytest.fail(c))
    assert data["agrees"] is False
    assert data["report"]["agrees"] is False


def test_log_diff_compares_a_log_with_its_replay(
    logs: Callable[[str], Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    again = tmp_path / "again.mcap"
    replay(logs("walk"), record=again)
    assert main(["log", "diff", str(logs("walk")), str(again)]) == 0
    assert "agree within tolerance" in capsys.readouterr().out
    assert main(["log", "diff", str(logs("walk")), str(logs("ride"))]) == 1


def test_a_replay_with_a_set_parameter_and_with_another_graph(
    logs: Callable[[str], Path], tmp_path: Path
) -> None:
    # A parameter changed by --set: RF senses no contact; the check says what moved.
    result = replay(logs("walk"), check=True, sets=[("leg-RF.contact", "none")])
    assert result.ended_early is None
    assert result.report is not None
    moved = {(r.message, r.field) for r in result.report.fields if not r.agrees}
    assert ("LegState", "contact_source") in moved
    graph = tmp_path / "walk.toml"
    shutil.copy(ROOT / "config" / "graphs" / "walk.toml", graph)
    again = replay(logs("walk"), check=True, graph=graph)
    assert again.ended_early is None
    assert again.report is not None
    assert again.report.agrees, again.report.table()


def test_a_field_log_cut_short_replays_up_to_where_it_ends(
    logs: Callable[[str], Path], tmp_path: Path
) -> None:
    data = logs("walk").read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    result = replay(cut, check=True)
    assert result.damage is not None
    assert result.ended_early is None
    assert result.duration_s == pytest.approx(result.recorded_s, abs=0.1)
    assert result.recorded_s < 6.0


def test_a_field_log_of_a_killed_run_replays_up_to_where_it_ends(tmp_path: Path) -> None:
    script = write_script(tmp_path / "walk.jsonl", WALK)
    log = tmp_path / "killed.mcap"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    server = subprocess.Popen(
        [sys.executable, "-m", "whexar.cli", "emulate"],
        stdout=subprocess.PIPE,
        text=True,
        cwd=ROOT,
        env=env,
    )
    try:
        assert server.stdout is not None
        pty = server.stdout.readline().split(" on ", 1)[1].split(" at ")[0]
        run = subprocess.Popen(
            [
                *(sys.executable, "-m", "whexar.cli", "run", "config/graphs/walk.toml"),
                *("--set", f"bus.port={pty}", "--commands", str(script)),
                *("--record", str(log), "--quiet"),
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            cwd=ROOT,
            env=env,
        )
        time.sleep(6.0)
        run.send_signal(signal.SIGKILL)
        run.wait()
    finally:
        server.terminate()
        server.wait()
    result = replay(log, check=True)
    assert 3.0 < result.recorded_s < 7.0
    assert result.ended_early is None
    assert result.report is not None
    assert result.report.agrees, result.report.table()
