"""The report of a run: plots from a short real run, segments and the summary tables."""

from __future__ import annotations

import json
from pathlib import Path

import imageio.v2 as imageio
import pytest

from whexar.robot import LEG_NAMES
from whexar.sim.report import (
    PLOTTED_JOINTS,
    joint_traces,
    leg_currents,
    segments,
    summary_markdown,
    swing_intervals,
    write_report,
)
from whexar.sim.run import Sample, SimResult, simulate
from whexar.testing.walk import command

WALK_AT_S = 3.0


@pytest.fixture(scope="module")
def walked() -> SimResult:
    """Stand up, then walk the tripod gait for two seconds."""
    return simulate(commands=[(WALK_AT_S, command(vx_m_s=0.1))], duration=5.0)


@pytest.mark.slow
def test_the_report_folder_has_every_plot_and_both_tables(
    walked: SimResult, tmp_path: Path
) -> None:
    cmds = [(WALK_AT_S, command(vx_m_s=0.1))]
    written = write_report(walked, tmp_path / "report", commands=cmds, name="walk")
    names = {p.name for p in written}
    assert names == {
        "path.png",
        "gait.png",
        "joints.png",
        "current.png",
        "cot.png",
        "summary.json",
        "summary.md",
    }
    for path in written:
        if path.suffix == ".png":
            image = imageio.imread(path)
            assert image.shape[0] > 300
            assert image.shape[1] > 600
    doc = json.loads((tmp_path / "report" / "summary.json").read_text(encoding="utf-8"))
    assert doc["scenario"] == "walk"
    assert set(walked.summary()) <= set(doc)
    assert [s["label"] for s in doc["segments"]] == ["start", "vx 0.1"]
    md = (tmp_path / "report" / "summary.md").read_text(encoding="utf-8")
    assert "| path length (sway included) |" in md
    assert "| progress (start to end) |" in md
    assert "| vx 0.1 |" in md.replace("| 3.0 |", "")


@pytest.mark.slow
def test_walking_legs_swing_and_report_goals_present_angles_and_currents(
    walked: SimResult,
) -> None:
    swings = swing_intervals(walked)
    assert set(swings) == set(range(len(LEG_NAMES)))
    assert all(t1 >= t0 >= WALK_AT_S for spans in swings.values() for t0, t1 in spans)
    assert sum(len(spans) for spans in swings.values()) >= 3
    traces = joint_traces(walked)
    assert set(traces) == set(PLOTTED_JOINTS)
    for goals, present in traces.values():
        assert len(goals) > 10
        assert len(present) > 10
    times, amps = leg_currents(walked)
    assert amps.shape == (len(times), len(LEG_NAMES))
    assert (amps >= 0).all()
    assert amps.max() > 0.1  # standing takes current


def _sample(t: float, x: float, power: float) -> Sample:
    return Sample(t, x, 0.0, 0.3, 0.0, 0.0, 0.0, power)


def test_segments_split_at_command_times_with_cost_of_transport() -> None:
    samples = [_sample(0.1 * k, 0.01 * max(0, k - 20), 100.0) for k in range(61)]
    found = segments(
        samples,
        [(2.0, command(vx_m_s=0.1)), (4.0, command(gait="ripple")), (4.0, command(stop=True))],
        mass_kg=10.0,
    )
    assert [(s.t0, s.t1, s.label) for s in found] == [
        (0.0, 2.0, "start"),
        (2.0, 4.0, "vx 0.1"),
        (4.0, pytest.approx(6.0), "ripple, stop"),
    ]
    start, walk, _ = found
    assert start.distance_m == 0.0
    assert start.cost_of_transport is None  # standing: no distance, no CoT
    assert walk.distance_m == pytest.approx(0.2)
    assert walk.energy_j == pytest.approx(200.0)
    assert walk.mean_power_w == pytest.approx(100.0)
    assert walk.cost_of_transport == pytest.approx(200.0 / (10.0 * 9.81 * 0.2))
    by_time = segments(samples, [], mass_kg=10.0, every_s=2.5)
    assert [s.t0 for s in by_time] == [0.0, 2.5, 5.0]
    assert summary_markdown({"distance_m": 0.4, "falls": 0}, found).count("\n| ") >= 5
