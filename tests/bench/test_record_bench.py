"""``whexar bench record`` measures a recorded run against a plain one."""

from __future__ import annotations

import ast
import math
import shutil
import sys

import pytest

from whexar.bench import record, replay
from whexar.bench.record import count_instructions, instructions, measure


@pytest.mark.slow
def test_the_bench_compares_a_recorded_run_with_a_plain_one() -> None:
    found = measure(seconds=1.0, repeats=1)
    assert math.isfinite(found["overhead_cpu_pct"])
    assert found["cpu_s_with"] > 0
    assert found["cpu_s_without"] > 0
    assert 0 < found["max_cycle_delay_ms"] < 1000
    assert found["bytes_per_s"] > 10_000  # 42 servos at about 100 Hz, and their bytes
    # The runtime's own share, counted: every hand-over and every packing between cycles.
    assert found["handovers"] > 1000
    assert 0 < found["handover_us"] < 100
    assert 0 < found["direct_pct"] < 100
    assert found["writer_process_cpu_pct"] > 0  # the recording process did the writing


@pytest.mark.slow
def test_the_replay_bench_replays_a_recorded_run_as_fast_as_it_goes() -> None:
    found = replay.measure(seconds=1.0, repeats=1)
    assert found["replayed_s"] == 1.0
    assert found["replay_realtime_factor"] > 0
    assert found["replay_check_wall_s"] > 0  # and it agreed with the recording: no raise


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("valgrind") is None, reason="Valgrind is not installed")
def test_valgrind_counts_a_commands_instructions() -> None:
    empty = instructions([sys.executable, "-c", "pass"])
    busy = instructions([sys.executable, "-c", "sum(range(10**6))"])
    assert 10**7 < empty < busy  # an interpreter's start-up is tens of millions
    with pytest.raises(RuntimeError, match="failed"):
        instructions([sys.executable, "-c", "raise SystemExit(3)"])


def _probed(command: list[str]) -> tuple[float, bool]:
    """The arguments of the ``_probe`` call a Valgrind command runs."""
    seconds, recorded = ast.literal_eval(command[-1].rsplit("_probe", 1)[1])
    assert isinstance(seconds, float)
    assert isinstance(recorded, bool)
    return seconds, recorded


def test_the_instruction_count_is_per_second_of_the_longer_runs(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """What both lengths share cancels out: only the seconds between them count."""
    per_s = {False: 1_000_000, True: 1_040_000}
    start_up = {False: 5_000_000, True: 9_000_000}  # the recording's start-up is dearer

    def fake(command: list[str]) -> int:
        seconds, recorded = _probed(command)
        return start_up[recorded] + round(seconds * per_s[recorded])

    monkeypatch.setattr(record, "instructions", fake)
    monkeypatch.setattr(shutil, "which", lambda _: "/usr/bin/valgrind")
    found = count_instructions(seconds=10.0, base_s=2.0)
    assert found == {
        "instructions_pct": 4.0,
        "instructions_per_s_without": 1_000_000,
        "instructions_per_s_with": 1_040_000,
    }
    monkeypatch.setattr(shutil, "which", lambda _: None)
    assert count_instructions() is None


def test_a_probe_that_ends_early_is_run_again(monkeypatch: pytest.MonkeyPatch) -> None:
    """Under Valgrind MuJoCo's XML parser now and then refuses the model: such a probe
    is run again (and said), up to ``PROBE_ATTEMPTS`` runs."""
    failures = {"left": 3}

    def flaky(command: list[str]) -> int:
        if failures["left"]:
            failures["left"] -= 1
            raise RuntimeError("valgrind … failed (exit status 1): XML Error")
        seconds, _ = _probed(command)
        return round(seconds * 1_000_000)

    said: list[str] = []
    monkeypatch.setattr(record, "instructions", flaky)
    monkeypatch.setattr(shutil, "which", lambda _: "/usr/bin/valgrind")
    found = count_instructions(seconds=10.0, base_s=2.0, progress=said.append)
    assert found is not None
    assert found["instructions_pct"] == 0.0
    assert sum("again" in line for line in said) == 3
    failures["left"] = 10**6  # never gets through: the count says so
    with pytest.raises(RuntimeError, match="XML Error"):
        count_instructions(seconds=10.0, base_s=2.0)
