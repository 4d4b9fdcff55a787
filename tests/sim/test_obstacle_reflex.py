"""The obstacle reflex in the simulated world (4.2.2, 6.7.4): a tripod walk toward a box
stops before it, measures it with the rangefinders by sweeping the trochanters, and
climbs it with a higher step; toward a wall it stops and lets nothing go forward until
the operator has sidestepped clear of it, then walks on."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

from whexar.actors.messages import ReflexActivity, ReflexRequest
from whexar.sim.run import SimResult
from whexar.sim.scenario import parse_scenario

pytestmark = pytest.mark.slow  # two walks on the full runtime, 34 s and 24 s

FACE_X_M = 1.3
"""Where the box's or the wall's face is."""


def walk(
    tmp_path: Path, block: dict[str, Any], commands: list[dict[str, Any]], duration_s: float
) -> tuple[SimResult, list[tuple[float, float, float]]]:
    config = tmp_path / "obstacle.toml"
    config.write_text('[[reflexes]]\ntype = "obstacle"\n')
    doc = {
        "name": "obstacle",
        "description": "A tripod walk toward an obstacle, the obstacle reflex running.",
        "duration_s": duration_s,
        "seed": 0,
        "terrain": {"base": "flat", "blocks": [block]},
        "config": str(config),
        "commands": commands,
    }
    path: list[tuple[float, float, float]] = []
    result = parse_scenario(doc).run(
        on_sample=lambda s, w: path.append((s.t, s.x, s.y)), keep_log=True
    )
    assert result.summary()["falls"] == 0
    return result, path


def at(path: list[tuple[float, float, float]], t: float) -> tuple[float, float]:
    _, x, y = min(path, key=lambda p: abs(p[0] - t))
    return x, y


def test_a_box_is_measured_then_climbed(tmp_path: Path) -> None:
    box = {"size_mm": [300.0, 1500.0, 80.0], "at_m": [FACE_X_M + 0.15, 0.0]}
    result, path = walk(tmp_path, box, [{"t": 3.0, "gait": "tripod", "vx_m_s": 0.1}], 34.0)
    asked = result.run.log.messages(of=ReflexRequest)
    halt = next(r for r in asked if r.halt)
    # Stopped well before it: the rangefinders (0.35 m ahead of the centre) 0.6 m away.
    assert at(path, halt.t)[0] + 0.35 < FACE_X_M - 0.45
    climb = next(r for r in asked if r.step_height_m)
    height_cm = int(re.search(r"(\d+) cm high", climb.reason).group(1))  # type: ignore[union-attr]
    assert 7 <= height_cm <= 10
    assert climb.step_height_m == pytest.approx(height_cm / 100 + 0.03, abs=0.006)
    assert path[-1][1] > FACE_X_M + 0.3 + 0.3  # the body over the box and beyond it


def test_a_wall_is_kept_off_until_the_operator_sidesteps_clear(tmp_path: Path) -> None:
    # 40 cm high: above the highest ray of the sweep; its left end at y = 0.
    wall = {"size_mm": [200.0, 1500.0, 400.0], "at_m": [FACE_X_M + 0.1, -0.75]}
    commands: list[dict[str, Any]] = [
        {"t": 3.0, "gait": "tripod", "vx_m_s": 0.1},
        {"t": 15.0, "vy_m_s": 0.06},  # the operator steers left, still asking forward
    ]
    result, path = walk(tmp_path, wall, commands, 26.0)
    asked = result.run.log.messages(of=ReflexRequest)
    blocked = next(r for r in asked if r.block_ahead)
    assert "keeping off" in blocked.reason
    held = at(path, blocked.t + 0.5)[0]
    assert at(path, 15.0)[0] == pytest.approx(held, abs=0.02)  # nothing went forward
    freed = next(r for r in asked if r.block_ahead is False)
    assert freed.t > 15.0
    x, y = at(path, freed.t)
    assert y > 0.1  # sidestepped
    assert path[-1][1] > x + 0.15  # then on forward
    spells = [a for a in result.run.log.messages(of=ReflexActivity) if a.active]
    assert len(spells) == 1
