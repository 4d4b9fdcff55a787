"""Heading hold in the simulated world: the middle right coxa goes silent during a tripod
walk (its Bus Watchdog holds its last goal); without the reflex the robot veers 24° in
8 s, with it the heading stays within 5° — on a robot whose gyroscope has an unknown
zero-rate level (the spread of real parts, seed 1)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from whexar.sim.scenario import parse_scenario

pytestmark = pytest.mark.slow  # two 16 s walks on the full runtime

COXA_RM = 15


def veer_deg(tmp_path: Path, *, hold: bool) -> float:
    """The largest heading change from the failure (8 s) to the end of the walk."""
    faults = tmp_path / "coxa.toml"
    faults.write_text(f"seed = 0\n[[faults]]\nkind = 'silent'\nids = [{COXA_RM}]\nat_s = 8.0\n")
    doc = {
        "name": "lost-coxa",
        "description": "A tripod walk whose middle right coxa goes silent at 8 s.",
        "duration_s": 16.0,
        "seed": 1,
        "terrain": "flat",
        "faults": str(faults),
        "commands": [{"t": 3.0, "gait": "tripod", "vx_m_s": 0.1}],
    }
    if hold:
        config = tmp_path / "hold.toml"
        config.write_text('[[reflexes]]\ntype = "heading-hold"\n')
        doc["config"] = str(config)
    scenario = parse_scenario(doc).with_overrides(spread=True)
    yaw: list[tuple[float, float]] = []
    result = scenario.run(on_sample=lambda s, w: yaw.append((s.t, s.yaw)))
    assert result.summary()["falls"] == 0
    start = min(yaw, key=lambda p: abs(p[0] - 7.9))[1]
    return max(abs(math.degrees(y - start)) for t, y in yaw if t >= 8.0)


def test_a_lost_coxa_turns_the_robot_unless_its_heading_is_held(tmp_path: Path) -> None:
    assert veer_deg(tmp_path, hold=False) > 20.0
    assert veer_deg(tmp_path, hold=True) < 5.0
