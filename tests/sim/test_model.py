"""The MJCF model: names, joint angles that are whexar's, wheels, masses, standing."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from whexar.config import RobotConfig, parse_config
from whexar.errors import ConfigError, UsageError
from whexar.kinematics.body import leg_to_body, stance_feet
from whexar.kinematics.leg import fk, fk_chain, ik
from whexar.kinematics.wheels import heading_from_direction
from whexar.robot import JOINT_NAMES, LEG_NAMES
from whexar.sim.model import (
    STANCE_KEY,
    TIMESTEP_S,
    WheelShape,
    build_mjcf,
    default_base_height,
    load_model,
    stance_angles,
)
from whexar.sim.motors import MOTORS
from whexar.testing.walk import command

CFG = RobotConfig()
GEOMETRY = CFG.leg_geometry()
NAMES = [f"{leg}_{joint}" for leg in LEG_NAMES for joint in JOINT_NAMES]


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return load_model(CFG)


def _qadr(m: mujoco.MjModel) -> np.ndarray:
    return np.array([m.jnt_qposadr[m.joint(n).id] for n in NAMES])


def _dadr(m: mujoco.MjModel) -> np.ndarray:
    return np.array([m.jnt_dofadr[m.joint(n).id] for n in NAMES])


def _at_origin(m: mujoco.MjModel, angles: np.ndarray) -> mujoco.MjData:
    """Base at the origin, identity orientation, joints (6, 7) as given; kinematics only."""
    d = mujoco.MjData(m)
    d.qpos[:] = 0.0
    d.qpos[3] = 1.0
    d.qpos[_qadr(m)] = angles.ravel()
    mujoco.mj_kinematics(m, d)
    return d


# --------------------------------------------------------------------------- names


def test_the_model_has_the_named_joints_actuators_sites_and_geoms(model: mujoco.MjModel) -> None:
    m = model
    assert m.njnt == 43
    assert m.nu == 42
    base = m.joint("base")
    assert base.type[0] == mujoco.mjtJoint.mjJNT_FREE
    assert m.body(base.bodyid[0]).name == "base"
    assert int(m.jnt_qposadr[base.id]) == 0, "the base's pose is qpos[0:7]"
    for name in NAMES:
        joint = m.joint(name)
        assert joint.type[0] == mujoco.mjtJoint.mjJNT_HINGE
        act = m.actuator(name)
        assert act.trnid[0] == joint.id
        assert act.gear[0] == 1.0
        assert not m.actuator_ctrllimited[act.id]
        assert act.biastype[0] == mujoco.mjtBias.mjBIAS_NONE  # a plain motor: ctrl is N·m
    for site in ("imu", "ir_right", "ir_left", *(f"{leg}_contact" for leg in LEG_NAMES)):
        assert m.site(site).id >= 0
    for leg in LEG_NAMES:
        assert m.geom(f"{leg}_wheel").size[0] == pytest.approx(GEOMETRY.wheel_radius)
    assert m.site("imu").bodyid[0] == m.body("base").id
    assert np.allclose(m.site("imu").pos, 0.0)


def test_the_options_are_the_contract(model: mujoco.MjModel) -> None:
    assert model.opt.timestep == TIMESTEP_S == 0.0025
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    assert model.opt.impratio == 10.0
    assert load_model(CFG, timestep=0.001).opt.timestep == 0.001
    xml = build_mjcf(CFG)
    assert '<compiler angle="radian" autolimits="true"/>' in xml


# --------------------------------------------------------------------------- joint angles


def test_contact_sites_are_the_kinematics_contact_points(model: mujoco.MjModel) -> None:
    rng = np.random.default_rng(20230721)
    sites = [model.site(f"{leg}_contact").id for leg in LEG_NAMES]
    for _ in range(60):
        angles = np.zeros((6, 7))
        angles[:, :5] = rng.uniform(GEOMETRY.lower_limits, GEOMETRY.upper_limits, size=(6, 5))
        angles[:, 5:] = rng.uniform(-math.pi, math.pi, size=(6, 2))  # no effect on the point
        d = _at_origin(model, angles)
        expected = leg_to_body(fk(angles[:, :5], GEOMETRY, point="contact"), GEOMETRY)
        np.testing.assert_allclose(d.site_xpos[sites], expected, atol=1e-6)


def test_every_joint_sits_on_the_kinematics_chain(model: mujoco.MjModel) -> None:
    rng = np.random.default_rng(7)
    angles = np.zeros((6, 7))
    angles[:, :5] = rng.uniform(GEOMETRY.lower_limits, GEOMETRY.upper_limits, size=(6, 5))
    d = _at_origin(model, angles)
    chain = fk_chain(angles[:, :5], GEOMETRY)  # (6, 7, 3): coxa … tarsus, direction, axle
    # fk_chain's points 0…5 are the coxa, femur, tibia, tarsus, direction joints and the axle.
    for point, joint in enumerate(("coxa", "femur", "tibia", "tarsus", "direction", "wheel")):
        expected = leg_to_body(chain[:, point, :], GEOMETRY)
        got = np.array([d.xanchor[model.joint(f"{leg}_{joint}").id] for leg in LEG_NAMES])
        np.testing.assert_allclose(got, expected, atol=1e-9, err_msg=joint)


def _vertical_pose(rng: np.random.Generator) -> np.ndarray:
    """Angles (6, 7) with every tarsus vertical: IK to random feet, random direction."""
    feet = stance_feet(CFG.stance("basic"))
    yaw = rng.uniform(-0.6, 0.6, size=6)
    reach = feet[:, 0] + rng.uniform(-0.03, 0.03, size=6)
    targets = np.stack([reach * np.cos(yaw), feet[:, 1], reach * np.sin(yaw)], axis=-1)
    angles = np.zeros((6, 7))
    angles[:, :5] = ik(targets, GEOMETRY, target="contact").angles
    angles[:, 5] = rng.uniform(-math.pi, math.pi, size=6)
    return angles


def test_the_direction_joint_turns_the_wheel_about_the_tarsus_axis(model: mujoco.MjModel) -> None:
    rng = np.random.default_rng(3)
    angles = np.zeros((6, 7))
    angles[:, :5] = rng.uniform(GEOMETRY.lower_limits, GEOMETRY.upper_limits, size=(6, 5))
    d = _at_origin(model, angles)
    wheels = [model.body(f"{leg}_wheel_link").id for leg in LEG_NAMES]
    before = d.xpos[wheels].copy()
    chain = leg_to_body(np.moveaxis(fk_chain(angles[:, :5], GEOMETRY), 1, 0), GEOMETRY)
    segment = chain[6] - chain[3]  # tarsus joint → contact: the last segment
    segment /= np.linalg.norm(segment, axis=-1, keepdims=True)
    for i, leg in enumerate(LEG_NAMES):
        axis = d.xaxis[model.joint(f"{leg}_direction").id]
        assert abs(float(axis @ segment[i])) == pytest.approx(1.0, abs=1e-9)
    angles[:, 5] += 1.0
    d = _at_origin(model, angles)
    np.testing.assert_allclose(d.xpos[wheels], before, atol=1e-9)  # the axle stays on the axis


def test_wheels_roll_forward_along_their_heading(model: mujoco.MjModel) -> None:
    # Positive wheel speed rolls a wheel forward along heading ψ = s·(coxa + direction)
    # (kinematics.wheels), on both sides; the tarsus vertical, the body level.
    rng = np.random.default_rng(11)
    for _ in range(10):
        angles = _vertical_pose(rng)
        d = _at_origin(model, angles)
        heading = heading_from_direction(angles[:, 5], angles[:, 0])
        for i, leg in enumerate(LEG_NAMES):
            axle = d.xpos[model.body(f"{leg}_wheel_link").id]
            contact = d.site_xpos[model.site(f"{leg}_contact").id]
            up = (axle - contact) / np.linalg.norm(axle - contact)
            np.testing.assert_allclose(up, [0.0, 0.0, 1.0], atol=1e-9)
            spin = d.xaxis[model.joint(f"{leg}_wheel").id]
            forward = np.cross(spin, up)  # v = ω × r of the axle about the contact point
            expected = [math.cos(heading[i]), math.sin(heading[i]), 0.0]
            np.testing.assert_allclose(forward, expected, atol=1e-9, err_msg=leg)


# --------------------------------------------------------------------------- masses, limits


def test_the_total_mass_is_the_robots(model: mujoco.MjModel) -> None:
    assert float(model.body_mass.sum()) == pytest.approx(CFG.robot.mass_kg, abs=1e-3)
    assert (model.body_mass[1:] > 0).all()
    assert (model.body_inertia[1:] > 0).all()
    heavier = parse_config({"robot": {"mass_kg": 9.5}})
    assert float(load_model(heavier).body_mass.sum()) == pytest.approx(9.5, abs=1e-3)


def test_the_centre_of_gravity_the_controller_counts_is_the_models() -> None:
    """``body.cog_mm`` (where the stability margin puts the CoG) is where the model's masses
    put it, walking the tripod gait in the default stance (the legs it lifts raise it):
    within 5 mm over a gait cycle. Standing it sits 52 mm below the coxa joints."""
    from whexar.sim.run import Sample, simulate
    from whexar.sim.world import SimWorld

    seen: list[np.ndarray] = []

    def walking(sample: Sample, world: SimWorld) -> None:
        if sample.t > 5.0 and sample.activity.startswith("walking "):
            d, base = world.data, world._base
            rot = d.xmat[base].reshape(3, 3)
            seen.append(rot.T @ (d.subtree_com[base] - d.xpos[base]) * 1000)

    simulate(duration=7.0, commands=[(3.0, command(vx_m_s=0.12))], on_sample=walking)
    assert len(seen) > 30  # two seconds, more than a gait cycle
    assert np.mean(seen, axis=0) == pytest.approx(CFG.body.cog_mm, abs=5.0)


def test_a_robot_lighter_than_its_servos_is_refused() -> None:
    with pytest.raises(ConfigError, match=r"robot\.mass_kg"):
        build_mjcf(parse_config({"robot": {"mass_kg": 5.0}}))


def test_joint_ranges_and_dynamics_follow_the_config(model: mujoco.MjModel) -> None:
    for name in NAMES:
        joint = model.joint(name)
        spec = CFG.joints.by_name(name.split("_", 1)[1])
        limits = spec.limits_rad
        if limits is None:
            assert not model.jnt_limited[joint.id]
        else:
            assert model.jnt_limited[joint.id]
            np.testing.assert_allclose(joint.range, limits)
        motor = MOTORS[spec.model]
        dof = int(model.jnt_dofadr[joint.id])
        assert model.dof_armature[dof] == pytest.approx(motor.armature)
        assert model.dof_damping[dof] == pytest.approx(motor.viscous)
        assert model.dof_frictionloss[dof] == pytest.approx(motor.coulomb)


def test_ir_sites_ride_on_the_front_legs_looking_forward(model: mujoco.MjModel) -> None:
    down = math.radians(CFG.ir.pitch_deg)  # the mount, pitched down
    c, s = math.cos(down), math.sin(down)
    d = _at_origin(model, np.zeros((6, 7)))
    for name, leg, side in (("ir_right", "RF", -1.0), ("ir_left", "LF", 1.0)):
        site = model.site(name)
        assert model.body(site.bodyid[0]).name == f"{leg}_trochanter_link"
        ray = d.site_xmat[site.id].reshape(3, 3)[:, 2]
        np.testing.assert_allclose(ray, [c, 0.0, -s], atol=1e-12)
        assert d.site_xpos[site.id][0] > 0.3
        assert side * d.site_xpos[site.id][1] > 0.1
    # The coxa yaws it; the femur does not move it.
    angles = np.zeros((6, 7))
    angles[:, 0], angles[:, 2] = 0.3, 0.8
    d = _at_origin(model, angles)
    ray = d.site_xmat[model.site("ir_right").id].reshape(3, 3)[:, 2]
    np.testing.assert_allclose(ray, [c * math.cos(0.3), c * math.sin(0.3), -s], atol=1e-12)
    # The body pitched nose down by 0.2 rad, the trochanters following it (eq. 4.18):
    # the rays keep their pitch below the horizon.
    d = mujoco.MjData(model)
    d.qpos[3:7] = [math.cos(0.1), 0.0, math.sin(0.1), 0.0]
    d.qpos[_qadr(model)[1::7]] = 0.2
    mujoco.mj_kinematics(model, d)
    for name in ("ir_right", "ir_left"):
        ray = d.site_xmat[model.site(name).id].reshape(3, 3)[:, 2]
        np.testing.assert_allclose(ray, [c, 0.0, -s], atol=1e-12)


def test_bad_arguments_are_usage_errors() -> None:
    with pytest.raises(UsageError, match="wheel_shape"):
        build_mjcf(CFG, wheel_shape="square")  # type: ignore[arg-type]
    with pytest.raises(UsageError, match="timestep"):
        build_mjcf(CFG, timestep=0.0)


# --------------------------------------------------------------------------- standing


def _stand(m: mujoco.MjModel, seconds: float, wheel_speed: float = 0.0) -> mujoco.MjData:
    """Drop the robot from its keyframe and hold the stance with PD torques; the wheels
    follow ``wheel_speed`` rad/s after the first second."""
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key(STANCE_KEY).id)
    qadr, dadr = _qadr(m), _dadr(m)
    target = stance_angles(CFG).ravel()
    wheel = np.array([name.endswith("_wheel") for name in NAMES])
    act = np.array([m.actuator(n).id for n in NAMES])
    steps = round(seconds / m.opt.timestep)
    for step in range(steps):
        q, w = d.qpos[qadr], d.qvel[dadr]
        tau = 60.0 * (target - q) - 1.0 * w
        speed = wheel_speed if step * m.opt.timestep >= 1.0 else 0.0
        tau[wheel] = 2.0 * (speed - w[wheel])
        d.ctrl[act] = tau
        mujoco.mj_step(m, d)
    return d


@pytest.mark.parametrize("shape", ["sphere", "cylinder"])
def test_the_robot_stands_on_its_six_wheels(shape: WheelShape) -> None:
    m = load_model(CFG, wheel_shape=shape)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key(STANCE_KEY).id)
    assert d.qpos[2] == pytest.approx(default_base_height(CFG))
    d = _stand(m, 1.0)
    height = CFG.stance(CFG.locomotion.stance).height
    assert d.qpos[2] == pytest.approx(height, abs=0.003)  # contact and servo sag < 3 mm
    up = d.xmat[m.body("base").id].reshape(3, 3)[:, 2]
    assert math.degrees(math.acos(min(1.0, up[2]))) < 0.2
    assert np.abs(d.qvel[:6]).max() < 1e-3
    wheels = {m.geom(f"{leg}_wheel").id for leg in LEG_NAMES}
    touching = {int(g) for c in d.contact[: d.ncon] for g in (c.geom1, c.geom2)}
    assert wheels <= touching
    floor = m.geom("floor").id
    assert touching <= wheels | {floor}, "only the wheels touch the floor"


def test_turning_wheels_drive_the_robot_forward_without_slip() -> None:
    # Heading 0 on every leg (direction = −coxa): positive wheel speed drives +x.
    m = load_model(CFG)
    speed = 0.1  # m/s at the contact
    rate = speed / GEOMETRY.wheel_radius
    before = _stand(m, 1.5, wheel_speed=rate)
    x0, wheels0 = float(before.qpos[0]), before.qpos[_qadr(m)][6::7].copy()
    after = mujoco.MjData(m)
    mujoco.mj_copyData(after, m, before)
    qadr, dadr = _qadr(m), _dadr(m)
    target = stance_angles(CFG).ravel()
    wheel = np.array([name.endswith("_wheel") for name in NAMES])
    for _ in range(round(1.0 / m.opt.timestep)):  # 1 s
        q, w = after.qpos[qadr], after.qvel[dadr]
        tau = 60.0 * (target - q) - 1.0 * w
        tau[wheel] = 2.0 * (rate - w[wheel])
        after.ctrl[[m.actuator(n).id for n in NAMES]] = tau
        mujoco.mj_step(m, after)
    moved = float(after.qpos[0]) - x0
    rolled = float((after.qpos[qadr][6::7] - wheels0).mean()) * GEOMETRY.wheel_radius
    assert moved == pytest.approx(speed * 1.0, rel=0.05)
    assert abs(float(after.qpos[1])) < 1e-4
    assert moved / rolled == pytest.approx(1.0, abs=0.005)  # slip below 0.5 %


def test_the_stance_keyframe_holds_the_stance_angles(model: mujoco.MjModel) -> None:
    key = model.key(STANCE_KEY)
    angles = key.qpos[_qadr(model)].reshape(6, 7)
    solution = ik(stance_feet(CFG.stance(CFG.locomotion.stance)), GEOMETRY, target="contact")
    np.testing.assert_allclose(angles[:, :5], solution.angles)
    np.testing.assert_allclose(angles[:, 5], -solution.angles[:, 0])  # heading 0
    np.testing.assert_allclose(key.qpos[3:7], [1.0, 0.0, 0.0, 0.0])


# --------------------------------------------------------------------------- URDF


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    x, y, z = axis / np.linalg.norm(axis)
    c, s = math.cos(angle), math.sin(angle)
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    result: np.ndarray = np.eye(3) + s * k + (1 - c) * (k @ k)
    return result


def _rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    rx = _rotation(np.array([1.0, 0.0, 0.0]), roll)
    ry = _rotation(np.array([0.0, 1.0, 0.0]), pitch)
    rz = _rotation(np.array([0.0, 0.0, 1.0]), yaw)
    result: np.ndarray = rz @ ry @ rx
    return result


def test_the_urdf_has_the_same_kinematics() -> None:
    import xml.etree.ElementTree as ET

    from whexar.sim.urdf import build_urdf

    # The rangefinders mounted level, so that the ray's x is cos(coxa)·cos(trochanter).
    robot = ET.fromstring(build_urdf(RobotConfig.model_validate({"ir": {"pitch_deg": 0.0}})))
    rng = np.random.default_rng(5)
    angles = np.zeros((6, 7))
    angles[:, :5] = rng.uniform(GEOMETRY.lower_limits, GEOMETRY.upper_limits, size=(6, 5))
    values = dict(zip(NAMES, angles.ravel(), strict=True))
    poses: dict[str, tuple[np.ndarray, np.ndarray]] = {"base": (np.eye(3), np.zeros(3))}
    pending = list(robot.iter("joint"))
    while pending:  # joints in any order: place each once its parent is placed
        joint = pending.pop(0)
        parent = joint.find("parent").get("link")  # type: ignore[union-attr]
        child = joint.find("child").get("link")  # type: ignore[union-attr]
        if parent not in poses:
            pending.append(joint)
            continue
        origin = joint.find("origin")
        assert origin is not None
        xyz = np.array([float(v) for v in origin.get("xyz", "0 0 0").split()])
        rpy = [float(v) for v in origin.get("rpy", "0 0 0").split()]
        rot, pos = poses[parent]
        rot_child, pos_child = rot @ _rpy_matrix(*rpy), pos + rot @ xyz
        if joint.get("type") != "fixed":
            axis = joint.find("axis")
            assert axis is not None
            a = np.array([float(v) for v in axis.get("xyz", "1 0 0").split()])
            rot_child = rot_child @ _rotation(a, values[str(joint.get("name"))])
        poses[str(child)] = (rot_child, pos_child)
    expected = leg_to_body(fk(angles[:, :5], GEOMETRY, point="contact"), GEOMETRY)
    got = np.array([poses[f"{leg}_contact"][1] for leg in LEG_NAMES])
    np.testing.assert_allclose(got, expected, atol=1e-6)
    ray = poses["ir_left"][0][:, 2]
    assert ray[0] == pytest.approx(math.cos(angles[1, 0]) * math.cos(angles[1, 1]), abs=1e-9)
