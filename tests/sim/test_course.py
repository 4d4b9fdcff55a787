"""The default course (`make sim`) run to its end: the main job gets where it should."""

from __future__ import annotations

import pytest

from whexar.actors.messages import GaitSelected
from whexar.sim.report import reactive_timeline
from whexar.sim.scenario import load_scenario

pytestmark = pytest.mark.slow  # the full runtime over the course's 105 s


def test_the_default_course_gets_past_the_sill_and_the_rocks_with_its_reflexes() -> None:
    # The sill is at x = 5 m, the rocks from 7 to 8 m (config/scenarios/course.toml). A
    # gait's start and the standing settle once fought at x = 5.9 m until the end; with
    # every reflex running, a foot searching for the ramp's foot was lifted before its
    # search ran and the body was held at x = 4.2 m for good.
    scenario = load_scenario()
    # Beside the graph's battery reflex (config/reflexes.toml):
    assert [r.type for r in scenario.config.reflexes] == [
        "elevator",
        "searching",
        "stepping",
        "heading-hold",
        "obstacle",
    ]
    result = scenario.run()
    summary = result.summary()
    assert summary["progress_along_m"] >= 7.5, summary
    # Along the course, not beside it: heading hold keeps the body square to it. With a
    # gyroscope level learnt while the obstacle reflex swayed the body, it veered 37° and
    # walked 1.8 m to the side of the sill and the blocks.
    side = (summary["progress_m"] ** 2 - summary["progress_along_m"] ** 2) ** 0.5
    assert side <= 0.5, summary
    assert summary["falls"] == 0, summary
    # The selector chose, not the operator: wheels on the flat, the tripod on the ramp.
    chosen = [e.after for e in result.events if isinstance(e, GaitSelected)]
    assert {"wheels", "tripod"} <= set(chosen), chosen
    assert summary["gait_selections"] == len(chosen) >= 3
    assert summary["reflex_activations"] >= 1, summary
    timeline = [what for _, what in reactive_timeline(result)]
    assert any(what.startswith("reflex ") for what in timeline), timeline
