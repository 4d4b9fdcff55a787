"""Switching the simulated robot on: torque-on holds each joint where it sagged to."""

from __future__ import annotations

from whexar.actors.messages import BodyTilt
from whexar.sim.run import simulate


def test_torque_on_holds_the_seated_robot_still() -> None:
    # Seated and limp, the legs sag under the body's weight while the bus starts up.
    # Torque-on takes the joints where they are then, not where the start-up's survey
    # found them: no jolt (it used to throw the body 18 mm up, at 435 W) and the IMU
    # never reads the robot upside down.
    samples: list[tuple[float, float, float]] = []
    result = simulate(
        duration=0.6, on_sample=lambda s, _w: samples.append((s.t, s.z, s.power_w)), keep_log=True
    )
    # Until the coordinator starts to stand it up, half a second in.
    before = [(z, power) for t, z, power in samples if t <= 0.5]
    seated = before[0][0]
    assert max(z for z, _ in before) - seated < 0.002
    assert max(power for _, power in before) < 200.0
    tilts = [m for m in result.run.log.messages("tilt", of=BodyTilt) if m.t <= 0.6]
    assert tilts
    assert all(abs(m.roll_rad) < 0.1 and abs(m.pitch_rad) < 0.1 for m in tilts)
