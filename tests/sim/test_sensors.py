"""The sensors read the world: tilt from the IMU and the board's accelerometer, whichever way
the tilt is made; distances from the IR rangefinders' rays; loads from the wheels' contacts."""

from __future__ import annotations

import math

import numpy as np
import pytest

from whexar.bus.emulator.chain import ServoChain
from whexar.config import RobotConfig
from whexar.kinematics.sensing import ir_distance, tilt_from_acceleration
from whexar.sensors.board_emulator import SensorBoardEmulator
from whexar.sensors.frame import ACC_KEYS, FSR_KEYS
from whexar.sensors.imu_emulator import FakeLsm9ds1
from whexar.sim.model import load_model
from whexar.sim.run import seated_angles
from whexar.sim.terrain import Floor, Terrain, block, flat, slope
from whexar.sim.world import SimWorld, fsr_counts

CFG = RobotConfig()


def _resting(
    terrain: Terrain, *, gravity_pitch_deg: float = 0.0, cfg: RobotConfig = CFG
) -> tuple[SimWorld, FakeLsm9ds1, SensorBoardEmulator]:
    model = load_model(cfg, terrain=terrain)
    if gravity_pitch_deg:
        # The other way to make a slope: tilt gravity instead of the ground.
        theta = math.radians(gravity_pitch_deg)
        model.opt.gravity[:] = (-9.81 * math.sin(theta), 0.0, -9.81 * math.cos(theta))
    chain = ServoChain.for_models(CFG.servos(), baudrate=CFG.bus.baudrate)
    chip = FakeLsm9ds1()
    board = SensorBoardEmulator(accelerometer=True)
    world = SimWorld(model, chain, cfg=cfg, board=board, imu=chip)
    pos, quat = terrain.ground.start_pose(CFG.locomotion.sit_height_mm / 1000 + 0.002)
    world.set_pose(seated_angles(CFG), base_xyz=pos, base_quat=quat)
    for servo in chain.servos.values():  # every servo holds where it is
        servo.set_register("goal_position", round(servo.position))
        servo.set_register("torque_enable", 1)
    for k in range(1, 101):  # 1 s: it comes to rest
        for servo in chain.servos.values():
            servo.advance(k * 0.01)
    return world, chip, board


def _board_tilt(board: SensorBoardEmulator) -> tuple[float, float]:
    counts = board.inputs_at(0.0)
    acc = CFG.sensor_board.accelerometer
    g = [
        (counts[key] - zero) / per
        for key, zero, per in zip(ACC_KEYS, acc.zero_g_counts, acc.counts_per_g, strict=True)
    ]
    return tilt_from_acceleration(*g)


@pytest.mark.parametrize("how", ["tilted plane", "tilted gravity"])
def test_a_20_degree_slope_reads_as_20_degrees_of_pitch(how: str) -> None:
    if how == "tilted plane":
        world, chip, board = _resting(slope(20))
        w, x, y, z = world.base_quat
        body_pitch = math.asin(2 * (w * y - z * x))  # the body on the plane, in the world
    else:
        world, chip, board = _resting(flat(), gravity_pitch_deg=20)
        body_pitch = -math.radians(20)  # level in a world whose gravity leans 20°
    roll, pitch = tilt_from_acceleration(*chip.accel_g)
    # Nose up on an upward slope: a negative pitch (nose down is positive, eq. 5.7); the
    # seated robot stands within a couple of degrees of the slope.
    assert body_pitch == pytest.approx(-math.radians(20), abs=math.radians(3))
    assert pitch == pytest.approx(body_pitch, abs=math.radians(0.5))
    assert roll == pytest.approx(0.0, abs=math.radians(1))
    assert np.linalg.norm(chip.accel_g) == pytest.approx(1.0, abs=0.02)
    board_roll, board_pitch = _board_tilt(board)
    assert board_pitch == pytest.approx(pitch, abs=math.radians(1.5))  # ADC resolution
    assert board_roll == pytest.approx(roll, abs=math.radians(1.5))


LEVEL = RobotConfig.model_validate({"ir": {"pitch_deg": 0.0}})
"""The rangefinders mounted level: their rays stay above the floor."""


def _ranges(board: SensorBoardEmulator) -> list[float]:
    counts = board.inputs_at(0.0)
    ir = CFG.ir
    return [ir_distance(counts[key], ir.k_cm, ir.exponent) for key in ("ir1", "ir2")]  # m


def test_the_rangefinders_see_a_block_ahead_and_nothing_beyond_range() -> None:
    _, _, board = _resting(flat() + block((0.1, 1.0, 0.6), (1.0, 0.0)), cfg=LEVEL)
    seen = _ranges(board)
    # The block's face is at x = 0.95 m; the sensors sit on the front legs, ahead of C.
    assert all(0.3 < d < 0.95 for d in seen), seen
    assert seen[0] == pytest.approx(seen[1], abs=0.02)
    world2, _, board2 = _resting(flat(), cfg=LEVEL)
    assert all(d > CFG.ir.max_distance_mm / 1000 for d in _ranges(board2))
    assert isinstance(world2.ir_counts[0], int)


def test_pitched_down_the_rangefinders_meet_the_floor_ahead() -> None:
    world, _, board = _resting(flat())
    site = world.model.site("ir_right").id
    height = float(world.data.site_xpos[site][2])
    # Seated, the sensors are low: each ray meets the floor at height / sin(20°).
    expected = height / math.sin(math.radians(CFG.ir.pitch_deg))
    assert _ranges(board) == pytest.approx([expected] * 2, rel=0.1)


def test_seated_on_its_wheels_each_force_sensor_reads_a_sixth_of_the_weight() -> None:
    world, _, board = _resting(Terrain("flat", Floor()))
    counts = board.inputs_at(0.0)
    loads = [counts[key] for key in FSR_KEYS]
    assert world.fsr_counts == loads
    sixth = fsr_counts(CFG.robot.mass_kg * 9.81 / 6)
    assert all(c == pytest.approx(sixth, abs=5) for c in loads)
    assert all(c > CFG.fsr.contact_on_counts for c in loads)
