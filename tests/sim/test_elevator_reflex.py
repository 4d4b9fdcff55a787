"""The elevator reflex in the simulated world: a tripod walk at the default 6 cm step into
the 6 cm sill of the obstacles terrain stops there for good; with the elevator its
blocked swings raise the step and it walks on over the sill."""

from __future__ import annotations

from pathlib import Path

import pytest

from whexar.sim.scenario import parse_scenario

pytestmark = pytest.mark.slow  # two 24 s walks on the full runtime

SILL_X_M = 1.2
"""Where the obstacles terrain's sill is (whexar.sim.terrain.obstacles)."""


def walk(tmp_path: Path, *, elevator: bool) -> tuple[float, int]:
    """The body's x at the end, and the falls."""
    doc = {
        "name": "sill",
        "description": "A tripod walk at the default step into the 6 cm sill.",
        "duration_s": 24.0,
        "seed": 0,
        "terrain": "obstacles",
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
