"""The world's physical faults: a push, a slippery ground, a limp servo, a snagged joint.

Each is shown by what it does to the robot against the same world without it (or with
the bus's ``silent`` in its place), and each scenario key is checked before a run."""

from __future__ import annotations

import functools
import math
import typing
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest

from whexar.actors.messages import (
    BusLost,
    ServoDegraded,
    ServoFault,
    ServoRecovered,
    WorldFault,
)
from whexar.bus.control_table import CENTER_TICKS
from whexar.bus.emulator.chain import ServoChain
from whexar.bus.protocol import Instruction, encode_instruction
from whexar.config import RobotConfig
from whexar.errors import ConfigError
from whexar.kinematics.body import stance_feet
from whexar.kinematics.leg import ik
from whexar.record.reader import Recording
from whexar.robot import JOINT_NAMES, LEG_NAMES
from whexar.sim import spread as sp
from whexar.sim.faults import JointName, PushFault, SlipperyFault, WorldFaultSpec
from whexar.sim.model import load_model
from whexar.sim.motors import TICKS_PER_RAD
from whexar.sim.run import SimResult, simulate
from whexar.sim.scenario import parse_scenario
from whexar.sim.terrain import GROUND_FRICTION, Floor
from whexar.sim.world import Patch, SimWorld

CFG = RobotConfig()
RF_FEMUR = 3  # servo IDs (eq. 4.1)
RF_COXA = 1
STANDING_S = 3.0
"""The simulated robot stands up from its seat by 2.5 s."""


def _problems(faults: list[Any], **extra: Any) -> dict[str, str]:
    """Key path → "value: allowed" of every problem of a scenario with these faults."""
    with pytest.raises(ConfigError) as info:
        parse_scenario({"duration_s": 5.0, "world_faults": faults, **extra}, "test.toml")
    return {p.path: f"{p.value!r}: {p.allowed}" for p in info.value.problems}


# --------------------------------------------------------------------------- the keys


def test_each_kind_parses_with_its_own_keys() -> None:
    s = parse_scenario(
        {
            "duration_s": 10.0,
            "world_faults": [
                {
                    "kind": "push",
                    "at_s": 4.0,
                    "force_n": 60.0,
                    "heading_deg": 90.0,
                    "duration_s": 0.3,
                },
                {"kind": "slippery", "at_s": 0.0, "friction": 0.1, "x_m": [1.0, 1.5]},
                {"kind": "slippery", "at_s": 5.0, "friction": 0.2, "leg": 3, "duration_s": 2},
                {"kind": "limp", "at_s": 6.0, "ids": [3], "duration_s": 1.5},
                {"kind": "limp", "at_s": 6.0, "leg": 1, "joint": "tibia"},
                {"kind": "snag", "at_s": 7.0, "leg": 2, "joint": "tibia", "duration_s": 1.0},
            ],
        },
        "test.toml",
    )
    push, area, foot, limp, limp2, snag = s.world_faults
    assert isinstance(push, PushFault)
    assert push.force() == pytest.approx((0.0, 60.0, 0.0), abs=1e-12)
    assert push.ends_at == pytest.approx(4.3)
    assert isinstance(area, SlipperyFault)
    assert area.area == ((1.0, 1.5), None)
    assert area.ends_at is None  # duration 0: for good
    assert foot.describe(CFG) == ("LM wheel", "µ 0.2 for 2 s")
    assert limp.describe(CFG) == ("servo 3 (RF femur)", "no power for 1.5 s")
    assert limp2.describe(CFG)[0] == "servo 11 (LF tibia)"
    assert snag.describe(CFG) == ("RM tibia", "blocked for 1 s")


def test_a_push_points_along_its_heading_and_elevation() -> None:
    push = PushFault(
        kind="push",
        at_s=1.0,
        force_n=10.0,
        heading_deg=-135.0,
        elevation_deg=30.0,
        duration_s=0.1,
    )
    fx, fy, fz = push.force()
    flat = 10.0 * math.cos(math.radians(30))
    assert (fx, fy) == pytest.approx((-flat / math.sqrt(2), -flat / math.sqrt(2)))
    assert fz == pytest.approx(5.0)
    assert math.hypot(fx, fy, fz) == pytest.approx(10.0)


def test_joint_names_are_the_robots() -> None:
    assert typing.get_args(JointName) == JOINT_NAMES


def test_bad_values_are_named_by_their_key() -> None:
    found = _problems(
        [
            {"kind": "push", "at_s": -1.0, "force_n": 0.0, "duration_s": 0.2},
            {"kind": "push", "at_s": 1.0, "force_n": 5.0, "heading": 90, "duration_s": 0.2},
            {"kind": "push", "at_s": 1.0, "force_n": 5.0},
            {"kind": "melt", "at_s": 1.0},
            {"kind": "snag", "at_s": 1.0, "leg": 6, "joint": "knee"},
            "push",
        ]
    )
    assert found["world_faults[0].at_s"].startswith("-1.0: Input should be greater than or equal")
    assert found["world_faults[0].force_n"].startswith("0.0: Input should be greater than 0")
    # An unknown key lists the keys of its kind, not another kind's.
    heading = found["world_faults[1].heading"]
    assert heading.startswith("90: unknown key; allowed here: ")
    assert "heading_deg" in heading
    assert "friction" not in heading
    assert found["world_faults[2].duration_s"] == "(missing): required key is missing"
    assert found["world_faults[3].kind"] == ("'melt': one of 'push', 'slippery', 'limp', 'snag'")
    assert found["world_faults[4].leg"].startswith("6: Input should be less than or equal to 5")
    assert "'femur'" in found["world_faults[4].joint"]
    assert found["world_faults[5]"].startswith("'push': a table")


def test_a_slippery_ground_is_under_a_wheel_or_an_area() -> None:
    found = _problems(
        [
            {"kind": "slippery", "at_s": 1.0, "friction": 0.1, "leg": 0, "x_m": [0, 1]},
            {"kind": "slippery", "at_s": 1.0, "friction": 0.1},
            {"kind": "slippery", "at_s": 1.0, "friction": 0.1, "y_m": [1.0, -1.0]},
            {"kind": "slippery", "at_s": 1.0, "friction": -0.1, "leg": 0},
        ]
    )
    assert found["world_faults[0].x_m"] == "(0.0, 1.0): not with leg: under a wheel or an area"
    assert found["world_faults[1].leg"].startswith("(missing): a leg (0–5), or an area")
    assert found["world_faults[2].y_m"] == "[1.0, -1.0]: [min, max] with min < max, m"
    assert found["world_faults[3].friction"].startswith("-0.1: Input should be greater")


def test_a_limp_servo_is_named_once_and_is_the_robots() -> None:
    found = _problems(
        [
            {"kind": "limp", "at_s": 1.0},
            {"kind": "limp", "at_s": 1.0, "ids": [3], "leg": 0},
            {"kind": "limp", "at_s": 1.0, "leg": 0},
            {"kind": "limp", "at_s": 1.0, "ids": [3, 99]},
        ]
    )
    assert found["world_faults[0].ids"].startswith("(missing): servo IDs such as [3]")
    assert found["world_faults[1].leg"] == "0: not with ids: ids or leg + joint"
    assert found["world_faults[2].joint"].startswith("(missing): a joint with leg")
    assert found["world_faults[3].ids[1]"] == "99: a servo of the robot (its legs' servo_ids)"


def test_a_bad_fault_is_reported_beside_another_bad_key() -> None:
    found = _problems([{"kind": "snag", "at_s": 1.0, "leg": 0}], seed=-1)
    assert set(found) == {"seed", "world_faults[0].joint"}


# --------------------------------------------------------------------------- in the world
# Worlds without the runtime: the servos told directly, the world stepped by bus time.


def _standing(*, in_the_air: bool = False) -> tuple[SimWorld, ServoChain]:
    """The robot in its stance, every servo holding where it is: on the floor, or held
    still in the air by its body, its legs hanging."""
    model = load_model(CFG)
    if in_the_air:
        model.dof_armature[0:6] = 1e9  # the body does not move
    chain = ServoChain.for_models(CFG.servos(), baudrate=CFG.bus.baudrate)
    world = SimWorld(model, chain, cfg=CFG)
    stance = CFG.stance(CFG.locomotion.stance)
    angles = ik(stance_feet(stance), CFG.leg_geometry(), target="contact").angles
    pose = {(leg, j): float(angles[leg, j]) for leg in range(6) for j in range(5)}
    if in_the_air:
        world.set_pose(pose, base_xyz=(0.0, 0.0, 1.0))
    else:
        xyz, quat = Floor().start_pose(stance.height + 0.001)
        world.set_pose(pose, base_xyz=xyz, base_quat=quat)
    for servo in chain.servos.values():
        servo.set_register("goal_position", round(servo.position))
        servo.set_register("torque_enable", 1)
    _run(world, 0.0, 0.1)
    return world, chain


def _run(world: SimWorld, start: float, end: float) -> None:
    """Bus transactions every 10 ms from ``start`` to ``end``."""
    for k in range(round(start * 100) + 1, round(end * 100) + 1):
        world.move_servos(k / 100)


def _wheel_friction(world: SimWorld) -> dict[int, float]:
    """The sliding µ of each wheel's contact with the ground, by leg: what MuJoCo's
    solver uses for the contact."""
    m, d = world.model, world.data
    wheels = {
        mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"{name}_wheel"): leg
        for leg, name in enumerate(LEG_NAMES)
    }
    out = {}
    for k in range(d.ncon):
        for g in d.contact.geom[k]:
            if int(g) in wheels:
                out[wheels[int(g)]] = float(d.contact.friction[k, 0])
    return out


@pytest.mark.slow
def test_a_slippery_patch_sets_the_friction_its_wheels_contacts_see() -> None:
    world, _ = _standing()
    nominal = GROUND_FRICTION[0]
    assert _wheel_friction(world) == dict.fromkeys(range(6), nominal)
    # Ice under the front wheels (x ≈ +0.38 m), oil under RR's wheel (x ≈ −0.38 m).
    world.slip("ice", Patch(0.1, x=(0.2, 1.0)))
    world.slip("oil", Patch(0.3, leg=4))
    _run(world, 0.1, 0.15)
    assert _wheel_friction(world) == pytest.approx(
        {0: 0.1, 1: 0.1, 2: nominal, 3: nominal, 4: 0.3, 5: nominal}
    )
    # A later patch lies on top; an ended one leaves the floor as it was.
    world.slip("wet", Patch(0.6, y=(-1.0, 0.0)))  # the right side
    world.slip("oil", None)
    _run(world, 0.15, 0.2)
    assert _wheel_friction(world) == pytest.approx(
        {0: 0.6, 1: 0.1, 2: 0.6, 3: nominal, 4: 0.6, 5: nominal}
    )
    world.slip("ice", None)
    world.slip("wet", None)
    _run(world, 0.2, 0.25)
    assert _wheel_friction(world) == dict.fromkeys(range(6), nominal)


@pytest.mark.slow
def test_the_spread_of_the_tyres_scales_a_patch_as_it_scales_the_floor() -> None:
    world, _ = _standing()
    sp.apply(sp.Spread.draw(5, world.model, len(world.joints)), world)
    tyres = world.wheel_friction.copy()
    assert not np.allclose(tyres, GROUND_FRICTION[0])
    world.slip("oil", Patch(0.2, leg=1))
    _run(world, 0.1, 0.15)
    seen = _wheel_friction(world)
    assert seen[1] == pytest.approx(0.2 * tyres[1] / GROUND_FRICTION[0])
    assert seen[0] == pytest.approx(tyres[0])


@pytest.mark.slow
def test_a_limp_servo_lets_its_joint_fall_where_a_silent_one_holds() -> None:
    femur = JOINT_NAMES.index("femur")
    dropped = {}
    for how in ("limp", "silent"):
        world, chain = _standing(in_the_air=True)
        q0 = list(world.q)
        if how == "limp":
            world.limp("cut", [RF_FEMUR], 0.1)
        else:  # the bus fault plan's silent: no reply, but the servo holds its goal
            chain.faults.silent_until[RF_FEMUR] = math.inf
        _run(world, 0.1, 0.6)
        dropped[how] = abs(world.q[femur] - q0[femur])
        assert abs(world.q[7 + femur] - q0[7 + femur]) < 0.005  # LF's femur holds
        assert chain.transact(_ping(RF_FEMUR), 0.61).reply == b""  # neither answers
    # The leg's own weight, against the gears' friction alone, pulls the limp femur down.
    assert dropped["limp"] > 0.5
    assert dropped["silent"] < 0.005
    servo = chain.servos[RF_FEMUR]
    assert servo.torque_enabled  # the silent one


@pytest.mark.slow
def test_a_servo_whose_power_returns_boots_with_its_torque_off() -> None:
    world, chain = _standing(in_the_air=True)
    world.limp("cut", [RF_FEMUR], 0.1)
    servo = chain.servos[RF_FEMUR]
    assert not servo.powered
    assert RF_FEMUR in world.unpowered
    _run(world, 0.1, 0.3)
    world.limp("cut", None, 0.3)
    assert servo.powered
    assert not servo.torque_enabled
    assert chain.transact(_ping(RF_FEMUR), 0.31).reply == b""  # booting
    assert chain.transact(_ping(RF_FEMUR), 0.3 + servo.boot_time_s + 0.01).reply != b""
    assert not servo.torque_enabled  # until the bus enables it


def _ping(sid: int) -> bytes:
    return encode_instruction(sid, Instruction.PING)


# --------------------------------------------------------------------------- in a run


@functools.cache
def _run_with(*faults: WorldFaultSpec, duration: float = 4.0) -> SimResult:
    return simulate(duration=duration, world_faults=faults, keep_log=True)


def _push(force: float, heading: float) -> PushFault:
    return PushFault(
        kind="push", at_s=STANDING_S, force_n=force, heading_deg=heading, duration_s=0.4
    )


ICE = SlipperyFault(kind="slippery", at_s=2.9, friction=0.05, x_m=(-1.0, 1.0), y_m=(-1.0, 1.0))


def _at(result: SimResult, t: float) -> tuple[float, float]:
    s = min(result.samples, key=lambda s: abs(s.t - t))
    return s.x, s.y


@pytest.mark.slow
def test_a_push_moves_the_standing_body_its_way() -> None:
    still = _run_with()
    pushed = _run_with(_push(60.0, 90.0))
    x0, y0 = _at(still, 3.4)
    x1, y1 = _at(pushed, 3.4)
    assert abs(x0) < 1e-3
    assert abs(y0) < 1e-3
    # 60 N for 0.4 s sideways, 8.8 kg: the body rolls onto its downhill wheels and gives
    # 13 cm by the push's end; it settles back, 1 cm aside.
    assert y1 - y0 > 0.05
    assert abs(x1 - x0) < 0.01
    assert _at(pushed, 4.0)[1] - _at(still, 4.0)[1] > 0.005
    events = [e for e in pushed.events if isinstance(e, WorldFault)]
    assert [(e.kind, e.target, e.active) for e in events] == [
        ("push", "body", True),
        ("push", "body", False),
    ]
    assert [e.t for e in events] == pytest.approx([3.0, 3.4])


@pytest.mark.slow
def test_on_ice_the_same_push_slides_the_robot_away() -> None:
    # 30 N is nothing to six rubber tyres on the floor (µ 1.3); on ice (µ 0.05: 4 N of
    # friction for 86 N of weight) the body slides off along the push.
    dry = _run_with(_push(30.0, -135.0))
    icy = _run_with(ICE, _push(30.0, -135.0))
    x, y = _at(dry, 4.0)
    assert math.hypot(x, y) < 0.01
    x, y = _at(icy, 4.0)
    assert math.hypot(x, y) > 0.3
    assert math.degrees(math.atan2(y, x)) == pytest.approx(-135.0, abs=10.0)
    assert _at(_run_with(ICE), 4.0) == pytest.approx((0.0, 0.0), abs=0.01)  # ice alone


@pytest.mark.slow
def test_a_limp_femur_goes_silent_on_the_bus_and_is_moved_only_by_its_load() -> None:
    doc = {
        "duration_s": 4.5,
        "world_faults": [{"kind": "limp", "at_s": STANDING_S, "leg": 0, "joint": "femur"}],
    }
    femur = JOINT_NAMES.index("femur")
    seen: list[tuple[float, float, bool]] = []

    def look(s: Any, w: SimWorld) -> None:
        seen.append((s.t, w.q[femur], w.chain.servos[RF_FEMUR].torque_enabled))

    result = parse_scenario(doc, "test.toml").run(on_sample=look, keep_log=True)
    log = result.run.log
    faults = log.events(of=ServoFault)
    assert {f.servo_id for f in faults} == {RF_FEMUR}
    assert min(f.t for f in faults) > STANDING_S
    assert [d.servo_id for d in log.events(of=ServoDegraded)] == [RF_FEMUR]
    assert log.events(of=BusLost)  # a femur: the robot stops safely and sits down
    assert not result.world.chain.servos[RF_FEMUR].powered
    # Its motor off from the fault on, the femur still turns by a radian as the robot
    # sits: its planted foot and the leg's other joints carry it along.
    after = [(q, torque) for t, q, torque in seen if t > STANDING_S + 0.01]
    assert not any(torque for _, torque in after)
    assert after[-1][0] - after[0][0] > 1.0


@pytest.mark.slow
def test_a_coxa_whose_power_returns_is_rebooted_and_back_in_the_cycle() -> None:
    doc = {
        "duration_s": 4.3,
        "world_faults": [{"kind": "limp", "at_s": STANDING_S, "ids": [RF_COXA], "duration_s": 0.3}],
    }
    seen: list[tuple[float, bool, bool]] = []

    def look(s: Any, w: SimWorld) -> None:
        servo = w.chain.servos[RF_COXA]
        seen.append((s.t, servo.powered, servo.torque_enabled))

    result = parse_scenario(doc, "test.toml").run(on_sample=look, keep_log=True)
    log = result.run.log
    assert [d.servo_id for d in log.events(of=ServoDegraded)] == [RF_COXA]
    assert [r.servo_id for r in log.events(of=ServoRecovered)] == [RF_COXA]
    assert not log.events(of=BusLost)
    assert all(not powered for t, powered, _ in seen if 3.05 < t < 3.25)
    # Powered again, it boots with its torque off; the bus finds it and enables it.
    assert all(powered and not torque for t, powered, torque in seen if 3.35 < t < 3.65)
    assert all(powered and torque for t, powered, torque in seen if 4.1 < t < 4.3)


@pytest.mark.slow
def test_a_snag_holds_its_joint_while_the_goal_moves_and_lets_go_after() -> None:
    femur = JOINT_NAMES.index("femur")
    rows: list[tuple[float, float, float, float, float]] = []

    def look(s: Any, w: SimWorld) -> None:
        rf, lf = w.joints[femur], w.joints[7 + femur]
        goal = (rf.servo.goal - CENTER_TICKS) / TICKS_PER_RAD
        amps = [abs(j.servo.register_value("present_current")) for j in (rf, lf)]
        rows.append((s.t, w.q[femur], goal, amps[0], amps[1]))

    # Standing up from the seat, 1–2 s: the femurs turn by a radian.
    snag = parse_scenario(
        {
            "duration_s": 2.6,
            "world_faults": [
                {"kind": "snag", "at_s": 1.0, "leg": 0, "joint": "femur", "duration_s": 1.0}
            ],
        },
        "test.toml",
    )
    snag.run(on_sample=look)
    held = [r for r in rows if 1.05 < r[0] < 2.0]
    q = [r[1] for r in held]
    goals = [r[2] for r in held]
    assert max(q) - min(q) < 0.01
    assert max(goals) - min(goals) > 0.5
    # Stalled against it, the servo draws several amperes; its twin on LF a fraction.
    assert max(r[3] for r in held) > 5 * max(r[4] for r in held)
    free = [r for r in rows if 2.4 < r[0] <= 2.6]  # stood up (the run then sits down)
    assert all(abs(r[1] - r[2]) < 0.05 for r in free)  # free: at its goal again
    assert all(abs(r[1] - q[-1]) > 0.5 for r in free)


# --------------------------------------------------------------------------- runs repeat


@pytest.mark.slow
def test_the_same_faults_give_the_same_run_and_are_recorded(tmp_path: Path) -> None:
    doc = {
        "duration_s": 4.0,
        "seed": 3,
        "spread": True,
        "world_faults": [
            {"kind": "slippery", "at_s": 2.0, "friction": 0.3, "leg": 2},
            {
                "kind": "push",
                "at_s": 3.0,
                "force_n": 40.0,
                "heading_deg": 30.0,
                "elevation_deg": -10.0,
                "duration_s": 0.2,
            },
            {"kind": "snag", "at_s": 3.1, "leg": 5, "joint": "tarsus", "duration_s": 0.4},
            {"kind": "limp", "at_s": 3.2, "leg": 4, "joint": "direction", "duration_s": 0.3},
        ],
    }
    scenario = parse_scenario(doc, "test.toml")
    plain = scenario.run()
    path = tmp_path / "faults.mcap"
    recorded = scenario.run(record=path)
    assert plain.world.state_hash() == recorded.world.state_hash()
    said = [e for e in plain.events if isinstance(e, WorldFault)]
    assert [(e.kind, e.active) for e in said] == [
        ("slippery", True),
        ("push", True),
        ("snag", True),
        ("push", False),  # at one time, ends come first
        ("limp", True),
        ("snag", False),
        ("limp", False),
    ]
    assert [e.t for e in said] == pytest.approx([2.0, 3.0, 3.1, 3.2, 3.2, 3.5, 3.5])
    kept = [r.value for r in Recording(path).records() if isinstance(r.value, WorldFault)]
    assert kept == said  # the same events, field for field
