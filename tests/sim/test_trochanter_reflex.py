"""The trochanter reflex in the simulated world, as the thesis ran its first slope
experiment (6.7.6): the robot stands on a board raised at 2°/s to 30°, its coordinator
configured not to follow the pitch by itself. Without the reflex the legs stay square to
the body; with it they turn to the pitch once the board passes the threshold, and the
legs stand parallel to gravity again."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from whexar.actors.messages import BodyMotion, ReflexActivity
from whexar.sim.scenario import parse_scenario

pytestmark = pytest.mark.slow  # two 22 s stands on the full runtime


def stand_on_the_board(
    tmp_path: Path, *, reflex: bool
) -> tuple[list[BodyMotion], list[ReflexActivity]]:
    config = tmp_path / f"robot-{reflex}.toml"
    text = "[locomotion]\ntrochanter_follows_pitch = false\n"
    if reflex:
        text += '[[reflexes]]\ntype = "trochanter"\n'
    config.write_text(text)
    doc = {
        "name": "tilting-board",
        "description": "Stand on a board raised at 2°/s to 30° from 5 s.",
        "duration_s": 22.0,
        "seed": 0,
        "terrain": "flat",
        "config": str(config),
        "tilt": {"start_s": 5.0, "rate_deg_s": 2.0, "max_deg": 30.0},
        "commands": [{"t": 3.0, "vx_m_s": 0.0}],
    }
    result = parse_scenario(doc).run(keep_log=True)
    assert result.summary()["falls"] == 0
    log = result.run.log
    return log.messages(of=BodyMotion), log.messages(of=ReflexActivity)


def trochanter_deg(motion: list[BodyMotion], t: float) -> float:
    return math.degrees(min(motion, key=lambda m: abs(m.t - t)).trochanter_rad)


def test_past_its_threshold_the_reflex_turns_the_legs_parallel_to_gravity(
    tmp_path: Path,
) -> None:
    motion, activity = stand_on_the_board(tmp_path, reflex=False)
    assert max(abs(m.trochanter_rad) for m in motion) == 0.0
    assert not activity
    motion, activity = stand_on_the_board(tmp_path, reflex=True)
    assert trochanter_deg(motion, 6.0) == 0.0  # the board at 2°: below the threshold
    became = next(a for a in activity if a.active)
    assert 7.0 < became.t < 10.0  # 5° of the board's tilt, through the reflex's filter
    # The board at 30° from 20 s: the legs follow it (the body pitches as the board does;
    # nose up, facing uphill, is a negative pitch: eq. 5.7 of the board's axes).
    assert trochanter_deg(motion, 21.9) == pytest.approx(-30.0, abs=4.0)
