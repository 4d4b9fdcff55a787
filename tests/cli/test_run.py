"""``whexar run`` and ``whexar bench runtime`` from the command line."""

from __future__ import annotations

from pathlib import Path

import pytest

from whexar.bench.runtime import run as bench_run
from whexar.cli import main
from whexar.runtime.supervisor import EXIT_ESCALATED

DEMO = Path(__file__).resolve().parents[2] / "config" / "graphs" / "demo.toml"


def test_demo_graph_runs_on_virtual_time_and_stops_in_reverse_order(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["run", str(DEMO), "--virtual", "--duration", "12"]) == 0
    out = capsys.readouterr().out
    stopped = [
        line.split("actor=")[1].split(",")[0] for line in out.splitlines() if "ActorStopped" in line
    ]
    assert stopped == ["'flaky'", "'monitor'", "'heart'"]
    assert "ActorEscalated" not in out
    assert out.count("ActorRestarted") == 2  # it healed at t = 5 s
    assert "stopped: duration 12 s elapsed" in out
    assert "channel beats:" in out
    assert "dropped for monitor" in out


def test_escalation_exits_with_its_own_status(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    graph = tmp_path / "escalates.toml"
    graph.write_text(DEMO.read_text().replace("heal_at_s = 5.0", "heal_at_s = 12.0"))
    assert main(["run", str(graph), "--virtual", "--duration", "20"]) == EXIT_ESCALATED
    out = capsys.readouterr().out
    assert "ActorEscalated  actor='flaky', failures=4" in out
    assert out.index("SafeStop") < out.index("ActorStopped    actor='monitor'")


def test_bad_wiring_exits_1_naming_actor_and_channel(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    graph = tmp_path / "bad.toml"
    graph.write_text(
        DEMO.read_text()
        .replace('inputs = { inp = "beats" }', 'inputs = { inp = "beets" }')
        .replace("whexar.testing:Sink", "whexar.testing:Sunk")
    )
    assert main(["run", str(graph), "--virtual", "--duration", "1"]) == 1
    err = capsys.readouterr().err
    assert "actors.monitor.class = 'whexar.testing:Sunk'" in err
    assert "module 'whexar.testing' has no 'Sunk'" in err


def test_run_refuses_a_non_positive_duration(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["run", str(DEMO), "--duration", "-1"])
    assert exc.value.code == 2
    assert "expected a number of seconds > 0" in capsys.readouterr().err


def test_bench_runtime_reports_the_three_figures() -> None:
    # Small sizes: this checks the benchmark's wiring, not the speed (that is
    # what `whexar bench runtime` is for).
    report = bench_run(messages=2_000, hops=200, virtual_s=2.0, repeats=1)
    assert list(report.figures) == ["messages_per_s", "hop_us", "virtual_60s_wall_s"]
    assert all(value > 0 for value in report.figures.values())
    assert report.items[0].at_least
    assert not report.items[1].at_least
    assert "frozen dataclass" in report.render()
