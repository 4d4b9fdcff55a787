"""A URDF of WHexaR for Foxglove and RViz: the links and joints of the MuJoCo model.

Theory of operation
-------------------
The URDF is written from the same links as the MJCF (:func:`whexar.sim.model.robot_links`),
so frames, axes, limits and joint angles are the same numbers: a joint state of
``{leg}_{joint}`` = q rad shows the pose the kinematics and the simulation compute for
q. Every link frame is parallel to ``base`` at q = 0 and sits at its joint, so each
joint's origin is a plain offset (rpy 0) and its axis a body-frame vector; left legs
are built as mirror images with flipped axes, as in the MJCF (see there).

Masses and inertias are MuJoCo's: the MJCF is compiled once and each body's mass,
centre of mass and principal inertia (with its frame) go into ``<inertial>``. URDF has
no capsule, so segments are cylinders of the capsule's length. The MuJoCo sites
(``imu``, ``{leg}_contact``, ``ir_right``, ``ir_left``) become massless links on
fixed joints, so a viewer shows their frames (an IR link's +z is its ray).

Joint types: ``continuous`` for the wheel (endless, Table 5.2), ``revolute`` with the
configuration's limits for the rest; ``effort`` is the servo's stall torque (Table 5.1)
and ``velocity`` its no-load speed at the supply voltage (:mod:`whexar.sim.motors`).
"""

from __future__ import annotations

import functools
import math
from typing import Final
from xml.sax.saxutils import quoteattr

import numpy as np

from whexar.config import RobotConfig
from whexar.sim.model import ModelGeom, ModelLink, WheelShape, _frame, load_model, robot_links

ROOT_LINK: Final = "base"
"""The URDF's root link: whexar's body frame (origin at the body centre, x forward, y left,
z up), the MJCF's ``base``."""

Vec3 = tuple[float, float, float]


def _f(value: float) -> str:
    # Rounding noise of the DH products (1e-18 m) reads as 0.
    return f"{(value if abs(value) > 1e-12 else 0.0):.10g}"


def _v(values: tuple[float, ...] | list[float] | np.ndarray) -> str:
    return " ".join(_f(float(v)) for v in values)


def _rpy(rot: np.ndarray) -> Vec3:
    """URDF's fixed-axis roll, pitch, yaw of a rotation matrix: R = Rz(yaw)·Ry(pitch)·Rx(roll)."""
    roll = math.atan2(rot[2, 1], rot[2, 2])
    pitch = math.atan2(-rot[2, 0], math.hypot(rot[2, 1], rot[2, 2]))
    yaw = math.atan2(rot[1, 0], rot[0, 0])
    return roll, pitch, yaw


def _geometry(geom: ModelGeom) -> str:
    if geom.shape == "box":
        return f'<box size="{_v([2 * s for s in geom.size])}"/>'
    if geom.shape == "sphere":
        return f'<sphere radius="{_f(geom.size[0])}"/>'
    # Capsules and cylinders lie along the geom's z, as a URDF cylinder does.
    radius, half = geom.size[0], geom.size[1]
    return f'<cylinder radius="{_f(radius)}" length="{_f(2 * half)}"/>'


def _origin(pos: Vec3 | np.ndarray, rot: np.ndarray | None = None) -> str:
    rpy = (0.0, 0.0, 0.0) if rot is None else _rpy(rot)
    return f'<origin xyz="{_v(tuple(pos))}" rpy="{_v(rpy)}"/>'


def _material(rgba: str, names: dict[str, str]) -> str:
    if rgba not in names:
        names[rgba] = f"m{len(names)}"
    return names[rgba]


def _link_xml(
    link: ModelLink,
    inertial: tuple[float, np.ndarray, np.ndarray, np.ndarray],
    materials: dict[str, str],
) -> list[str]:
    mass, com, axes, principal = inertial
    out = [f"  <link name={quoteattr(link.name)}>"]
    out.append(
        f"    <inertial>{_origin(com, axes)}<mass value={quoteattr(_f(mass))}/>"
        f'<inertia ixx="{_f(principal[0])}" ixy="0" ixz="0" iyy="{_f(principal[1])}" '
        f'iyz="0" izz="{_f(principal[2])}"/></inertial>'
    )
    for geom in link.geoms:
        rot = np.array(geom.rot, dtype=np.float64).T  # columns are the geom's axes
        shape = f"{_origin(geom.pos, rot)}<geometry>{_geometry(geom)}</geometry>"
        material = _material(geom.rgba, materials)
        out.append(f'    <visual>{shape}<material name="{material}"/></visual>')
        if geom.collide:
            out.append(f"    <collision>{shape}</collision>")
    out.append("  </link>")
    return out


def _site_frame(zaxis: Vec3) -> np.ndarray:
    """A site's frame: +z along ``zaxis`` (the MJCF's ``zaxis`` attribute)."""
    return np.array(_frame(np.array(zaxis, dtype=np.float64)), dtype=np.float64).T


def build_urdf(cfg: RobotConfig | None = None, *, wheel_shape: WheelShape = "sphere") -> str:
    """The URDF document of WHexaR (``cfg``, default the thesis robot); root link ``base``.

    Built once per configuration and process (it compiles a MuJoCo model: 0.09 s),
    so that every recorded run of a campaign or a benchmark does not pay it again."""
    cfg = RobotConfig() if cfg is None else cfg
    return _build_urdf(cfg.model_dump_json(), wheel_shape)


@functools.lru_cache(maxsize=8)
def _build_urdf(config_json: str, wheel_shape: WheelShape) -> str:
    import mujoco

    cfg = RobotConfig.model_validate_json(config_json)
    links = robot_links(cfg, wheel_shape=wheel_shape)
    model = load_model(cfg, wheel_shape=wheel_shape)
    inertials: dict[str, tuple[float, np.ndarray, np.ndarray, np.ndarray]] = {}
    for link in links:
        body = model.body(link.name)
        frame = np.zeros(9)
        mujoco.mju_quat2Mat(frame, body.iquat)
        inertials[link.name] = (
            float(body.mass[0]),
            np.array(body.ipos, dtype=np.float64),
            frame.reshape(3, 3),
            np.array(body.inertia, dtype=np.float64),
        )

    materials: dict[str, str] = {}
    body_lines: list[str] = []
    joint_lines: list[str] = []
    for link in links:
        body_lines.extend(_link_xml(link, inertials[link.name], materials))
        joint = link.joint
        if link.parent is not None and joint is not None:
            if joint.limits is None:
                kind, limit = "continuous", ""
            else:
                kind = "revolute"
                limit = f'lower="{_f(joint.limits[0])}" upper="{_f(joint.limits[1])}" '
            joint_lines.append(
                f'  <joint name="{joint.name}" type="{kind}">'
                f'<parent link="{link.parent}"/><child link="{link.name}"/>'
                f"{_origin(link.pos)}"
                f'<axis xyz="{_v(joint.axis)}"/>'
                f'<limit {limit}effort="{_f(joint.effort)}" velocity="{_f(joint.velocity)}"/>'
                f'<dynamics damping="{_f(joint.damping)}" friction="{_f(joint.frictionloss)}"/>'
                "</joint>"
            )
        for site in link.sites:
            body_lines.append(f'  <link name="{site.name}"/>')
            joint_lines.append(
                f'  <joint name="{site.name}_mount" type="fixed">'
                f'<parent link="{link.name}"/><child link="{site.name}"/>'
                f"{_origin(site.pos, _site_frame(site.zaxis))}</joint>"
            )
    header = [
        '<?xml version="1.0"?>',
        f"<robot name={quoteattr(cfg.robot.name)}>",
        *(
            f'  <material name="{name}"><color rgba="{rgba}"/></material>'
            for rgba, name in materials.items()
        ),
    ]
    return "\n".join([*header, *body_lines, *joint_lines, "</robot>", ""])


__all__ = ["ROOT_LINK", "build_urdf"]
