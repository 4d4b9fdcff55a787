"""The elevator reflex in the simulated world: a tripod walk at the default 6 cm step into
an 8 cm sill, higher than the step, stops there for good; with the elevator its blocked
swings raise the step and it walks on over the sill. A light 6 cm sill (0.3 kg) is pushed
away by the feet it meets: the elevator does not fire, as the thesis's did not on light
obstacles (6.7.2). (A fixed 6 cm sill the tripod climbs without the elevator: its feet
stand on the sill's edge where they stop.)"""

from __future__ import annotations

from pathlib import Path

import pytest

from whexar.actors.messages import ReflexActivity, SwingEnded
from whexar.sim.scenario import parse_scenario

pytestmark = pytest.mark.slow  # three 24 s walks on the full runtime

SILL_X_M = 1.2
"""Where the sill stands across the path, m."""


def walk(tmp_path: Path, *, elevator: bool) -> tuple[float, int]:
    """The body's x at the end, and the falls."""
    doc = {
        "name": "sill",
        "description": "A tripod walk at the default step into an 8 cm sill.",
        "duration_s": 24.0,
        "seed": 0,
        "terrain": {
            "base": "flat",
            "blocks": [{"size_mm": [40.0, 1500.0, 80.0], "at_m": [SILL_X_M, 0.0]}],
        },
        "commands": [{"t": 3.0, "gait": "tripod", "vx_m_s": 0.1}],
    }
    if elevator:
        config = tmp_path / "elevator.toml"
        config.write_text('[[reflexes]]\ntype = "elevator"\n')
        doc["config"] = str(config)
    xs: list[float] = []
    result = parse_scenario(doc).run(on_sample=lambda s, w: xs.append(s.x))
    return xs[-1], result.summary()["falls"]


def test_blocked_swings_raise_the_step_and_the_walk_goes_over_the_sill(tmp_path: Path) -> None:
    x, falls = walk(tmp_path, elevator=False)
    assert x < SILL_X_M - 0.15  # stopped in front of it
    x, falls = walk(tmp_path, elevator=True)
    assert falls == 0
    assert x > SILL_X_M + 0.3  # the body over it, and on


def test_a_light_sill_is_pushed_away_and_the_elevator_does_not_fire(tmp_path: Path) -> None:
    config = tmp_path / "elevator.toml"
    config.write_text('[[reflexes]]\ntype = "elevator"\n')
    sill = {"size_mm": [40.0, 1500.0, 60.0], "at_m": [SILL_X_M, 0.0], "mass_kg": 0.3}
    doc = {
        "name": "light-sill",
        "description": "A tripod walk into a 6 cm sill of 0.3 kg.",
        "duration_s": 24.0,
        "seed": 0,
        "terrain": {"base": "flat", "blocks": [sill]},
        "config": str(config),
        "commands": [{"t": 3.0, "gait": "tripod", "vx_m_s": 0.1}],
    }
    xs: list[float] = []
    result = parse_scenario(doc).run(on_sample=lambda s, w: xs.append(s.x), keep_log=True)
    log = result.run.log
    # A foot met it on its way up, and pushed it: no raise.
    assert [s for s in log.messages(of=SwingEnded) if s.outcome == "blocked"]
    assert not [a for a in log.messages(of=ReflexActivity) if a.active]
    assert result.summary()["falls"] == 0
    assert xs[-1] > SILL_X_M + 0.3
