"""``whexar bench fieldbus`` replays a log made on a real clock against the field bus."""

from __future__ import annotations

import pytest

from whexar.bench import fieldbus


@pytest.mark.slow
@pytest.mark.serial  # a log of real time, its replay timed on the wall clock
def test_the_field_bench_replays_a_real_time_log_and_prices_its_transactions() -> None:
    found = fieldbus.measure(seconds=1.0, repeats=1)
    assert found["recorded_packets"] > 50  # some hundred a second over the pty
    assert found["replay_realtime_factor"] > 1
    assert 0 < found["mover_us"] < found["field_chain_us"] * 10
    assert found["field_chain_us"] > 0
    assert found["emulator_us"] > 0
