"""The legs' contact estimate in the simulated world: a force sensor that dies and a femur
the bus stops reading are set aside with an event, and the walk goes on on what is left."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from whexar.actors.messages import ContactDegraded, ContactRestored, LegState, SwingEnded
from whexar.sim.scenario import parse_scenario

pytestmark = pytest.mark.slow  # the full runtime over 12–20 s of simulated time


def tripod(duration_s: float, **more: Any) -> dict[str, Any]:
    return {
        "duration_s": duration_s,
        "terrain": "flat",
        "commands": [{"t": 3.0, "gait": "tripod", "vx_m_s": 0.1}],
        **more,
    }


def test_a_dead_force_sensor_falls_back_on_the_current_and_the_walk_goes_on() -> None:
    # RF's force sensor reads 0 from 6 s (a broken wire): the front femur draws −0.5 A in
    # stance, never the 0.8 A of 6.7.3, so only a learnt threshold can replace it.
    doc = tripod(20.0, sensor_faults=[{"at_s": 6.0, "kind": "dead_fsr", "leg": 0}])
    result = parse_scenario(doc).run(keep_log=True)
    (dead,) = [e for e in result.events if isinstance(e, ContactDegraded)]
    assert (dead.leg, dead.sensor) == (0, "fsr")
    assert 6.0 < dead.t < 6.0 + 5 * 1.6  # within five tripod cycles
    assert not [e for e in result.events if isinstance(e, ContactRestored)]
    after = [m for m in result.run.log.messages("legs", of=LegState) if m.leg == 0]
    assert {m.contact_source for m in after if m.t > dead.t} == {"current"}
    # Its swings land as before: the fallback reads ground where there is ground.
    swings = result.run.log.messages("swings", of=SwingEnded)
    late = [s.outcome for s in swings if s.leg == 0 and s.t > dead.t + 0.5]
    assert len(late) >= 4
    assert set(late) == {"completed"}
    summary = result.summary()
    assert summary["falls"] == 0
    assert summary["progress_along_m"] > 1.4  # 17 s at 0.1 m/s, less the ramp-up


def test_a_femur_the_bus_stops_reading_is_set_aside_and_taken_back(tmp_path: Path) -> None:
    (tmp_path / "plan.toml").write_text(
        "seed = 1\n[[faults]]\nkind = 'silent'\nids = [3]\nat_s = 6.0\nduration_s = 0.3\n"
    )
    result = parse_scenario(tripod(8.0, faults="plan.toml"), base=tmp_path).run()
    said = [
        (type(e).__name__, e.leg, e.sensor)
        for e in result.events
        if isinstance(e, ContactDegraded | ContactRestored)
    ]
    assert said == [("ContactDegraded", 0, "current"), ("ContactRestored", 0, "current")]
    degraded, restored = [
        e for e in result.events if isinstance(e, ContactDegraded | ContactRestored)
    ]
    assert 6.0 < degraded.t < 6.3 < restored.t < 6.6
