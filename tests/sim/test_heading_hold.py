"""A lost coxa in the simulated world: the middle right coxa goes silent during a tripod
walk (its Bus Watchdog holds its last goal). Dragged along, the leg turns the robot 24° in
8 s; heading hold keeps the heading within 5° — on a robot whose gyroscope has an unknown
zero-rate level (the spread of real parts, seed 1). With the loss reported to the
coordinator, the leg rides its wheel and the heading stays within 5° with no reflex at all
(:mod:`whexar.actors.locomotion.losses`)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from whexar.actors.messages import JointLost
from whexar.sim.scenario import parse_scenario

pytestmark = pytest.mark.slow  # three 16 s walks on the full runtime

COXA_RM = 15
RM = 2


def veer_deg(tmp_path: Path, *, hold: bool, ride: bool) -> float:
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
    config = tmp_path / f"robot-{hold}-{ride}.toml"
    text = f"[locomotion]\nride_lost_coxa = {str(ride).lower()}\n"
    if hold:
        text += '[[reflexes]]\ntype = "heading-hold"\n'
    config.write_text(text)
    doc["config"] = str(config)
    scenario = parse_scenario(doc).with_overrides(spread=True)
    yaw: list[tuple[float, float]] = []
    result = scenario.run(on_sample=lambda s, w: yaw.append((s.t, s.yaw)))
    assert result.summary()["falls"] == 0
    lost = [e for e in result.events if isinstance(e, JointLost)]
    assert [(e.leg, e.joint) for e in lost] == [(RM, 0)]
    assert ("rides its wheel" in lost[0].action) == ride
    start = min(yaw, key=lambda p: abs(p[0] - 7.9))[1]
    return max(abs(math.degrees(y - start)) for t, y in yaw if t >= 8.0)


def test_a_lost_coxa_turns_the_robot_unless_its_heading_is_held(tmp_path: Path) -> None:
    assert veer_deg(tmp_path, hold=False, ride=False) > 20.0
    assert veer_deg(tmp_path, hold=True, ride=False) < 5.0


def test_a_lost_coxa_whose_leg_rides_its_wheel_does_not_turn_the_robot(tmp_path: Path) -> None:
    assert veer_deg(tmp_path, hold=False, ride=True) < 5.0
