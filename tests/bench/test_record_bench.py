"""``whexar bench record`` measures a recorded run against a plain one."""

from __future__ import annotations

import math

from whexar.bench import replay
from whexar.bench.record import measure


def test_the_bench_compares_a_recorded_run_with_a_plain_one() -> None:
    found = measure(seconds=1.0, repeats=1)
    assert math.isfinite(found["overhead_pct"])
    assert found["cpu_s_with"] > 0
    assert found["cpu_s_without"] > 0
    assert 0 < found["max_cycle_delay_ms"] < 1000
    assert found["bytes_per_s"] > 10_000  # 42 servos at about 100 Hz, and their bytes
    # The runtime's own share, counted: every hand-over and every packing between cycles.
    assert found["handovers"] > 1000
    assert 0 < found["handover_us"] < 100
    assert 0 < found["direct_pct"] < 100
    assert found["writer_process_cpu_pct"] > 0  # the recording process did the writing


def test_the_replay_bench_replays_a_recorded_run_as_fast_as_it_goes() -> None:
    found = replay.measure(seconds=1.0, repeats=1)
    assert found["replayed_s"] == 1.0
    assert found["replay_realtime_factor"] > 0
    assert found["replay_check_wall_s"] > 0  # and it agreed with the recording: no raise
