"""Sensor faults in a simulated run become what the readers report on the robot."""

from __future__ import annotations

import pytest

from whexar.actors.messages import (
    LegLoads,
    SensorFrameRejected,
    SensorLinkDown,
    SensorLinkStale,
    SensorLinkUp,
)
from whexar.errors import ConfigError
from whexar.sim.scenario import parse_scenario

DOC = {
    "name": "faulty",
    "duration_s": 4.0,
    "sensor_faults": [
        {"at_s": 1.0, "kind": "unplug", "device": "board", "duration_s": 1.0},
        {"at_s": 2.5, "kind": "corrupt", "frames": 2},
        {"at_s": 3.0, "kind": "dead_fsr", "leg": 2},
        {"at_s": 1.0, "kind": "unplug", "device": "imu", "duration_s": 0.5},
    ],
}


@pytest.mark.slow
def test_sensor_faults_reach_the_readers() -> None:
    result = parse_scenario(DOC, "<test>").run(keep_log=True)
    events = result.run.log.events()

    def at(kind: type, link: str) -> list[float]:
        return [
            e.t for e in events if isinstance(e, kind) and getattr(e, "link", "").startswith(link)
        ]

    # The board's cable out at 1 s for 1 s: down, stale, up (after the reader's retry).
    assert at(SensorLinkDown, "emulator") == [pytest.approx(1.0, abs=0.01)]
    assert at(SensorLinkStale, "emulator")
    assert 2.0 <= at(SensorLinkUp, "emulator")[-1] <= 2.6
    # The IMU off its bus for 0.5 s: down at once, up when it answers again.
    assert at(SensorLinkDown, "i2c") == [pytest.approx(1.0, abs=0.03)]
    assert 1.5 <= at(SensorLinkUp, "i2c")[-1] <= 1.7
    # Two corrupted frames at 2.5 s: rejected, nothing of them published.
    assert at(SensorFrameRejected, "emulator")
    loads = result.run.log.messages("loads", of=LegLoads)
    before = [m for m in loads if 2.6 < m.t < 2.9]
    after = [m for m in loads if m.t > 3.3]
    assert before
    assert after
    assert all(m.counts[2] > 0 for m in before)  # standing: the wheel carries load
    assert all(m.counts[2] == 0 for m in after)  # its sensor dead
    assert all(m.counts[1] > 0 for m in after)  # the others still read


def test_a_fault_on_the_wrong_device_is_a_scenario_problem() -> None:
    bad = {**DOC, "sensor_faults": [{"at_s": 1.0, "kind": "freeze", "device": "board"}]}
    with pytest.raises(ConfigError) as err:
        parse_scenario(bad, "<test>")
    assert "sensor_faults[0].device" in str(err.value)
    unknown = {**DOC, "sensor_faults": [{"at_s": 1.0, "kind": "melt"}]}
    with pytest.raises(ConfigError) as err2:
        parse_scenario(unknown, "<test>")
    assert "sensor_faults" in str(err2.value)
    assert "melt" in str(err2.value)


@pytest.mark.slow
def test_a_bus_fault_plan_reaches_the_simulated_servos() -> None:
    # The RF femur (servo 3) goes silent at 2 s: the bus scheduler finds it and, the
    # femur being critical, stops the robot safely.
    from whexar.actors.messages import BusLost, ServoFault
    from whexar.sim.run import simulate

    result = simulate(duration=3.0, faults="config/faults/dead-femur.toml", keep_log=True)
    faults = result.run.log.events(of=ServoFault)
    assert faults
    assert {f.servo_id for f in faults} == {3}
    assert min(f.t for f in faults) > 2.0
    assert result.run.log.events(of=BusLost)
