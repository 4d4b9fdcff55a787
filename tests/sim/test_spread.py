"""The spread of real parts: drawn within its amplitudes, repeatable by seed, and a world
that differs by seed and repeats itself bit for bit for one seed."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from whexar.bus.emulator.chain import ServoChain
from whexar.config import RobotConfig
from whexar.sim import spread as sp
from whexar.sim.model import load_model
from whexar.sim.scenario import load_scenario, parse_scenario
from whexar.sim.terrain import GROUND_FRICTION
from whexar.sim.world import SimWorld

CFG = RobotConfig()


def _world() -> SimWorld:
    chain = ServoChain.for_models(CFG.servos(), baudrate=CFG.bus.baudrate)
    return SimWorld(load_model(CFG), chain, cfg=CFG)


def test_draws_repeat_by_seed_and_stay_within_their_amplitudes() -> None:
    model = load_model(CFG)
    a, b, c = (sp.Spread.draw(s, model, 42) for s in (3, 3, 4))
    assert a == b
    assert a != c
    assert all(abs(g - 1) <= sp.FSR_GAIN for g in a.fsr_gain)
    assert all(abs(g - 1) <= sp.IR_GAIN for g in a.ir_gain)
    assert all(abs(o) <= sp.ACCEL_OFFSET_G for o in a.accel_offset_g)
    assert all(abs(o) <= sp.GYRO_OFFSET_DPS for o in a.gyro_offset_dps)
    lo, hi = sp.FRICTION_RANGE
    assert len(a.wheel_friction) == 6
    nominal = GROUND_FRICTION[0]
    assert all(lo * nominal <= mu <= hi * nominal for mu in a.wheel_friction)
    assert all(abs(f - 1) <= sp.MASS_TOLERANCE for f in a.mass_factor)
    assert all(abs(s) <= sp.COM_SHIFT_M for s in a.com_shift_m)
    assert len(a.backlash_rad) == 42
    assert all(0 <= b <= sp.BACKLASH_RAD for b in a.backlash_rad)


def test_the_perfect_world_changes_nothing() -> None:
    world = _world()
    mass, friction = world.model.body_mass.copy(), world.model.geom_friction.copy()
    sp.apply(sp.Spread.none(), world)
    assert np.array_equal(world.model.body_mass, mass)
    assert np.array_equal(world.model.geom_friction, friction)
    assert world.sense_hook is None
    assert world.dead_zone_rad is None
    assert world.chain.reply_jitter is None


def test_a_spread_changes_the_parts_and_the_running_draws() -> None:
    world = _world()
    total = float(world.model.body_mass.sum())
    drawn = sp.Spread.draw(1, world.model, len(world.joints))
    sp.apply(drawn, world)
    assert float(world.model.body_mass.sum()) != pytest.approx(total, rel=1e-6)
    assert float(world.model.body_mass.sum()) == pytest.approx(total, rel=sp.MASS_TOLERANCE)
    assert world.dead_zone_rad is not None
    assert len(world.dead_zone_rad) == 42
    jitter = world.chain.reply_jitter
    assert jitter is not None
    delays = [jitter() for _ in range(100)]
    assert all(abs(d) <= sp.REPLY_JITTER_S for d in delays)
    assert len(set(delays)) > 1


def test_the_scenario_key_defaults_to_the_perfect_world() -> None:
    doc = {"duration_s": 1.0}
    assert parse_scenario(doc).spread is False
    assert parse_scenario({**doc, "spread": True}).spread is True


def _run(seed: int, spread: bool) -> str:
    scenario = load_scenario("tripod").with_overrides(duration_s=1.5, seed=seed, spread=spread)
    return str(scenario.run().summary()["state_hash"])


_hash = functools.cache(_run)


@pytest.mark.slow
def test_one_seed_one_run_other_seeds_other_runs() -> None:
    # Standing up (1.5 s) runs the servos, the bus, the force sensors and the IMU.
    assert _run(0, True) == _hash(0, True)
    assert _hash(0, True) != _hash(1, True)
    assert _hash(0, True) != _hash(0, False)
    # Without the spread the seed moves nothing on a terrain without rocks.
    assert _hash(0, False) == _hash(1, False)


def test_the_sensors_read_through_their_parts() -> None:
    from whexar.sensors.imu_emulator import FakeLsm9ds1
    from whexar.sim.run import seated_angles
    from whexar.sim.world import fsr_counts

    chain = ServoChain.for_models(CFG.servos(), baudrate=CFG.bus.baudrate)
    chip = FakeLsm9ds1()
    world = SimWorld(load_model(CFG), chain, cfg=CFG, imu=chip)
    drawn = sp.Spread.draw(2, world.model, len(world.joints))
    sp.apply(drawn, world)
    # Seated 1 mm into the floor: the wheels pressed on it, the force sensors loaded.
    seat = CFG.locomotion.sit_height_mm / 1000 - 0.001
    world.set_pose(seated_angles(CFG), base_xyz=(0.0, 0.0, seat))
    assert min(world.contact_forces) > 1.0
    nominal = [fsr_counts(f) for f in world.contact_forces]
    assert world.fsr_counts != nominal
    for force, counts, gain in zip(
        world.contact_forces, world.fsr_counts, drawn.fsr_gain, strict=True
    ):
        low = fsr_counts(force * gain * (1 - sp.FSR_REPEAT))
        high = fsr_counts(force * gain * (1 + sp.FSR_REPEAT))
        assert low <= counts <= high
    offset = [a - b for a, b in zip(chip.accel_g, world.accel_g, strict=True)]
    assert offset == pytest.approx(list(drawn.accel_offset_g))


def test_the_chip_carries_the_levels_its_configuration_takes_off() -> None:
    # The simulated LSM9DS1 is the one the configuration was calibrated for: it reads the
    # configured zero-g and zero-rate levels on top, the spread's residual on top of that.
    from whexar.config import parse_config
    from whexar.sensors.imu_emulator import FakeLsm9ds1
    from whexar.sim.run import seated_angles

    cfg = parse_config(
        {"imu": {"accel_offset_g": [0.05, -0.02, 0.01], "gyro_offset_dps": [12.0, 0.0, -4.0]}}
    )
    chain = ServoChain.for_models(cfg.servos(), baudrate=cfg.bus.baudrate)
    chip = FakeLsm9ds1()
    world = SimWorld(load_model(cfg), chain, cfg=cfg, imu=chip)
    seat = cfg.locomotion.sit_height_mm / 1000 - 0.001
    world.set_pose(seated_angles(cfg), base_xyz=(0.0, 0.0, seat))
    offset = [a - b for a, b in zip(chip.accel_g, world.accel_g, strict=True)]
    assert offset == pytest.approx([0.05, -0.02, 0.01])
    assert chip.gyro_dps == pytest.approx((12.0, 0.0, -4.0), abs=1e-6)  # at rest
    drawn = sp.Spread.draw(2, world.model, len(world.joints))
    sp.apply(drawn, world)
    world.set_pose(seated_angles(cfg), base_xyz=(0.0, 0.0, seat))
    offset = [a - b for a, b in zip(chip.accel_g, world.accel_g, strict=True)]
    residual = [o - c for o, c in zip(offset, (0.05, -0.02, 0.01), strict=True)]
    assert residual == pytest.approx(list(drawn.accel_offset_g))
