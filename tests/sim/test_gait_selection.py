"""The gait selector in the simulated world: the operator asks for ``auto`` and walks
from the flat over a field of rocks (40 of up to 8 cm, x = 1–2 m) and on to the flat.
On the rocks the terrain asks for a higher step than the tripod's limit (Table 5.9:
100 mm), and the selector moves to a more stable gait at once (further, up to the wave,
where feet lose their supports: the selector's own tests); past the rocks, after each
calm period, it returns one rank at a time to the tripod — each change kept for its
minimum dwell, never back and forth."""

from __future__ import annotations

from itertools import pairwise

import pytest

from whexar.actors.messages import LocomotionChanged
from whexar.config import RobotConfig
from whexar.kinematics.gait import stability_rank
from whexar.sim.scenario import parse_scenario

pytestmark = pytest.mark.slow  # a 70 s walk on the full runtime


def test_rough_then_smooth_ground_takes_stabler_gaits_and_back() -> None:
    doc = {
        "name": "rough-then-smooth",
        "description": "Walk with the selector's gaits over a field of rocks and beyond.",
        "duration_s": 70.0,
        "seed": 0,
        "terrain": {
            "base": "flat",
            "rocks": {"count": 40, "size_mm": 80.0, "area_m": [[1.0, 2.0], [-0.6, 0.6]]},
        },
        "commands": [{"t": 3.0, "gait": "auto", "vx_m_s": 0.1}],
    }
    result = parse_scenario(doc).run()
    summary = result.summary()
    assert summary["falls"] == 0
    assert summary["progress_along_m"] > 2.3  # past the rocks

    def x_at(t: float) -> float:
        return min(result.samples, key=lambda s: abs(s.t - t)).x

    walked = [e for e in result.events if isinstance(e, LocomotionChanged) and e.what == "gait"]
    ranks = [stability_rank(walked[0].before), *(stability_rank(e.after) for e in walked)]
    top = ranks.index(max(ranks))
    # Up while on the rocks, then down: never back and forth.
    assert ranks[: top + 1] == sorted(ranks[: top + 1])
    assert ranks[top:] == sorted(ranks[top:], reverse=True)
    assert max(ranks) >= stability_rank("tetrapod")
    assert walked[0].before == walked[-1].after == "tripod"
    assert 0.6 < x_at(walked[0].t) < 2.0  # the front feet reach the rocks first
    assert x_at(walked[-1].t) > 2.0  # the tripod again once past them
    dwell = RobotConfig().gait_selector.min_dwell_s
    downs = [e.t for e in walked[top:]]
    assert all(b - a >= dwell for a, b in pairwise(downs))
