"""The tilting board of the thesis's slope experiments (6.7.6, 6.8.1).

The thesis put the robot on a board and raised one end gradually, the robot on it
walking, riding or standing, until it could no longer. Here the board is the floor and
its tilt is gravity's: :class:`BoardTilt` rotates the world's gravity about y, so that
the floor rises along +x by the board's angle, from ``start_s`` at ``rate_deg_s`` up to
``max_deg``. The IMU and the sensor board's accelerometer read the specific force
against that gravity, so they see the board tilt as the robot's did; the floor itself,
the start pose and the obstacles do not move.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["BoardTilt"]


@dataclass(frozen=True)
class BoardTilt:
    """The board's angle over time: level until ``start_s``, then rising at ``rate_deg_s``
    to ``max_deg`` and held there."""

    start_s: float
    rate_deg_s: float
    max_deg: float

    def angle_deg(self, t: float) -> float:
        """The board's angle (°) at simulated time ``t``."""
        return min(max(t - self.start_s, 0.0) * self.rate_deg_s, self.max_deg)

    def time_at(self, angle_deg: float) -> float:
        """When the board reaches ``angle_deg`` (at most ``max_deg``)."""
        return self.start_s + min(angle_deg, self.max_deg) / self.rate_deg_s

    def gravity(self, t: float, g: float) -> tuple[float, float, float]:
        """The world's gravity (m/s²) at ``t`` for magnitude ``g``: the floor rising along
        +x by the angle is gravity pulling along −x by it."""
        a = math.radians(self.angle_deg(t))
        return -g * math.sin(a), 0.0, -g * math.cos(a)
