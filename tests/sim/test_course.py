"""The default course (`make sim`) run to its end: the main job gets where it should."""

from __future__ import annotations

import pytest

from whexar.sim.scenario import load_scenario

pytestmark = pytest.mark.slow  # the full runtime over the course's 105 s


def test_the_default_course_gets_past_the_sill_and_the_rocks() -> None:
    # The sill is at x = 5 m, the rocks from 7 to 8 m (config/scenarios/course.toml). A
    # gait's start and the standing settle once fought at x = 5.9 m until the end.
    result = load_scenario().run()
    summary = result.summary()
    assert summary["progress_along_m"] >= 7.5, summary
    assert summary["falls"] == 0, summary
    assert summary["gait_changes"] >= 2, summary  # the selector chose, not the operator
