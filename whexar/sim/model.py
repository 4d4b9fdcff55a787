"""The MuJoCo (MJCF) model of WHexaR, generated from a :class:`~whexar.config.RobotConfig`.

Theory of operation
-------------------
*One chain, two writers.* :func:`robot_links` turns the configuration into a list of
links — bodies with their joint, geoms and sites — and :func:`build_mjcf` writes them as
MJCF (:mod:`whexar.sim.urdf` writes the same links as URDF). Every link frame is
parallel to the body frame when all joints are at 0 and sits at its joint, so positions
are plain differences of the points of the kinematics and a joint's axis is a vector in
the body frame: no rotations to compose, and nothing to get wrong between the writers.

*Joint angles are whexar's.* The geometry at q = 0 comes from the DH table
(:func:`whexar.kinematics.leg.dh_transforms` with all angles 0) and each hinge's axis is
the DH axis z_{k−1} times the joint's ``theta_sign`` (Table 5.3 with the sign flips that
map Table 6.5's convention onto it, :class:`~whexar.config.DHRow`). The hinge angle is
then the number the kinematics and the bus use. Left legs are mirror images of right
legs (:mod:`whexar.kinematics.geometry`); a mirror is not a rotation, so a left leg is
built as the reflection of a right one: points reflect, and an axis reflects and
flips (a mirrored rotation turns the other way: P·R(a, q)·P⁻¹ = R(−P·a, q) for a
reflection P). The test compares every leg's contact site with
:func:`~whexar.kinematics.leg.fk` over random poses.

*Chassis.* The direction joint turns the wheel about the last segment, at its end; its
axis points up the segment on a right leg, so that a positive angle turns the wheel
counter-clockwise seen from above when the tarsus is vertical, as
:mod:`whexar.kinematics.wheels` has it (direction = s·heading − coxa). The wheel's axle
lies ``direction_length`` (42 mm) further down, across the leg plane, oriented so that
a positive wheel speed rolls the wheel forward along its heading on both sides.

*Contact site.* ``{leg}_contact`` is the kinematics' contact point, the axle plus the
wheel radius along the last segment: the bottom of the wheel when the tarsus is
vertical. It sits on the wheel's fork (the body the direction joint turns), not on the
spinning wheel, where it would circle the axle as the wheel rolls.

*Masses* (8.8 kg in all, Table 6.8): every servo's mass (Table 5.1) sits at its joint,
on the link that carries its housing — the one before the joint, since the horn turns
the next link (so the wheel servo does not spin with the wheel); brackets are light
capsules and boxes of estimated mass (:data:`BRACKET_MASS_KG`); the body tube
(600 × 100 × 60 mm, 5.2) takes the rest. Each geom carries its mass, and MuJoCo derives
the links' inertias from the shapes.

*Collisions.* Robot geoms touch the terrain but never each other (MuJoCo's contype and
conaffinity bits, :mod:`whexar.sim.terrain`): the legs' workspaces overlap by design
and the real robot avoids collisions in its controller (5.2); self-contacts would only
add noise and cost. Colliding: the body box, the leg segments (so a leg hits a block,
6.7.2) and the wheels. Servo boxes and the wheel fork are visual (and carry mass).

*Contacts.* An elliptic friction cone with ``impratio`` 10: on a slope with the wheels
held, the robot creeps a twentieth as fast as under MuJoCo's default pyramidal cone,
for a modest cost per step; ``noslip`` would stop the creep entirely but costs more
again (docs/sim.md, "Body, legs and wheels", has the figures). The wheel is a
sphere by default (see :data:`WHEEL_SHAPES`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Final, Literal

import numpy as np

from whexar._typing import FloatArray
from whexar.config import RobotConfig
from whexar.errors import ConfigError, Problem, UsageError
from whexar.kinematics.body import stance_feet
from whexar.kinematics.geometry import DH_TO_LEG, SIDE_SIGN
from whexar.kinematics.leg import dh_transforms, ik
from whexar.robot import JOINT_NAMES, LEG_NAMES
from whexar.runtime.checks import positive
from whexar.sim.motors import MOTORS
from whexar.sim.terrain import GROUND_FRICTION, Box, Terrain, flat

if TYPE_CHECKING:
    import mujoco

WheelShape = Literal["sphere", "cylinder"]

WHEEL_SHAPES: Final[tuple[WheelShape, ...]] = ("sphere", "cylinder")
"""Wheel geoms on offer; ``"sphere"`` is the default.

A sphere of the wheel's radius touches the ground at the kinematics' contact point
whenever the axle is horizontal, and also when the trochanter tilts the leg (the
tyres of Fig. 5.2 are round in section too). One contact per wheel with ``condim`` 3
against two with ``condim`` 6: a cheaper step (docs/sim.md has the times). Both roll
without slip beyond the tyre's sinking (:data:`WHEEL_SOLREF`) and hold on a 15° slope
with the wheels braked, creeping a fraction of a millimetre a second. A sphere has no
scrub torque when
the direction servo turns it in place, and it is wider than the tyre, which matters
only against obstacles at the wheel's side. ``"cylinder"`` is the true shape, 26 mm
wide, with torsional and rolling friction (``condim`` 6).
"""

ROBOT_CONTYPE: Final = 2
ROBOT_CONAFFINITY: Final = 1
"""Robot geoms: bit 2 meets the terrain's conaffinity, bit 1 the terrain's contype;
two robot geoms share no bit (2 & 1 = 0), so the robot never collides with itself."""
ROBOT_COLLISION_GROUP: Final = 1
ROBOT_VISUAL_GROUP: Final = 2
"""Geom groups of the robot's colliding and visual-only geoms (terrain: group 0)."""

SERVO_SIZE_MM: Final[dict[str, tuple[float, float, float]]] = {
    # Table 5.1: width, height, depth. The box's depth lies along the joint axis.
    "MX-28": (35.6, 50.6, 35.5),
    "MX-64": (40.2, 61.1, 41.0),
    "MX-106": (40.2, 65.1, 46.0),
}

BRACKET_MASS_KG: Final[dict[str, float]] = {
    # Estimates: the thesis weighs only the servos (Table 5.1) and the whole robot
    # (8.8 kg, 6.8.1). Aluminium brackets of 1.5–2 mm sheet, two plates per long segment.
    "coxa": 0.040,  # the one bracket linking coxa and trochanter (Fig. 5.3)
    "trochanter": 0.030,  # 63 mm (Table 5.2)
    "femur": 0.060,  # 127 mm
    "tibia": 0.060,  # 124 mm
    "tarsus": 0.040,  # 95 mm, with the FSR and its spacer (5.3.3)
    "direction": 0.020,  # the fork holding the wheel servo
}
WHEEL_MASS_KG: Final = 0.040
"""An RC-model wheel of 66 mm with a foam-filled rubber tyre (Fig. 5.2): an estimate."""
WHEEL_WIDTH: Final = 0.026
"""Tyre width of the cylinder wheel, m: an estimate for a 66 mm RC tyre."""
SEGMENT_RADIUS: Final = 0.02
"""Radius of the leg segments' capsules: half the servos' 40 mm width (Table 5.1)."""
IR_FORWARD: Final = 0.023
"""The IR sensor sits on the femur servo's front face: half the MX-106's 46 mm depth
(Table 5.1) ahead of the femur joint, along the femur axis."""
MIN_BODY_MASS_KG: Final = 0.1
DROP_CLEARANCE: Final = 0.005
"""Default height of the wheels above the floor at the start, m: the robot drops onto it."""
WHEEL_SOLREF: Final = (0.005, 1.0)
"""Wheel contacts: time constant 5 ms (MuJoCo's default 20 ms), critically damped.

A stiffer contact sinks less, and on the flat the "slip" of a rolling wheel is mostly
that sinking: the tyre rolls on a radius shorter by its penetration, and 5 ms cuts it
to an eighth of the default's (docs/sim.md, "Body, legs and wheels", has the figures).
5 ms is 2 steps of 2.5 ms; MuJoCo raises a time constant below 2 timesteps to 2
timesteps itself (``refsafe``), so a longer timestep stays stable, with softer wheels."""
TIMESTEP_S: Final = 0.0025
"""The physics timestep: 2.5 ms, chosen by measurement (docs/sim.md, "Time and timestep").

It agrees with 1 ms within millimetres over the whole course, and it is the longest step
that keeps the wheels' 5 ms contact time constant (:data:`WHEEL_SOLREF`) at MuJoCo's
two-timestep floor instead of raising it."""
STANCE_KEY: Final = "stance"
"""Name of the keyframe in which the robot stands in its configured stance."""

_SERVO_RGBA = "0.12 0.12 0.13 1"
_BRACKET_RGBA = "0.75 0.76 0.78 1"
_BODY_RGBA = "0.62 0.64 0.68 1"
_WHEEL_RGBA = "0.08 0.08 0.08 1"

Vec3 = tuple[float, float, float]


# --------------------------------------------------------------------------- the link list


@dataclass(frozen=True)
class ModelGeom:
    """A geom in its link's frame.

    ``size`` is MuJoCo's: box half-extents, (radius, half-length) of a capsule or cylinder
    along the geom's z, (radius,) of a sphere. ``rot``'s columns are the geom's axes.
    """

    shape: Literal["box", "capsule", "cylinder", "sphere"]
    size: tuple[float, ...]
    pos: Vec3
    rot: tuple[Vec3, Vec3, Vec3]
    mass: float
    collide: bool
    rgba: str
    name: str | None = None


@dataclass(frozen=True)
class ModelSite:
    """A site in its link's frame; ``zaxis`` is the site's +z (a ray's direction)."""

    name: str
    pos: Vec3
    zaxis: Vec3 = (0.0, 0.0, 1.0)


@dataclass(frozen=True)
class ModelJoint:
    """A hinge at its link's origin; ``limits`` is None for an endless joint."""

    name: str
    axis: Vec3
    limits: tuple[float, float] | None
    servo: str
    armature: float
    damping: float
    frictionloss: float
    effort: float
    """Stall torque at the supply voltage (Table 5.1), N·m."""
    velocity: float
    """No-load speed at the supply voltage (:mod:`whexar.sim.motors`), rad/s."""


@dataclass(frozen=True)
class ModelLink:
    """A rigid body: frame parallel to the base's at q = 0, origin at its joint."""

    name: str
    parent: str | None
    pos: Vec3
    """Origin relative to the parent's origin, m (the base: relative to the world)."""
    joint: ModelJoint | None
    geoms: tuple[ModelGeom, ...]
    sites: tuple[ModelSite, ...] = ()


def _vec(a: FloatArray) -> Vec3:
    return (float(a[0]), float(a[1]), float(a[2]))


def _frame(z: FloatArray, hint: FloatArray | None = None) -> tuple[Vec3, Vec3, Vec3]:
    """Columns (x, y, z) of a right-handed frame with the given z, x as close to ``hint``."""
    zn = z / np.linalg.norm(z)
    h = np.array([1.0, 0.0, 0.0]) if hint is None else np.asarray(hint, dtype=np.float64)
    x = h - zn * float(h @ zn)
    if np.linalg.norm(x) < 1e-9:
        for cand in (np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])):
            x = cand - zn * float(cand @ zn)
            if np.linalg.norm(x) > 1e-6:
                break
    x = x / np.linalg.norm(x)
    y = np.cross(zn, x)
    return _vec(x), _vec(y), _vec(zn)


_IDENTITY: Final[tuple[Vec3, Vec3, Vec3]] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


def _capsule(
    a: FloatArray, b: FloatArray, origin: FloatArray, mass: float, *, collide: bool
) -> ModelGeom:
    """A bracket: a capsule from a to b (base-frame points at q = 0) in the link at ``origin``."""
    d = b - a
    length = float(np.linalg.norm(d))
    return ModelGeom(
        shape="capsule",
        size=(SEGMENT_RADIUS, length / 2),
        pos=_vec((a + b) / 2 - origin),
        rot=_frame(d),
        mass=mass,
        collide=collide,
        rgba=_BRACKET_RGBA,
    )


def _servo(
    model: str,
    mass: float,
    at: FloatArray,
    axis: FloatArray,
    origin: FloatArray,
    hint: FloatArray | None = None,
) -> ModelGeom:
    """A servo's housing: a box of Table 5.1's size, its depth along the joint axis."""
    w, h, d = SERVO_SIZE_MM[model]
    return ModelGeom(
        shape="box",
        size=(w / 2000, h / 2000, d / 2000),
        pos=_vec(at - origin),
        rot=_frame(axis, hint),
        mass=mass,
        collide=False,
        rgba=_SERVO_RGBA,
    )


def _check_models(cfg: RobotConfig) -> None:
    problems = [
        Problem(f"joints.{name}.model", model, f"one of {', '.join(sorted(MOTORS))} (sim.motors)")
        for name in JOINT_NAMES
        if (model := cfg.joints.by_name(name).model) not in MOTORS or model not in SERVO_SIZE_MM
    ]
    if problems:
        raise ConfigError("simulation model", problems)


def body_mass(cfg: RobotConfig) -> float:
    """What the body tube gets: the robot's mass less servos, brackets and wheels (kg)."""
    per_leg = sum(cfg.servo_models[cfg.joints.by_name(j).model].mass_g / 1000 for j in JOINT_NAMES)
    per_leg += sum(BRACKET_MASS_KG.values()) + WHEEL_MASS_KG
    rest = cfg.robot.mass_kg - len(cfg.legs) * per_leg
    if rest < MIN_BODY_MASS_KG:
        raise ConfigError(
            "simulation model",
            [
                Problem(
                    "robot.mass_kg",
                    cfg.robot.mass_kg,
                    f"at least {len(cfg.legs) * per_leg + MIN_BODY_MASS_KG:.3f} kg: the servos, "
                    "brackets and wheels alone weigh "
                    f"{len(cfg.legs) * per_leg:.3f} kg",
                )
            ],
        )
    return rest


def robot_links(
    cfg: RobotConfig | None = None, *, wheel_shape: WheelShape = "sphere"
) -> tuple[ModelLink, ...]:
    """The robot as links, base first, then each leg from coxa to wheel (legs in
    :data:`~whexar.robot.LEG_NAMES` order): what :func:`build_mjcf` and
    :func:`whexar.sim.urdf.build_urdf` write."""
    cfg = RobotConfig() if cfg is None else cfg
    if wheel_shape not in WHEEL_SHAPES:
        raise UsageError(f"wheel_shape {wheel_shape!r}; allowed: {', '.join(WHEEL_SHAPES)}")
    _check_models(cfg)
    g = cfg.leg_geometry()
    volts = cfg.robot.supply_voltage_v

    def joint(
        leg: str, name: str, axis: FloatArray, limits: tuple[float, float] | None
    ) -> ModelJoint:
        model = cfg.joints.by_name(name).model
        motor = MOTORS[model]
        return ModelJoint(
            name=f"{leg}_{name}",
            axis=_vec(axis / np.linalg.norm(axis)),
            limits=limits,
            servo=model,
            armature=motor.armature,
            damping=motor.viscous,
            frictionloss=motor.coulomb,
            effort=cfg.servo_models[model].stall_torque_nm,
            velocity=motor.no_load_speed(volts),
        )

    def servo_mass(name: str) -> float:
        return cfg.servo_models[cfg.joints.by_name(name).model].mass_g / 1000

    body = cfg.body
    base_geoms: list[ModelGeom] = [
        ModelGeom(
            shape="box",
            size=(body.length_mm / 2000, body.width_mm / 2000, body.height_mm / 2000),
            pos=(0.0, 0.0, 0.0),
            rot=_IDENTITY,
            mass=body_mass(cfg),
            collide=True,
            rgba=_BODY_RGBA,
            name="body",
        )
    ]
    legs: list[ModelLink] = []

    # DH frames at q = 0 (Table 5.3): F_k = A_0 ⋯ A_k, in DH base coordinates.
    links_dh = dh_transforms(np.zeros(5), g)
    frames = [links_dh[0]]
    for k in range(1, 5):
        frames.append(frames[-1] @ links_dh[k])
    # The tarsus frame with the last segment vertical (tarsus = −90°, eq. 4.19): fixes the
    # wheel axle's sense, which the DH table does not.
    vertical = dh_transforms(np.array([0.0, 0.0, 0.0, 0.0, -math.pi / 2]), g)
    tarsus_vertical = vertical[0] @ vertical[1] @ vertical[2] @ vertical[3] @ vertical[4]

    for index, leg in enumerate(LEG_NAMES):
        side = float(SIDE_SIGN[index])
        # DH base → body: leg frame (DH_TO_LEG), then leg → body (kinematics.body.leg_to_body).
        leg_to_body = np.array([[0.0, 0.0, 1.0], [-side, 0.0, 0.0], [0.0, -1.0, 0.0]])
        to_body = leg_to_body @ DH_TO_LEG
        det = float(np.linalg.det(to_body))  # +1 right legs, −1 left legs (a mirror)
        mount = g.mounts[index]

        def point(
            p: FloatArray, to_body: FloatArray = to_body, mount: FloatArray = mount
        ) -> FloatArray:
            result: FloatArray = to_body @ p + mount
            return result

        def axis(a: FloatArray, to_body: FloatArray = to_body, det: float = det) -> FloatArray:
            result: FloatArray = det * (to_body @ a)
            return result

        z_dh = [np.array([0.0, 0.0, 1.0])] + [f[:3, 2] for f in frames[:4]]
        origins_dh = [np.zeros(3)] + [f[:3, 3] for f in frames[:4]]
        anchors = [point(o) for o in origins_dh]  # coxa … tarsus joints
        axes = [axis(g.theta_sign[k] * z_dh[k]) for k in range(5)]
        seg_dh = frames[4][:3, 0]  # the last segment, tarsus joint → wheel (DH x₄)
        end = point(frames[4][:3, 3])  # the direction joint, end of the tarsus segment
        seg = to_body @ seg_dh  # a direction, not an axis: no mirror sign
        axle = end + seg * g.direction_length
        contact = end + seg * (g.direction_length + g.wheel_radius)
        direction_axis = axis(-seg_dh)  # up the segment on a right leg: CCW from above
        sense = 1.0 if axis(tarsus_vertical[:3, 1])[1] > 0 else -1.0
        wheel_axis = axis(sense * frames[4][:3, 1])  # +y (body) with the tarsus vertical
        limits = [
            None if (r := cfg.joints.by_name(name).limits_rad) is None else r
            for name in JOINT_NAMES
        ]

        # The coxa servo sits on the body (its horn turns the coxa bracket).
        base_geoms.append(
            _servo(cfg.joints.coxa.model, servo_mass("coxa"), anchors[0], axes[0], np.zeros(3))
        )
        prev = np.zeros(3)
        chain: list[tuple[str, FloatArray, FloatArray, list[ModelGeom], list[ModelSite]]] = []
        # coxa: the bracket linking coxa and trochanter, the trochanter's servo.
        o = anchors[0]
        chain.append(
            (
                "coxa",
                o,
                axes[0],
                [
                    ModelGeom(
                        shape="box",
                        size=(0.025, 0.02, 0.03),
                        pos=(0.0, 0.0, 0.0),
                        rot=_IDENTITY,
                        mass=BRACKET_MASS_KG["coxa"],
                        collide=False,
                        rgba=_BRACKET_RGBA,
                    ),
                    _servo(
                        cfg.joints.trochanter.model,
                        servo_mass("trochanter"),
                        anchors[1],
                        axes[1],
                        o,
                    ),
                ],
                [],
            )
        )
        # trochanter … tarsus: the segment to the next joint and the next joint's servo.
        nxt = [*anchors[2:], end]
        servo_axes = [axes[2], axes[3], axes[4], direction_axis]
        servo_names = ["femur", "tibia", "tarsus", "direction"]
        for k, name in enumerate(("trochanter", "femur", "tibia", "tarsus")):
            o = anchors[k + 1]
            geoms = [
                _capsule(o, nxt[k], o, BRACKET_MASS_KG[name], collide=True),
                _servo(
                    cfg.joints.by_name(servo_names[k]).model,
                    servo_mass(servo_names[k]),
                    nxt[k],
                    servo_axes[k],
                    o,
                    hint=nxt[k] - o,
                ),
            ]
            sites: list[ModelSite] = []
            if name == "trochanter" and leg[1] == "F":
                # The IR rangefinders ride on the front legs (5.3.5): on the femur servo's
                # front face, looking forward along the femur axis — body +x with coxa and
                # trochanter at 0. Sitting on that axis, they do not move with the femur;
                # the coxa yaws them (25° inward in the default stance) and the trochanter
                # tilts them, which keeps the ray level when the trochanter follows the
                # body's pitch (eq. 4.18). ``ir.pitch_deg`` tilts the mount down.
                down = math.radians(cfg.ir.pitch_deg)
                sites.append(
                    ModelSite(
                        f"ir_{'right' if side > 0 else 'left'}",
                        _vec(nxt[k] + np.array([IR_FORWARD, 0.0, 0.0]) - o),
                        (math.cos(down), 0.0, 0.0 - math.sin(down)),
                    )
                )
            chain.append((name, o, axes[k + 1], geoms, sites))
        # direction: the fork holding the wheel servo, and the contact site.
        fork = [
            _capsule(end, axle, end, BRACKET_MASS_KG["direction"], collide=False),
            _servo(
                cfg.joints.wheel.model,
                servo_mass("wheel"),
                (end + axle) / 2,
                wheel_axis,
                end,
                hint=seg,
            ),
        ]
        chain.append(
            (
                "direction",
                end,
                direction_axis,
                fork,
                [ModelSite(f"{leg}_contact", _vec(contact - end))],
            )
        )
        # wheel: the tyre.
        if wheel_shape == "sphere":
            tyre = ModelGeom(
                shape="sphere",
                size=(g.wheel_radius,),
                pos=(0.0, 0.0, 0.0),
                rot=_IDENTITY,
                mass=WHEEL_MASS_KG,
                collide=True,
                rgba=_WHEEL_RGBA,
                name=f"{leg}_wheel",
            )
        else:
            tyre = ModelGeom(
                shape="cylinder",
                size=(g.wheel_radius, WHEEL_WIDTH / 2),
                pos=(0.0, 0.0, 0.0),
                rot=_frame(wheel_axis),
                mass=WHEEL_MASS_KG,
                collide=True,
                rgba=_WHEEL_RGBA,
                name=f"{leg}_wheel",
            )
        chain.append(("wheel", axle, wheel_axis, [tyre], []))

        parent = "base"
        for name, origin, ax, geoms, sites in chain:
            link = f"{leg}_{name}_link"
            legs.append(
                ModelLink(
                    name=link,
                    parent=parent,
                    pos=_vec(origin - prev),
                    joint=joint(leg, name, ax, limits[JOINT_NAMES.index(name)]),
                    geoms=tuple(geoms),
                    sites=tuple(sites),
                )
            )
            parent, prev = link, origin

    base = ModelLink(
        name="base",
        parent=None,
        pos=(0.0, 0.0, 0.0),
        joint=None,
        geoms=tuple(base_geoms),
        sites=(ModelSite("imu", (0.0, 0.0, 0.0)),),
    )
    return (base, *legs)


# --------------------------------------------------------------------------- start pose


def stance_angles(cfg: RobotConfig | None = None, stance: str | None = None) -> FloatArray:
    """Joint angles (6, 7) of a stance preset (default: ``locomotion.stance``): IK to the
    wheel contacts, trochanters level, wheels heading straight ahead (direction = −coxa,
    :func:`~whexar.kinematics.wheels.direction_for_heading`), wheel angles 0."""
    cfg = RobotConfig() if cfg is None else cfg
    preset = cfg.stance(cfg.locomotion.stance if stance is None else stance)
    solution = ik(stance_feet(preset), cfg.leg_geometry(), target="contact")
    angles = np.zeros((len(LEG_NAMES), len(JOINT_NAMES)))
    angles[:, :5] = solution.angles
    angles[:, 5] = -solution.angles[:, 0]
    return angles


def default_base_height(cfg: RobotConfig | None = None, stance: str | None = None) -> float:
    """Height of the body centre above the floor in a stance preset, plus a drop clearance
    of :data:`DROP_CLEARANCE` (m)."""
    cfg = RobotConfig() if cfg is None else cfg
    preset = cfg.stance(cfg.locomotion.stance if stance is None else stance)
    mount_z = float(np.mean([leg.mount_mm[2] for leg in cfg.legs])) / 1000
    return preset.height - mount_z + DROP_CLEARANCE


# --------------------------------------------------------------------------- MJCF


def _f(value: float) -> str:
    # Rounding noise of the DH products (1e-18 m) reads as 0.
    return f"{(value if abs(value) > 1e-12 else 0.0):.12g}"


def _v(values: tuple[float, ...] | list[float] | FloatArray) -> str:
    return " ".join(_f(float(v)) for v in values)


def _quat(rot: tuple[Vec3, Vec3, Vec3]) -> tuple[float, float, float, float]:
    """Quaternion (w, x, y, z) of the rotation whose columns are ``rot``."""
    m = np.array(rot, dtype=np.float64).T  # rows of rot are the columns of the matrix
    t = float(np.trace(m))
    if t > 0:
        s = math.sqrt(t + 1.0) * 2
        q = (0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s)
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2]) * 2
        q = ((m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s)
    elif m[1, 1] > m[2, 2]:
        s = math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2]) * 2
        q = ((m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s)
    else:
        s = math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1]) * 2
        q = ((m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s)
    return q


def _geom_xml(geom: ModelGeom, wheel_condim: int) -> str:
    attrs = [f'type="{geom.shape}"', f'size="{_v(geom.size)}"', f'pos="{_v(geom.pos)}"']
    if geom.rot != _IDENTITY:
        attrs.append(f'quat="{_v(_quat(geom.rot))}"')
    attrs.append(f'mass="{_f(geom.mass)}"')
    attrs.append(f'rgba="{geom.rgba}"')
    if geom.name is not None:
        attrs.insert(0, f'name="{geom.name}"')
    if not geom.collide:
        attrs.append(f'contype="0" conaffinity="0" group="{ROBOT_VISUAL_GROUP}"')
    if geom.name is not None and geom.name.endswith("_wheel"):
        # The tyre's rubber decides its contacts (priority), whatever it touches.
        attrs.append(
            f'priority="1" condim="{wheel_condim}" friction="{_v(GROUND_FRICTION)}" '
            f'solref="{_v(WHEEL_SOLREF)}"'
        )
    return f"<geom {' '.join(attrs)}/>"


def _joint_xml(j: ModelJoint) -> str:
    limit = 'limited="false"' if j.limits is None else f'range="{_v(j.limits)}"'
    return (
        f'<joint name="{j.name}" type="hinge" axis="{_v(j.axis)}" {limit} '
        f'armature="{_f(j.armature)}" damping="{_f(j.damping)}" '
        f'frictionloss="{_f(j.frictionloss)}"/>'
    )


def _body_xml(
    link: ModelLink,
    children: dict[str, list[ModelLink]],
    wheel_condim: int,
    indent: int,
    out: list[str],
) -> None:
    pad = "  " * indent
    out.append(f'{pad}<body name="{link.name}" pos="{_v(link.pos)}">')
    if link.joint is not None:
        out.append(f"{pad}  {_joint_xml(link.joint)}")
    out.extend(f"{pad}  {_geom_xml(geom, wheel_condim)}" for geom in link.geoms)
    out.extend(
        f'{pad}  <site name="{s.name}" pos="{_v(s.pos)}" zaxis="{_v(s.zaxis)}" size="0.005"/>'
        for s in link.sites
    )
    for child in children.get(link.name, []):
        _body_xml(child, children, wheel_condim, indent + 1, out)
    out.append(f"{pad}</body>")


def build_mjcf(
    cfg: RobotConfig | None = None,
    *,
    terrain: Terrain | None = None,
    timestep: float = TIMESTEP_S,
    base_height: float | None = None,
    stance: str | None = None,
    wheel_shape: WheelShape = "sphere",
) -> str:
    """The MJCF document of WHexaR (``cfg``, default the thesis robot) on ``terrain``
    (default :func:`~whexar.sim.terrain.flat`).

    Names: the free joint and root body ``base`` (body frame: origin at the body centre,
    x forward, y left, z up); a hinge and a ``motor`` actuator (gear 1, torque in N·m,
    unlimited) ``{leg}_{joint}`` for every leg and joint; sites ``imu``,
    ``{leg}_contact``, ``ir_right``, ``ir_left`` (+z along the ray); wheel geoms
    ``{leg}_wheel``; links ``{leg}_{joint}_link``.

    Start: ``qpos0`` has the base ``base_height`` (default: the stance's height plus
    5 mm, :func:`default_base_height`) above the floor at the origin, parallel to it,
    and every joint at 0 (legs stretched out sideways). The keyframe ``stance``
    (:data:`STANCE_KEY`; ``mujoco.mj_resetDataKeyframe``) has the same base pose with
    the joints in the ``stance`` preset (default ``locomotion.stance``, see
    :func:`stance_angles`): the robot drops a few millimetres onto its wheels.
    """
    cfg = RobotConfig() if cfg is None else cfg
    terrain = flat() if terrain is None else terrain
    h = positive("timestep", timestep, "s")
    height = (
        default_base_height(cfg, stance)
        if base_height is None
        else positive("base_height", base_height, "m")
    )
    links = robot_links(cfg, wheel_shape=wheel_shape)
    pos, quat = terrain.start_pose(height)
    angles = stance_angles(cfg, stance)
    wheel_condim = 3 if wheel_shape == "sphere" else 6

    children: dict[str, list[ModelLink]] = {}
    for link in links[1:]:
        assert link.parent is not None
        children.setdefault(link.parent, []).append(link)
    base = links[0]
    robot: list[str] = [
        f'    <body name="base" childclass="robot" pos="{_v(pos)}" quat="{_v(quat)}">',
        '      <freejoint name="base"/>',
    ]
    robot.extend(f"      {_geom_xml(geom, wheel_condim)}" for geom in base.geoms)
    robot.extend(f'      <site name="{s.name}" pos="{_v(s.pos)}" size="0.01"/>' for s in base.sites)
    for child in children.get("base", []):
        _body_xml(child, children, wheel_condim, 3, robot)
    robot.append("    </body>")

    # qpos of the keyframe: the base, the joints in body order (legs in LEG_NAMES order,
    # coxa to wheel), then every free block of the terrain at its start.
    key = [*pos, *quat, *angles.ravel()]
    for part in terrain.parts:
        if isinstance(part, Box) and part.mass is not None:
            half_yaw, half_pitch = part.yaw / 2, part.pitch / 2
            cy, sy, cp, sp = (
                math.cos(half_yaw),
                math.sin(half_yaw),
                math.cos(half_pitch),
                math.sin(half_pitch),
            )
            key.extend([*part.pos, cy * cp, -sy * sp, cy * sp, sy * cp])

    actuators = [
        f'    <motor name="{leg}_{j}" joint="{leg}_{j}" gear="1" ctrllimited="false"/>'
        for leg in LEG_NAMES
        for j in JOINT_NAMES
    ]
    return "\n".join(
        [
            f'<mujoco model="{cfg.robot.name}">',
            '  <compiler angle="radian" autolimits="true"/>',
            # Contacts: see the module docstring (elliptic cone, impratio 10, notes).
            f'  <option timestep="{_f(h)}" integrator="implicitfast" cone="elliptic" '
            'impratio="10"/>',
            # Rendering: the notes' fast settings (1024 shadow map) and room for 1080p frames.
            '  <visual><global offwidth="1920" offheight="1080"/>'
            '<quality shadowsize="1024"/></visual>',
            # The robot's defaults, for its bodies only (childclass): the terrain keeps its own.
            '  <default><default class="robot">',
            f'    <geom contype="{ROBOT_CONTYPE}" conaffinity="{ROBOT_CONAFFINITY}" '
            f'group="{ROBOT_COLLISION_GROUP}" condim="3"/>',
            "  </default></default>",
            "  <asset>",
            '    <texture name="sky" type="skybox" builtin="gradient" rgb1="0.6 0.7 0.8" '
            'rgb2="0.2 0.25 0.3" width="256" height="256"/>',
            f"    {terrain.asset_xml()}",
            "  </asset>",
            "  <worldbody>",
            '    <light name="sun" directional="true" pos="0 0 5" dir="-0.3 0.2 -1" '
            'castshadow="true"/>',
            *robot,
            # The tracking camera follows the body centre from behind and to the left.
            '    <camera name="track" mode="trackcom" pos="-1.6 1.2 1.0" '
            'xyaxes="-0.6 -0.8 0 0.358 -0.268 0.894"/>',
            *("    " + line for line in terrain.worldbody_xml().splitlines()),
            "  </worldbody>",
            "  <actuator>",
            *actuators,
            "  </actuator>",
            "  <keyframe>",
            f'    <key name="{STANCE_KEY}" qpos="{_v(key)}"/>',
            "  </keyframe>",
            "</mujoco>",
            "",
        ]
    )


def load_model(
    cfg: RobotConfig | None = None,
    *,
    terrain: Terrain | None = None,
    timestep: float = TIMESTEP_S,
    base_height: float | None = None,
    stance: str | None = None,
    wheel_shape: WheelShape = "sphere",
) -> mujoco.MjModel:
    """The compiled model of :func:`build_mjcf` (same arguments)."""
    import mujoco

    xml = build_mjcf(
        cfg,
        terrain=terrain,
        timestep=timestep,
        base_height=base_height,
        stance=stance,
        wheel_shape=wheel_shape,
    )
    return mujoco.MjModel.from_xml_string(xml)


__all__ = [
    "STANCE_KEY",
    "WHEEL_SHAPES",
    "ModelGeom",
    "ModelJoint",
    "ModelLink",
    "ModelSite",
    "body_mass",
    "build_mjcf",
    "default_base_height",
    "load_model",
    "robot_links",
    "stance_angles",
]
