"""One leg's frame seen from the upright frame, through the body pose.

The *upright frame* is the body frame of a robot standing on its feet (x
forward, y left, z up, the ground below): the coordinator plans in it. The
body pose (x, y, z, roll, pitch, yaw; :class:`~whexar.kinematics.body.BodyPose`)
moves the body over the feet, and a leg's own frame (x outward, y down, z
forward; :mod:`whexar.kinematics.geometry`) hangs from its mount on the body.
Upside down (6.8.1) the leg works mirrored: its mount and side flip.

Plain Python: a leg converts its foot every control cycle.
"""

from __future__ import annotations

import math

from whexar.kinematics.geometry import SIDE_SIGN, LegGeometry


class LegFrame:
    """Leg ``leg``'s frame and the body pose it hangs from (module docstring)."""

    def __init__(self, geometry: LegGeometry, leg: int) -> None:
        mount = geometry.mounts[leg]
        self.mount = (float(mount[0]), float(mount[1]), float(mount[2]))
        self.side = float(SIDE_SIGN[leg])
        self.upside_down = False
        self.pose: tuple[float, ...] = (0.0,) * 6
        self.rotation: tuple[float, ...] | None = None
        """R of the body pose, row-major; ``None`` for the neutral pose."""

    def set_pose(self, pose: tuple[float, ...]) -> None:
        """The body pose (x, y, z, roll, pitch, yaw) the leg hangs from now."""
        self.pose = pose
        if not any(pose):
            self.rotation = None
            return
        _, _, _, roll, pitch, yaw = pose
        cr, sr = math.cos(roll), math.sin(roll)
        cp, sp = math.cos(pitch), math.sin(pitch)
        cy, sy = math.cos(yaw), math.sin(yaw)
        # R = R_z(yaw) · R_y(pitch) · R_x(roll), row-major (kinematics.body.BodyPose).
        self.rotation = (
            cy * cp,
            cy * sp * sr - sy * cr,
            cy * sp * cr + sy * sr,
            sy * cp,
            sy * sp * sr + cy * cr,
            sy * sp * cr - cy * sr,
            -sp,
            cp * sr,
            cp * cr,
        )

    def _frame(self) -> tuple[float, float, float]:
        """(side sign, mount y, mount z) of this leg in the upright frame (mirrored flipped)."""
        if self.upside_down:
            return -self.side, -self.mount[1], -self.mount[2]
        return self.side, self.mount[1], self.mount[2]

    def to_leg(self, p: list[float] | tuple[float, float, float]) -> tuple[float, float, float]:
        """Upright-frame point → this leg's frame, through the body pose (p' = Rᵀ(p − t))."""
        x, y, z = p
        if self.rotation is not None:
            px, py, pz = x - self.pose[0], y - self.pose[1], z - self.pose[2]
            r = self.rotation
            x = r[0] * px + r[3] * py + r[6] * pz
            y = r[1] * px + r[4] * py + r[7] * pz
            z = r[2] * px + r[5] * py + r[8] * pz
        side, my, mz = self._frame()
        return -side * (y - my), -(z - mz), x - self.mount[0]

    def from_leg(self, q: tuple[float, float, float]) -> tuple[float, float, float]:
        """This leg's frame → upright frame (the pose undone)."""
        side, my, mz = self._frame()
        x = self.mount[0] + q[2]
        y = my - side * q[0]
        z = mz - q[1]
        if self.rotation is not None:
            r = self.rotation
            x, y, z = (
                r[0] * x + r[1] * y + r[2] * z + self.pose[0],
                r[3] * x + r[4] * y + r[5] * z + self.pose[1],
                r[6] * x + r[7] * y + r[8] * z + self.pose[2],
            )
        return x, y, z
