"""The thesis's slopes in the world: the trochanter carries the feet under the centre of
mass (eq. 4.7–4.18; kinematics.leg.trochanter_arc), so on 32° the legs share the load."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from whexar.sim.run import Sample, simulate
from whexar.sim.terrain import slope
from whexar.sim.world import SimWorld

pytestmark = pytest.mark.slow  # a few simulated seconds each, on the full runtime


def _pair_loads(config: str | None) -> np.ndarray:
    """Front, middle and rear legs' mean normal forces (N) standing on 32°, 6–8 s (stood
    up by 2.4 s, the trochanters settled through their 1 s low-pass)."""
    seen: list[list[float]] = []

    def on_sample(sample: Sample, world: SimWorld) -> None:
        if 6.0 <= sample.t <= 8.0:
            seen.append(list(world.contact_forces))

    result = simulate(terrain=slope(32), duration=8.0, config=config, on_sample=on_sample)
    assert result.summary()["falls"] == 0
    legs = np.mean(seen, axis=0)  # RF, LF, RM, LM, RR, LR
    return np.array([legs[0] + legs[1], legs[2] + legs[3], legs[4] + legs[5]])


def test_standing_on_32_degrees_with_the_trochanter_the_legs_share_the_load() -> None:
    pairs = _pair_loads(None)
    assert np.all(np.abs(pairs / pairs.mean() - 1.0) <= 0.30), pairs


def test_without_the_trochanter_the_rear_legs_carry_most(tmp_path: Path) -> None:
    config = tmp_path / "no-trochanter.toml"
    config.write_text("[locomotion]\ntrochanter_follows_pitch = false\n")
    front, _, rear = _pair_loads(str(config))
    assert rear > 3 * front


def test_standing_settles_below_the_current_of_walking() -> None:
    # Position-held legs used to push each other through the ground: standing drew more
    # than walking (the slopes note: 11 A). The settling stance relaxes what they exchange.
    from whexar.testing.walk import command

    def mean_supply(result_samples: list[Sample], t0: float, t1: float) -> float:
        window = [s.supply_a for s in result_samples if t0 <= s.t <= t1]
        return sum(window) / len(window)

    stand = simulate(duration=8.0)
    walk = simulate(commands=[(3.0, command(gait="tripod", vx_m_s=0.12))], duration=12.0)
    standing, walking = mean_supply(stand.samples, 5.0, 8.0), mean_supply(walk.samples, 6.0, 12.0)
    assert standing < walking, (standing, walking)
