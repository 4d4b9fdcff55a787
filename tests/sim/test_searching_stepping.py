"""The searching and stepping reflexes in the simulated world: a trench under the feet
(searching finds its floor, or holds the robot safely at one too deep), a snagged leg and
a shove on a slippery foot (stepping steps the leg back, the walk goes on)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from whexar.actors.messages import NoFoothold, Restepped, SwingEnded
from whexar.sim.run import SimResult
from whexar.sim.scenario import parse_scenario

pytestmark = pytest.mark.slow  # the full runtime over 14–35 s of simulated time


def walk(tmp_path: Path, reflex: str | None, seconds: float, **more: Any) -> SimResult:
    """A tripod walk at 0.1 m/s from 3 s, with ``reflex`` (a ``[[reflexes]]`` type) or none."""
    doc: dict[str, Any] = {
        "duration_s": seconds,
        "terrain": "flat",
        "commands": [{"t": 3.0, "gait": "tripod", "vx_m_s": 0.1}],
        **more,
    }
    if reflex is not None:
        (tmp_path / "robot.toml").write_text(f'[[reflexes]]\ntype = "{reflex}"\n')
        doc["config"] = "robot.toml"
    return parse_scenario(doc, base=tmp_path).run(keep_log=True)


def trench(width_mm: float, depth_mm: float) -> dict[str, Any]:
    return {"base": "flat", "ditch": {"width_mm": width_mm, "depth_mm": depth_mm, "at_m": 0.9}}


def outcomes(result: SimResult) -> list[str]:
    return [s.outcome for s in result.run.log.messages("swings", of=SwingEnded)]


def test_searching_finds_the_floor_of_a_trench_under_the_feet(tmp_path: Path) -> None:
    without = walk(tmp_path, None, 25.0, terrain=trench(300, 50))
    found = walk(tmp_path, "searching", 25.0, terrain=trench(300, 50))
    assert outcomes(without).count("no_contact") >= 3  # feet over the trench, hanging
    assert outcomes(found).count("no_contact") == 0  # each found the floor
    floor = [
        s.ground_offset_m
        for s in found.run.log.messages("swings", of=SwingEnded)
        if s.outcome == "completed" and s.ground_offset_m < -0.001
    ]
    assert floor  # some searched down and stood below where they expected the ground
    s = found.summary()
    assert s["falls"] == 0
    assert s["progress_along_m"] >= without.summary()["progress_along_m"] - 0.05


def test_a_trench_too_deep_to_search_holds_the_robot_safely(tmp_path: Path) -> None:
    # Held at 30 s: which feet the far edge catches decides the rounds (docs/reflexes.md).
    result = walk(tmp_path, "searching", 35.0, terrain=trench(400, 200))
    (held,) = [e for e in result.events if isinstance(e, NoFoothold)]
    around = [e for e in result.events if isinstance(e, Restepped) and e.leg == held.leg]
    assert len(around) >= 2  # forward, then back, before holding
    assert all(e.done for e in around)
    s = result.summary()
    assert s["falls"] == 0
    assert s["reflex_activations"] >= 1
    x_end = result.samples[-1].x
    assert x_end < 0.9  # held at the trench's edge, not in it
    assert result.samples[-1].x - next(p.x for p in result.samples if p.t >= held.t) < 0.02


def test_stepping_steps_a_snagged_leg_back_and_the_walk_goes_on(tmp_path: Path) -> None:
    snag = {"kind": "snag", "at_s": 6.3, "duration_s": 2.0, "leg": 0, "joint": "coxa"}
    result = walk(tmp_path, "stepping", 14.0, world_faults=[snag])
    steps = [e for e in result.events if isinstance(e, Restepped)]
    assert [(e.leg, e.reflex, e.done) for e in steps] == [(0, "reflex-stepping", True)]
    assert 6.3 < steps[0].t < 9.5
    s = result.summary()
    assert s["falls"] == 0
    walked_after = result.samples[-1].x - next(p.x for p in result.samples if p.t >= 10.0)
    assert walked_after > 0.3  # 4 s at 0.1 m/s, less the ramp: it walks on


def test_a_shove_on_a_slippery_foot_is_stepped_back_and_nothing_falls(tmp_path: Path) -> None:
    faults = [
        {"kind": "slippery", "at_s": 5.0, "duration_s": 3.0, "friction": 0.05, "leg": 0},
        {"kind": "push", "at_s": 6.0, "force_n": 60.0, "heading_deg": -90.0, "duration_s": 0.5},
    ]
    without = walk(tmp_path, None, 14.0, world_faults=faults)
    result = walk(tmp_path, "stepping", 14.0, world_faults=faults)
    steps = [e for e in result.events if isinstance(e, Restepped)]
    assert steps
    assert all(e.done for e in steps)
    assert all(6.0 < e.t < 9.0 for e in steps)
    assert result.summary()["falls"] == 0
    assert result.summary()["progress_along_m"] > 0.8 * without.summary()["progress_along_m"]
