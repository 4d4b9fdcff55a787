"""A ramp up to 30° in the simulated world, walked with the elevator and the obstacle
reflexes running: the rangefinders see the ramp and the obstacle reflex calls it a slope,
the trochanters follow the pitch up it (eq. 4.18), and the elevator fires only where a
swing meets the ramp's foot or the crest beyond the plateau — never on the ramp itself
(6.7.2's false triggers)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from whexar.actors.messages import BodyMotion, ReflexActivity, ReflexRequest
from whexar.sim.scenario import parse_scenario

pytestmark = pytest.mark.slow  # a 55 s walk on the full runtime

FOOT_X_M = 1.0
"""Where the ramp starts; it rises 0.5 m at 30°, to a plateau from x = 1.87 m."""
CREST_X_M = FOOT_X_M + 0.5 / math.tan(math.radians(30.0)) + 1.0
"""Where the plateau ends and the ground goes down again at 30°."""
REACH_M = 0.4
"""How far ahead of the body's centre the front feet step (the default stance)."""


def test_up_a_30_degree_ramp_the_legs_follow_and_no_false_elevator(tmp_path: Path) -> None:
    config = tmp_path / "reflexes.toml"
    config.write_text('[[reflexes]]\ntype = "elevator"\n\n[[reflexes]]\ntype = "obstacle"\n')
    doc = {
        "name": "ramp30",
        "description": "A tripod walk up a 30° ramp, the elevator and obstacle reflexes on.",
        "duration_s": 55.0,
        "seed": 0,
        "terrain": {
            "base": "flat",
            "ramp": {"angle_deg": 30.0, "rise_mm": 500.0, "at_m": FOOT_X_M, "plateau_m": 1.0},
        },
        "config": str(config),
        "commands": [{"t": 3.0, "gait": "tripod", "vx_m_s": 0.1}],
    }
    path: list[tuple[float, float]] = []
    result = parse_scenario(doc).run(on_sample=lambda s, w: path.append((s.t, s.x)), keep_log=True)
    assert result.summary()["falls"] == 0
    assert path[-1][1] > FOOT_X_M + 0.87  # up on the plateau
    log = result.run.log

    def x_at(t: float) -> float:
        return min(path, key=lambda p: abs(p[0] - t))[1]

    # The trochanters follow the pitch up the ramp (nose up is a negative pitch).
    motion = log.messages(of=BodyMotion)
    assert min(math.degrees(m.trochanter_rad) for m in motion) < -25.0
    # The elevator: only where a swing met the ramp's foot, the body still before it, or
    # where the front feet go over the crest and the body tips down after them — never
    # on the ramp itself or the plateau.
    fired = [a for a in log.messages(of=ReflexActivity) if a.active]
    elevator = [a for a in fired if a.reflex.endswith("elevator")]
    assert all(x_at(a.t) < FOOT_X_M + 0.3 or x_at(a.t) > CREST_X_M - REACH_M for a in elevator), [
        (a.t, x_at(a.t)) for a in elevator
    ]
    # The obstacle reflex measured the ramp as a slope and kept nothing off.
    asked = log.messages(of=ReflexRequest)
    assert any(r.reason == "a slope ahead" for r in asked)
    assert not any(r.block_ahead for r in asked)
