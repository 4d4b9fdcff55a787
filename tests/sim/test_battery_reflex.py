"""The battery reflex in the simulated world (5.3.1): on a Li-Po running empty the robot
warns, sits down before the servos' 10 V minimum, and shuts down — upright, having walked;
on the bench supply it never fires."""

from __future__ import annotations

import pytest

from whexar.actors.messages import BatteryLow, LocomotionChanged
from whexar.sim.run import Sample
from whexar.sim.scenario import load_scenario
from whexar.sim.world import SimWorld

pytestmark = pytest.mark.slow  # the full runtime over 35 s of simulated time


def test_a_discharging_battery_warns_then_sits_the_robot_down_and_shuts_it_down() -> None:
    lowest: list[float] = []

    def on_sample(sample: Sample, world: SimWorld) -> None:
        lowest.append(world.supply.terminal_volts)

    result = load_scenario("battery-empty").run(on_sample=on_sample)
    said = [e for e in result.events if isinstance(e, BatteryLow)]
    assert [e.stage for e in said] == ["warning", "empty"]
    warned, empty = said
    assert warned.voltage_v < 10.8 <= warned.threshold_v
    assert empty.voltage_v < 10.2
    # It walked between the warning and the sit-down, then sat, then the run stopped.
    assert empty.t - warned.t > 5.0
    (seated_by,) = [
        e for e in result.events if isinstance(e, LocomotionChanged) and e.what == "seated_by"
    ]
    assert seated_by.after.startswith("reflex-battery: battery at")
    assert seated_by.t == pytest.approx(empty.t, abs=0.05)
    activity = [(s.t, s.activity) for s in result.series.locomotion]
    assert activity[-1][1] == "seated"
    assert any(a == "walking" for t, a in activity if warned.t < t < empty.t)
    summary = result.summary()
    assert summary["falls"] == 0
    assert summary["sim_seconds"] < 0.9 * result.duration_s
    assert summary["stopped_by"] == (
        "reflex-battery: the battery is empty: the robot sat down and shuts down"
    )
    assert summary["progress_m"] > 1.0
    # Seated in time: the line never fell to the Li-Po's empty (9.6–9.9 V, 5.3.1).
    assert min(lowest) > 9.9


def test_on_the_bench_supply_the_battery_reflex_never_fires() -> None:
    result = load_scenario("tripod").with_overrides(duration_s=6.0).run()
    assert not [e for e in result.events if isinstance(e, BatteryLow)]
    assert result.summary()["stopped_by"] is None
