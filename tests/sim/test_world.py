"""The world behind the servo emulator: the servo law against the motor law, determinism,
and the robot standing, walking, climbing and riding on the full runtime."""

from __future__ import annotations

import functools
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from whexar.actors.messages import WorldDiverged
from whexar.bus.control_table import CENTER_TICKS
from whexar.bus.emulator.chain import ServoChain
from whexar.config import RobotConfig
from whexar.sim.model import load_model
from whexar.sim.motors import (
    MAX_DUTY,
    MOTORS,
    TICKS_PER_RAD,
    MotorModel,
    MotorSource,
    position_duty_per_rad,
)
from whexar.sim.run import Sample, SimResult, seated_angles, simulate
from whexar.sim.terrain import slope
from whexar.sim.world import SimWorld, fsr_counts
from whexar.testing.walk import command

CFG = RobotConfig()
FEMUR = 3  # servo ID of RF's femur (eq. 4.1), an MX-106


def _held_world(motors: MotorSource = "bam") -> tuple[SimWorld, ServoChain, mujoco.MjModel]:
    """The robot in the air without gravity, its body held still, every servo holding."""
    model = load_model(CFG)
    model.opt.gravity[:] = 0.0
    model.dof_armature[0:6] = 1e9  # the body does not move
    chain = ServoChain.for_models(CFG.servos(), baudrate=CFG.bus.baudrate)
    world = SimWorld(model, chain, cfg=CFG, motor_source=motors)
    world.set_pose(seated_angles(CFG), base_xyz=(0.0, 0.0, 1.0))
    for servo in chain.servos.values():
        servo.set_register("goal_position", round(servo.position))
        servo.set_register("torque_enable", 1)
    return world, chain, model


def test_a_position_step_follows_the_motor_law() -> None:
    """A 0.5 rad step of an MX-106: the world's joint against an independent integration of
    the law it implements (profile at the Velocity Limit, duty = KPP·error clipped to
    96 %, τ = kt·V/R − kt²·ω/R, friction and armature)."""
    world, chain, model = _held_world()
    servo = chain.servos[FEMUR]
    joint = world.by_servo[FEMUR]
    q0 = world.q[joint.index]
    servo.set_register("goal_position", round((q0 + 0.5) * TICKS_PER_RAD + CENTER_TICKS))
    motor = MOTORS["MX-106"]
    kp = position_duty_per_rad(850)
    vmax = servo.drive.max_velocity / TICKS_PER_RAD
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, world.data, full)
    inertia = float(full[joint.dadr, joint.dadr])  # the leg beyond it and the armature
    volts = servo.input_voltage_v
    # The reference: the same law, integrated finely on its own.
    h = 1e-5
    q, w, desired = q0, 0.0, q0
    reference = {}
    for k in range(1, round(0.3 / h) + 1):
        desired += max(-vmax * h, min(vmax * h, q0 + 0.5 - desired))
        duty = max(-MAX_DUTY, min(MAX_DUTY, kp * (desired - q)))
        tau = motor.kt * (duty * volts - motor.kt * w) / motor.resistance
        net = tau - motor.viscous * w - _unloaded_friction(motor, tau, w) * math.tanh(w / 1e-3)
        w += net / inertia * h
        q += w * h
        if k % 1000 == 0:
            reference[round(k * h, 3)] = q - q0
    got = {}
    for k in range(1, 31):
        t = k * 0.01
        for s in chain.servos.values():
            s.advance(t)
        got[round(t, 3)] = world.q[joint.index] - q0
    for t in (0.02, 0.05, 0.1, 0.2, 0.3):
        assert got[t] == pytest.approx(reference[t], abs=0.02), (t, got[t], reference[t])
    # It got there: within a few mrad of the goal, the motor no longer saturated.
    assert got[0.3] == pytest.approx(0.5, abs=0.01)
    # Present Current is the motor's torque over kt.
    amps = servo.register_value("present_current") * 3.36e-3
    assert abs(amps) < 0.5


def _unloaded_friction(motor: MotorModel, tau: float, w: float) -> float:
    """BAM's m6 friction budget with no external torque (bam/model.py)."""
    g = motor.gear
    if g is None:
        return motor.coulomb
    rest = math.exp(-(abs(w / g.dtheta_stribeck) ** g.alpha))
    quad = g.load_friction_motor_quad * tau * tau
    return (
        motor.coulomb
        + g.load_friction_motor * abs(tau)
        + rest * (g.friction_stribeck + g.load_friction_motor_stribeck * abs(tau) + quad)
    )


@pytest.mark.parametrize(("motors", "holds"), [("bam", True), ("bam-m1", False)])
def test_the_gears_hold_a_load_beyond_the_motors_torque(motors: MotorSource, holds: bool) -> None:
    """An MX-64 coxa holding its goal against 6 N·m, its datasheet's stall torque: BAM's m6
    gears hold it within the position loop's error (their friction grows with the load,
    more when the load drives the motor), m1's motor alone (4.93 N·m stall) gives way."""
    world, chain, _ = _held_world(motors)
    coxa = world.by_servo[1]  # RF's coxa, an MX-64
    assert chain.servos[1].model.name == "MX-64"
    q0 = world.q[coxa.index]
    world.data.qfrc_applied[coxa.dadr] = -6.0
    for k in range(1, 51):
        for s in chain.servos.values():
            s.advance(k * 0.01)
    moved = q0 - world.q[coxa.index]
    if holds:
        assert 0.0 < moved < math.radians(12)  # the error that drives the motor to full duty
    else:
        assert moved > 0.5  # running away


def _held_error(world: SimWorld, chain: ServoChain, sid: int, seconds: float) -> float:
    """How far joint ``sid`` gives way (rad) under 2 N·m after ``seconds``."""
    joint = world.by_servo[sid]
    q0 = world.q[joint.index]
    world.data.qfrc_applied[joint.dadr] = -2.0
    t0 = chain.servos[sid].time
    for k in range(1, round(seconds / 0.01) + 1):
        for s in chain.servos.values():
            s.advance(t0 + k * 0.01)
    return float(q0 - world.q[joint.index])


def test_a_position_i_gain_takes_the_error_of_a_held_load_away() -> None:
    """Position P Gain alone holds a load with an error (the coxa: 2 N·m without the gears'
    help, BAM's m1); Position I Gain (e-manual: KPI = I/65 536 on the error summed each
    millisecond) winds it away, D Gain alone changes nothing at rest."""
    p_alone = _held_error(*_held_world("bam-m1")[:2], sid=1, seconds=1.0)
    assert math.radians(1) < p_alone < math.radians(12)
    world, chain, _ = _held_world("bam-m1")
    chain.servos[1].set_register("position_d_gain", 200)
    assert _held_error(world, chain, 1, 1.0) == pytest.approx(p_alone, rel=0.05)
    world, chain, _ = _held_world("bam-m1")
    chain.servos[1].set_register("position_i_gain", 2000)
    assert abs(_held_error(world, chain, 1, 1.0)) < 0.1 * p_alone


def test_a_world_that_diverges_holds_still_and_says_when(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capfd: pytest.CaptureFixture[str]
) -> None:
    """MuJoCo would reset the robot to its first pose and print (and log to a file) a
    warning; the world goes back to the transaction's start and holds still instead."""
    monkeypatch.chdir(tmp_path)  # where MuJoCo's default handler would leave its log
    world, _, _ = _held_world()
    world.advance_to(0.05)
    before = world.data.qpos.copy()
    world.data.qvel[6] = 1e30  # RF's coxa: no physics integrates that
    world.advance_to(0.06)
    assert world.diverged_at is not None
    assert 0.05 < world.diverged_at <= 0.06  # at its first step
    assert "Nan, Inf or huge value in QVEL" in world.divergence
    np.testing.assert_array_equal(world.data.qpos, before)
    world.advance_to(0.5)  # the clock goes on, nothing moves
    assert world.time == pytest.approx(0.5, abs=world.h)
    np.testing.assert_array_equal(world.data.qpos, before)
    assert all(math.isfinite(a) for a in world.accel_g)
    assert "WARNING" not in capfd.readouterr().err
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


@pytest.mark.slow
def test_a_run_whose_world_diverges_says_so_and_stops() -> None:
    def poison(sample: Sample, world: SimWorld) -> None:
        if sample.t >= 1.0 and world.diverged_at is None:
            world.data.qvel[0] = 1e30

    r = simulate(duration=4.0, on_sample=poison)
    (said,) = [e for e in r.events if isinstance(e, WorldDiverged)]
    assert r.world.diverged_at is not None
    assert 1.0 < r.world.diverged_at < said.t < 1.2
    assert "QVEL" in said.detail
    stopped = r.summary()["stopped_by"]
    assert stopped is not None
    assert stopped.startswith("the simulated physics diverged")
    assert r.run.end_time < 3.0  # the stop sequence, not the 4 s


def test_present_current_is_the_motor_torque_over_kt() -> None:
    world, chain, _ = _held_world()
    servo = chain.servos[FEMUR]
    joint = world.by_servo[FEMUR]
    q0 = world.q[joint.index]
    servo.set_register("goal_position", round((q0 + 1.0) * TICKS_PER_RAD + CENTER_TICKS))
    for k in range(1, 21):
        for s in chain.servos.values():
            s.advance(k * 0.002)
    k = joint.index
    torque = float(world._torque[k])
    motor = MOTORS["MX-106"]
    # The torque of the last step, from the state that step started from.
    duty = position_duty_per_rad(850) * (float(world._desired[k]) - world.q[k])
    assert abs(duty) > MAX_DUTY  # 40 ms into a 1 rad step: saturated
    assert abs(torque) <= motor.stall_torque(servo.input_voltage_v) * MAX_DUTY
    current = world._current(servo, 0.0)
    assert current == pytest.approx(torque / motor.kt, rel=1e-9)
    # The bus reads it in 3.36 mA units (MX-106 Present Current, e-manual).
    assert servo.register_value("present_current") == round(current / 3.36e-3)


def test_the_force_sensor_divider() -> None:
    assert fsr_counts(0.0) == 0
    weight = CFG.robot.mass_kg * 9.81 / 6
    assert CFG.fsr.contact_on_counts < fsr_counts(weight) < 1023
    assert fsr_counts(1.0) < CFG.fsr.contact_off_counts


@functools.cache
def flat_walk() -> SimResult:
    return simulate(commands=[(4.0, command(vx_m_s=0.08))], duration=12.0)


@pytest.mark.slow
def test_the_same_run_gives_the_same_state_bit_for_bit() -> None:
    a = simulate(commands=[(2.5, command(vx_m_s=0.08))], duration=4.0, keep_log=True)
    b = simulate(commands=[(2.5, command(vx_m_s=0.08))], duration=4.0, keep_log=True)
    assert a.world.state_hash() == b.world.state_hash()
    assert a.run.log.digest() == b.run.log.digest()


def _steady(result: SimResult, start: float) -> list[float]:
    return [s.x for s in result.samples if start <= s.t <= result.duration_s]


@pytest.mark.slow
def test_it_stands_up_and_walks_on_the_flat_without_falling() -> None:
    r = flat_walk()
    summary = r.summary()
    assert summary["falls"] == 0
    standing = [s for s in r.samples if 3.0 <= s.t <= 3.9]
    assert all(s.z == pytest.approx(0.29, abs=0.01) for s in standing)  # the default stance
    walking = [s for s in r.samples if 7.0 <= s.t <= 12.0]
    speed = (walking[-1].x - walking[0].x) / (walking[-1].t - walking[0].t)
    assert speed == pytest.approx(0.08, rel=0.15)
    assert max(abs(s.roll) for s in walking) < math.radians(3)
    assert max(abs(s.pitch) for s in walking) < math.radians(3)
    assert abs(walking[-1].y) < 0.05


@pytest.mark.slow
def test_it_walks_up_a_15_degree_ramp_without_falling() -> None:
    r = simulate(terrain=slope(15), commands=[(4.0, command(vx_m_s=0.06))], duration=12.0)
    assert r.summary()["falls"] == 0
    late = [s for s in r.samples if 6.0 <= s.t <= 12.0]
    assert late[-1].x - late[0].x > 0.15  # uphill, along the slope
    assert all(s.pitch == pytest.approx(-math.radians(15), abs=math.radians(3)) for s in late)


@pytest.mark.slow
def test_it_rides_2_m() -> None:
    r = simulate(commands=[(3.0, command(mode="ride", vx_m_s=0.15))], duration=19.0)
    assert r.summary()["falls"] == 0
    end = [s for s in r.samples if s.t <= 19.0][-1]
    assert end.x > 2.0
    assert abs(end.y) < 0.06  # straight: under 2 % sideways
    rolling = [s for s in r.samples if 8.0 <= s.t <= 18.0]
    speed = (rolling[-1].x - rolling[0].x) / (rolling[-1].t - rolling[0].t)
    assert speed == pytest.approx(0.15, rel=0.03)  # the wheels roll without slipping
    _ = np.array([s.z for s in rolling])


def test_held_on_a_15_degree_slope_it_does_not_creep() -> None:
    """Contacts that hold: seated on its wheels with every servo holding, the robot stays
    put on a 15° slope (elliptic friction cone, impratio 10; docs/sim.md)."""
    terrain = slope(15)
    model = load_model(CFG, terrain=terrain)
    chain = ServoChain.for_models(CFG.servos(), baudrate=CFG.bus.baudrate)
    world = SimWorld(model, chain, cfg=CFG)
    pos, quat = terrain.ground.start_pose(CFG.locomotion.sit_height_mm / 1000 + 0.002)
    world.set_pose(seated_angles(CFG), base_xyz=pos, base_quat=quat)
    for servo in chain.servos.values():
        servo.set_register("goal_position", round(servo.position))
        servo.set_register("torque_enable", 1)
    marks = {}
    for k in range(1, 301):  # 3 s
        for servo in chain.servos.values():
            servo.advance(k * 0.01)
        if k in (100, 300):
            marks[k] = np.array(world.base_position)
    creep = float(np.linalg.norm(marks[300] - marks[100])) / 2.0  # m/s over the last 2 s
    assert creep < 0.001
