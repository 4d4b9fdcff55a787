"""The adaptive swing (Diosdado 2014, 3.5–3.6) on the servo emulator, contact from the current.

The emulated RF femur draws the current of a loaded leg while the RF wheel
touches a block 30 mm above the floor (foot point from the servos' present
angles through the leg's FK): a swing that meets it from its apex on stops
there, and the stance goes on at that height.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import pytest

from whexar.actors.messages import LegState, SwingEnded
from whexar.bus.control_table import TICKS_PER_REV
from whexar.bus.emulator.chain import SERVO_CHAIN, ServoChain
from whexar.bus.emulator.dynamics import ServoView, default_load
from whexar.config import RobotConfig
from whexar.kinematics.leg import fk_point
from whexar.runtime.devices import DEVICES
from whexar.testing.bus import servo_chain
from whexar.testing.walk import command, run_walk, walk_graph

# Whole walks on the emulators, a second or more each.
pytestmark = pytest.mark.slow

BLOCK_M = 0.03
LOADED_A = 2.0


def _rad(ticks: float) -> float:
    return (ticks - TICKS_PER_REV / 2) * 2 * math.pi / TICKS_PER_REV


@pytest.fixture
def blocked_chain() -> Iterator[ServoChain]:
    cfg = RobotConfig()
    geometry = cfg.leg_geometry()
    ground = -cfg.stance(cfg.locomotion.stance).height + BLOCK_M
    made = servo_chain()

    def load(servo: ServoView, t: float) -> float:
        if servo.id != 3:  # RF femur (eq. 4.1)
            return default_load(servo, t)
        angles = [_rad(made.servos[i].position) for i in range(1, 6)]
        _, down, _ = fk_point(angles, geometry)
        return LOADED_A if -down <= ground + 1e-3 else 0.1

    made.load_model = load
    with DEVICES.registered(SERVO_CHAIN, "block", made):
        yield made


def test_a_swing_that_meets_a_block_stops_on_it_and_the_stance_goes_on_there(
    blocked_chain: ServoChain,
) -> None:
    graph = walk_graph("emulator:block", leg_params={"contact": "current"})
    run = run_walk([(3.0, command(vx_m_s=0.08))], duration=9.0, graph=graph)
    ended = [e for e in run.log.messages("swings", of=SwingEnded) if e.leg == 0]
    early = [e for e in ended if e.outcome == "early_contact"]
    assert early, [(e.outcome, e.ground_offset_m) for e in ended]
    # It stopped on the block (30 mm up), within the swing's resolution per bus cycle.
    assert all(e.ground_offset_m == pytest.approx(BLOCK_M, abs=0.01) for e in early)
    stance_heights = [
        s.foot[2]
        for s in run.log.messages("legs", of=LegState)
        if s.leg == 0 and s.phase == "stance" and s.t > early[0].t
    ]
    floor = -RobotConfig().stance("default").height
    assert stance_heights
    assert min(stance_heights) > floor + BLOCK_M - 0.01  # it never sank back to the floor
    assert all(s.contact_source == "current" for s in run.log.messages("legs", of=LegState))


def test_a_swing_that_finds_no_ground_is_reported() -> None:
    # No load model: the femur never draws a loaded leg's current, so no swing meets ground.
    graph = walk_graph(leg_params={"contact": "current"})
    run = run_walk([(3.0, command(vx_m_s=0.08))], duration=6.0, graph=graph)
    outcomes = {e.outcome for e in run.log.messages("swings", of=SwingEnded)}
    assert outcomes == {"no_contact"}
