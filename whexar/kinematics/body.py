"""Body frame, leg frames and body poses (Diosdado 2014, 3.2; Žák 2023, 4.1, 5.2).

Body frame: origin at the body centre C, x forward, y left, z up (ROS
REP-103); roll, pitch and yaw are rotations about x, y and z, applied as
R = R_z(yaw) · R_y(pitch) · R_x(roll). Positive pitch lowers the nose.

Each leg frame (see :mod:`whexar.kinematics.geometry`) sits at its coxa
joint with x outward, y down, z forward; a left leg's frame is the mirror of
a right leg's. All functions take the six legs at once: arrays of shape
(..., 6, 3) in leg order RF, LF, RM, LM, RR, LR.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from whexar._typing import ArrayLike, FloatArray
from whexar.errors import KinematicsError, UsageError
from whexar.kinematics.geometry import SIDE_SIGN, LegGeometry, leg_positions
from whexar.kinematics.leg import IKSolution, Target, ik
from whexar.robot import N_LEGS
from whexar.runtime.checks import positive, real


def quat_rpy(w: float, x: float, y: float, z: float) -> tuple[float, float, float]:
    """Roll, pitch and yaw (rad) of unit quaternion (w, x, y, z), in this module's
    convention R = R_z(yaw) · R_y(pitch) · R_x(roll); pitch is clamped at ±90°."""
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return roll, pitch, yaw


def _six(points: ArrayLike, what: str) -> FloatArray:
    array = np.asarray(points, dtype=np.float64)
    if array.ndim < 2 or array.shape[-2:] != (N_LEGS, 3):
        raise UsageError(
            f"{what} have shape {array.shape}; allowed: (..., 6, 3), one (x, y, z) per leg "
            "in metres"
        )
    if not np.isfinite(array).all():
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(array))[0])
        raise UsageError(f"{what} {bad} = {array[bad]}; allowed: finite numbers")
    return array


def leg_to_body(points: ArrayLike, geometry: LegGeometry) -> FloatArray:
    """Leg-frame points (..., 6, 3) → body frame."""
    g = geometry
    p = _six(points, "leg-frame points")
    out = np.empty_like(p)
    out[..., 0] = p[..., 2]
    out[..., 1] = -SIDE_SIGN * p[..., 0]
    out[..., 2] = -p[..., 1]
    return out + g.mounts


def body_to_leg(points: ArrayLike, geometry: LegGeometry) -> FloatArray:
    """Body-frame points (..., 6, 3) → each leg's own frame."""
    g = geometry
    d = _six(points, "body-frame points") - g.mounts
    out = np.empty_like(d)
    out[..., 0] = -SIDE_SIGN * d[..., 1]
    out[..., 1] = -d[..., 2]
    out[..., 2] = d[..., 0]
    return out


@dataclass(frozen=True)
class BodyPose:
    """Pose of the body relative to its neutral frame: metres and radians."""

    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0

    def __post_init__(self) -> None:
        for name in ("x", "y", "z", "roll", "pitch", "yaw"):
            value = getattr(self, name)
            if not math.isfinite(value):
                raise UsageError(f"body pose {name} = {value}; allowed: a finite number")

    @property
    def rotation(self) -> FloatArray:
        """R = R_z(yaw) · R_y(pitch) · R_x(roll)."""
        cr, sr = math.cos(self.roll), math.sin(self.roll)
        cp, sp = math.cos(self.pitch), math.sin(self.pitch)
        cy, sy = math.cos(self.yaw), math.sin(self.yaw)
        return np.array(
            [
                [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                [-sp, cp * sr, cp * cr],
            ]
        )

    @property
    def translation(self) -> FloatArray:
        """(x, y, z) of the body centre."""
        return np.array([self.x, self.y, self.z])


def apply_body_pose(feet: ArrayLike, pose: BodyPose) -> FloatArray:
    """Feet that stay put on the ground, seen from a body moved to ``pose``.

    ``feet`` (..., 6, 3) are in the neutral body frame; the result is in the
    moved body frame: p' = Rᵀ (p − t) (Diosdado 2014, 3.2, eq. 3). Shifting the
    body forward moves every foot backwards in the body frame.
    """
    p = _six(feet, "feet")
    result: FloatArray = (p - pose.translation) @ pose.rotation
    return result


@dataclass(frozen=True)
class Stance:
    """A standing posture, the same for all legs up to the front/rear yaw (Žák 2023, 6.3, 6.4).

    ``reach`` is the horizontal distance from the coxa joint to the wheel's
    contact point and ``height`` the height of the coxa joints above the
    ground (m); ``front_rear_yaw`` turns the front legs forward and the rear
    legs backward (rad; 6.4: 25° stopped the tripod gait from tipping
    backwards). The configuration's stance presets build these
    (:meth:`whexar.config.RobotConfig.stance`).
    """

    reach: float
    height: float
    front_rear_yaw: float = 0.0

    def __post_init__(self) -> None:
        positive("reach", self.reach, "m")
        positive("height", self.height, "m")
        real("front_rear_yaw", self.front_rear_yaw)


def stance_feet(stance: Stance) -> FloatArray:
    """The six wheel-contact points of a stance, each in its leg frame (6, 3).

    Front legs turn forward and rear legs backward by ``front_rear_yaw``
    (6.4); in a leg frame a forward turn is +z on both sides.
    """
    yaw = stance.front_rear_yaw
    sign = {"front": 1.0, "middle": 0.0, "rear": -1.0}
    reach, height = stance.reach, stance.height
    return np.array(
        [
            [reach * math.cos(sign[pos] * yaw), height, reach * math.sin(sign[pos] * yaw)]
            for pos in leg_positions()
        ]
    )


def pose_ik(
    feet: ArrayLike,
    geometry: LegGeometry,
    pose: BodyPose = BodyPose(),
    *,
    target: Target = "contact",
    trochanter_follows_pitch: bool = False,
    clamp: bool = False,
) -> IKSolution:
    """Joint angles of all six legs that keep ``feet`` (neutral body frame) under a body pose.

    With ``trochanter_follows_pitch`` the trochanters turn by the body pitch
    (eq. 4.18), keeping the legs vertical when the body pitches on level ground.
    """
    g = geometry
    in_legs = body_to_leg(apply_body_pose(feet, pose), g)
    pitch = pose.pitch if trochanter_follows_pitch else 0.0
    return ik(in_legs, g, pitch=pitch, target=target, clamp=clamp)


def workspace_step(stance: Stance, geometry: LegGeometry, longest: float, height: float) -> float:
    """The longest step, at most ``longest``, every leg of ``stance`` can take in any
    direction with its foot ``height`` up at mid-swing (IK within the joint limits), in
    5 mm decrements; 0.01 m at the least."""
    feet = stance_feet(stance)  # leg frames: x outward, y down, z forward
    length = longest
    while length > 0.01:
        half = length / 2
        offsets = [(half, 0, 0), (-half, 0, 0), (0, 0, half), (0, 0, -half), (0, -height, 0)]
        points = np.array([f + np.array(o) for f in feet for o in offsets])
        try:
            ik(points, geometry, target="contact")
            return length
        except KinematicsError:
            length -= 0.005
    return 0.01
