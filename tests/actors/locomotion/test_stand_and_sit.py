"""Standing up from whatever pose the servos report; sitting down before torque goes off."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from whexar.actors.messages import (
    BusLost,
    GoalClamped,
    GoalRefused,
    IkFailed,
    LegState,
    LocomotionChanged,
)
from whexar.bus.control_table import TICKS_PER_REV
from whexar.bus.emulator.chain import SERVO_CHAIN, ServoChain
from whexar.config import RobotConfig
from whexar.kinematics.leg import fk_point
from whexar.runtime.devices import DEVICES
from whexar.runtime.messages import ActorFailed, SafeStop
from whexar.testing import Harness, RunResult, run_actors
from whexar.testing.bus import servo_chain
from whexar.testing.walk import command, run_walk, walk_graph

# Whole runs on the emulators, a second or more each.
pytestmark = pytest.mark.slow

CFG = RobotConfig()
GEOMETRY = CFG.leg_geometry()
SIT_M = CFG.locomotion.sit_height_mm / 1000


def _ticks(rad: float) -> float:
    return rad * TICKS_PER_REV / (2 * math.pi) + TICKS_PER_REV / 2


def _rad(ticks: float) -> float:
    return (ticks - TICKS_PER_REV / 2) * 2 * math.pi / TICKS_PER_REV


def _faults(run: RunResult) -> list[object]:
    kinds = (GoalClamped, GoalRefused, IkFailed, ActorFailed)
    return [e for kind in kinds for e in run.log.events(of=kind)]


def _activities(run: RunResult) -> list[str]:
    return [e.after for e in run.log.events(of=LocomotionChanged) if e.what == "activity"]


def _wheel_drop(chain: ServoChain, leg: int) -> float:
    """How far below its coxa joint leg ``leg``'s wheel touches, from the servos' angles."""
    angles = [_rad(chain.servos[7 * leg + j + 1].position) for j in range(5)]
    return fk_point(angles, GEOMETRY)[1]


@pytest.fixture
def sprawled() -> Iterator[ServoChain]:
    """The robot as it was switched off: every leg somewhere within its limits."""
    made = servo_chain()
    rng = np.random.default_rng(3)
    lo, hi = GEOMETRY.lower_limits, GEOMETRY.upper_limits
    for leg in range(6):
        for joint in range(5):
            # The trochanter rests level; the others anywhere within most of their range.
            angle = 0.0 if joint == 1 else float(rng.uniform(0.6 * lo[joint], 0.6 * hi[joint]))
            made.servos[7 * leg + joint + 1].set_state(_ticks(angle))
    with DEVICES.registered(SERVO_CHAIN, "sprawled", made):
        yield made


def test_it_stands_up_from_a_sprawled_pose_and_sits_down_when_stopped(
    sprawled: ServoChain,
) -> None:
    graph = walk_graph("emulator:sprawled")
    run = run_walk(duration=5.0, graph=graph)
    assert _faults(run) == []
    assert _activities(run) == ["standing", "sitting_down", "seated"]
    # Standing: every foot at its neutral point of the default stance.
    standing = {s.leg: s for s in run.log.messages("legs", of=LegState) if 4.5 < s.t < 4.9}
    assert len(standing) == 6
    assert all(s.foot[2] == pytest.approx(-0.29) for s in standing.values())
    # Stopped: seated (wheels 80 mm below the coxa joints), then torque off, in that order.
    for leg in range(6):
        assert _wheel_drop(sprawled, leg) == pytest.approx(SIT_M, abs=0.005)
    assert not any(s.torque_enabled for s in sprawled.servos.values())


def test_a_safe_stop_sits_down_while_the_bus_still_runs(sprawled: ServoChain) -> None:
    async def scenario(h: Harness) -> None:
        await h.sleep_until(3.0)
        await h.feed("commands", command(vx_m_s=0.08))
        await h.sleep_until(5.0)
        h.runtime.request_safe_stop("test: something the robot cannot do without")

    run = run_actors(
        walk_graph("emulator:sprawled"), scenario=scenario, feeds=["commands"], duration=12.0
    )
    assert run.exit_code == 3
    assert run.log.events(of=SafeStop)
    assert "seated" in _activities(run)
    for leg in range(6):
        assert _wheel_drop(sprawled, leg) == pytest.approx(SIT_M, abs=0.005)
    assert not any(s.torque_enabled for s in sprawled.servos.values())


def test_a_lost_servo_stops_the_robot_seated_not_dropped() -> None:
    # A dead femur servo is BusLost and a safe stop. The scheduler cycles on without it
    # until it parks the servos, so the coordinator sits the robot down first: parked
    # standing, with bus.on_stop = torque_off, it would drop onto its belly.
    graph = walk_graph(bus_params={"faults": "config/faults/dead-femur.toml"})
    run = run_walk([(3.0, command(vx_m_s=0.08))], duration=12.0, graph=graph)
    lost = run.log.events(of=BusLost)
    assert len(lost) == 1
    assert "servo 3 (RF femur) lost" in lost[0].reason
    activities = _activities(run)
    assert activities.index("sitting_down") < activities.index("seated")
    assert run.exit_code == 3
    assert run.end_time < lost[0].t + 3.0  # the stop stays bounded


def test_a_lost_port_is_not_asked_to_sit_down(tmp_path: Path) -> None:
    # The servo port gone: nothing can carry a sit-down out, so the coordinator does not
    # wait for one, and the stop stays bounded.
    plan = tmp_path / "unplug.toml"
    plan.write_text('seed = 0\n[[faults]]\nkind = "unplug"\nat_s = 4.0\n')
    graph = walk_graph(bus_params={"faults": str(plan)})
    run = run_walk([(3.0, command(vx_m_s=0.08))], duration=12.0, graph=graph)
    lost = run.log.events(of=BusLost)
    assert lost
    assert lost[0].reason.startswith("servo port lost")
    assert "sitting_down" not in _activities(run)
    assert run.exit_code == 3
    assert run.end_time < lost[0].t + 3.0
