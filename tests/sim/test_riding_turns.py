"""Riding a circle in the simulation: the wheels roll where they are, and do not fight.

Under the body's weight the legs sag (their servos hold a position error), so the wheels
stand inward of the feet the legs were asked for, the middle right one by 4 cm. The
coordinator steers and drives the wheels for where they are (the legs' measured feet).
Driven for the commanded feet, the wheels scrubbed against each other through the legs on
a 0.6 m circle, and the servos drew 1.9× the current of riding straight over 8–12 s
(1.2× now; 2.7× over 10–16 s, as the scrubbing built up).

The settling stance (actors.locomotion.settle) relaxes the legs before the ride and lowers
both currents, riding straight most (winding 7.8 → 4.0 A, the circle 8.3 → 6.4 A): the
test holds it off, to judge the wheels alone.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from whexar.sim.run import Sample
from whexar.sim.scenario import parse_scenario
from whexar.sim.world import SimWorld


def _mean_current(command: dict[str, object], folder: Path) -> float:
    """Σ|I| of the 42 servos (A), mean over 8–12 s of a ride from 3 s, not settled."""
    (folder / "held.toml").write_text("[locomotion]\nsettle_s = 0.0\n")
    scenario = parse_scenario(
        {
            "duration_s": 12.0,
            "terrain": "flat",
            "commands": [{"t": 3.0, **command}],
            "config": "held.toml",
        },
        base=folder,
    )
    totals: list[float] = []

    def sample(s: Sample, world: SimWorld) -> None:
        if s.t >= 8.0:
            totals.append(float(np.abs(world._amps).sum()))

    scenario.run(on_sample=sample)
    assert len(totals) > 50
    return sum(totals) / len(totals)


@pytest.mark.slow
def test_on_a_circle_the_wheels_do_not_fight_each_other(tmp_path: Path) -> None:
    straight = _mean_current({"mode": "ride", "vx_m_s": 0.2}, tmp_path)
    circle = _mean_current({"mode": "ride", "vx_m_s": 0.2, "turn_radius_m": 0.6}, tmp_path)
    assert circle < 1.5 * straight, (circle, straight)
