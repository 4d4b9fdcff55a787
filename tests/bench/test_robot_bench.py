"""``whexar bench robot`` measures the whole controller on real time, bus over a pty."""

from __future__ import annotations

import math
import os

import pytest

from whexar.bench import robot


@pytest.mark.slow
@pytest.mark.serial  # bus cycles counted on the wall clock
@pytest.mark.skipif(os.name != "posix", reason="needs a pseudo-terminal")
def test_the_bench_runs_the_robot_graph_and_counts_its_cycles() -> None:
    report = robot.run(seconds=1.0)
    figures = report.figures
    assert set(figures) == {"core_pct", "cpu_ms_per_cycle", "cycle_hz"}
    assert 0 < figures["core_pct"] < 200  # one process: at most its threads' share
    assert math.isfinite(figures["cpu_ms_per_cycle"])
    assert figures["cpu_ms_per_cycle"] > 0
    # A second of walking on a 1 Mbps bus: tens of cycles, not a handful.
    assert figures["cycle_hz"] > 20
    assert "cycles over 1 s of walking" in report.notes[0]
