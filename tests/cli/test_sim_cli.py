"""``whexar sim`` from the command line: the JSON summary, the report and video, bad input."""

from __future__ import annotations

import json
from pathlib import Path

import imageio.v2 as imageio
import pytest

from whexar.cli import main
from whexar.cli.sim import SUMMARY_KEYS


@pytest.mark.slow
def test_json_prints_exactly_the_summary_keys(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    report, video = tmp_path / "report", tmp_path / "run.mp4"
    args = ["sim", "--scenario", "wheels", "--duration", "2", "--json", "--no-record"]
    assert main([*args, "--report", str(report), "--video", str(video)]) == 0
    out, err = capsys.readouterr()
    summary = json.loads(out)
    assert tuple(summary) == SUMMARY_KEYS
    assert summary["sim_seconds"] == 2.0
    assert summary["falls"] == 0
    assert len(summary["state_hash"]) == 64
    assert summary["realtime_factor"] > 0
    assert "report:" in err
    assert "recording:" not in err
    assert (report / "gait.png").is_file()
    assert (report / "summary.md").is_file()
    frames = imageio.mimread(video, memtest=False)
    assert len(frames) >= 30  # 20 fps over about 2 s of samples
    assert frames[0].shape == (480, 640, 3)


@pytest.mark.slow
def test_text_summary_names_the_figures_and_the_recording(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)  # recorded by default, under recordings/
    monkeypatch.delenv("WHEXAR_RECORDINGS")
    assert main(["sim", "--scenario", "slope", "--duration", "1", "--seed", "3"]) == 0
    out, err = capsys.readouterr()
    assert out.startswith("whexar sim: slope")
    for label in ("progress", "path length", "cost of transport", "falls", "state hash"):
        assert label in out
    (recording,) = (tmp_path / "recordings").glob("slope-*.mcap")
    assert f"recording: {recording.relative_to(tmp_path)}" in err
    assert main(["sim", "--scenario", "slope", "--duration", "0.5", "--record", "x.mcap"]) == 0
    assert (tmp_path / "x.mcap").stat().st_size > 0


def test_a_bad_scenario_lists_its_problems_and_exits_1(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text(
        'duration_s = 5\nwind = 3\n[[commands]]\nt = 1\ngait = "gallop"\n', encoding="utf-8"
    )
    assert main(["sim", "--scenario", str(bad)]) == 1
    err = capsys.readouterr().err
    assert "2 problems" in err
    assert "wind" in err
    assert "commands[0].gait = 'gallop'" in err
    assert main(["sim", "--scenario", "no-such-scenario"]) == 1
    assert "course" in capsys.readouterr().err


def test_view_without_a_display_is_a_clear_error(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["sim", "--view", "--duration", "1", "--no-record"]) == 2
    assert "display" in capsys.readouterr().err


def test_bad_options_are_refused(capsys: pytest.CaptureFixture[str]) -> None:
    for args in (["--duration", "0"], ["--seed", "-1"]):
        with pytest.raises(SystemExit) as info:
            main(["sim", *args])
        assert info.value.code == 2
    capsys.readouterr()


@pytest.mark.slow
def test_bench_sim_splits_a_bus_cycle_four_ways_and_removes_its_timers() -> None:
    from whexar.bench.sim import measure
    from whexar.bus.sdk import InlinePortOwner
    from whexar.sim.world import SimWorld

    before = (SimWorld.advance_to, SimWorld._sense, InlinePortOwner.call)
    found = measure(seconds=1.0)
    assert (SimWorld.advance_to, SimWorld._sense, InlinePortOwner.call) == before
    assert found["realtime_factor"] > 0
    parts = found["cpu_ms_per_cycle"]
    assert set(parts) == {"bus", "actors", "physics", "sensors"}
    assert all(value > 0 for value in parts.values())
    assert found["cycles"] > 50  # about 110 bus cycles a second


def test_the_terminal_summary_lines_its_values_up() -> None:
    from whexar.cli.sim import summary_text

    summary = dict.fromkeys(SUMMARY_KEYS, 1.0) | {"state_hash": "ab" * 32, "falls": 0}
    lines = summary_text("course", summary).splitlines()[1:]
    assert len(lines) == len(SUMMARY_KEYS)
    # Every value starts in one column, at least two spaces after the longest label.
    starts = {len(line) - len(line.rstrip().split("  ")[-1].lstrip()) for line in lines}
    assert len(starts) == 1
    assert all("  " in line.strip() for line in lines)
    assert summary_text("course", summary).splitlines()[0] == "whexar sim: course"
    header = summary_text("course", summary, Path("robot.toml")).splitlines()[0]
    assert header == "whexar sim: course, robot configuration robot.toml"
