"""``whexar bench cycle``: the suite's wiring, with few cycles (the speed is the bench's job)."""

from __future__ import annotations

import functools
import json

import pytest

from whexar.bench import cycle
from whexar.cli import main


@pytest.mark.slow
def test_bench_cycle_json_has_the_figures(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(cycle, "run", functools.partial(cycle.run, cycles=40, repeats=2))
    main(["bench", "cycle", "--json"])  # the exit status is the target's verdict: not checked
    data = json.loads(capsys.readouterr().out)
    assert data["cpu_ms_per_cycle"] > 0
    assert data["p99_ms"] >= data["cpu_ms_per_cycle"]
    assert data["cycles"] == 40
    assert data["runs"] == 2
    engines = data["engines"]
    assert list(engines) == ["walk", "ride", "hybrid"]
    for name, figures in engines.items():
        assert figures["median_ms"] > 0, name
        assert figures["p99_ms"] > 0, name
        assert figures["legs_ms"] > 0, name  # the breakdown run
        assert figures["coordinator_ms"] > 0, name
        # Every measured cycle was the engine's own, and every leg answered it.
        assert figures["off_activity"] == 0, name
        assert figures["missing_goals"] == 0, name
    # The engines did what they are there for: legs swing, wheels turn.
    assert engines["walk"]["swing_cycles"] > 0
    assert engines["walk"]["rolling_cycles"] == 0
    assert engines["ride"]["swing_cycles"] == 0
    assert engines["ride"]["rolling_cycles"] == 2 * 40
    assert len(engines["walk"]["run_medians_ms"]) == 2
    assert engines["hybrid"]["swing_cycles"] > 0
    assert engines["hybrid"]["rolling_cycles"] > 0


def test_bench_cycle_table_names_the_target() -> None:
    report = cycle.run(cycles=20, repeats=1, breakdown=False)
    assert list(report.figures) == [
        "cpu_ms_per_cycle",
        "ride_cpu_ms_per_cycle",
        "hybrid_cpu_ms_per_cycle",
    ]
    assert all(f.target == cycle.CYCLE_TARGET_MS and not f.at_least for f in report.items)
    text = report.render()
    assert "tripod walk" in text
    assert "where it goes" not in text  # no breakdown asked for
