"""Leg and body geometry in SI units; the robot configuration builds it.

The leg frame is the one of the thesis's inverse kinematics (Žák 2023,
Fig. 4.3, Table 6.5): origin at the coxa joint, **x** outward along the leg,
**y** down, **z** forward. It is right-handed for right legs; left legs are
its mirror image, so the same joint angles give mirrored poses — as on the
robot, whose left servos turn the other way (5.1).

The DH base frame of Table 5.3 relates to the leg frame by a fixed rotation:
leg = (−y₀, −z₀, x₀); for a right leg the DH base axes coincide with the body
axes (x forward, y left, z up).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from whexar._typing import FloatArray
from whexar.robot import LEG_NAMES, N_LEGS, leg_side

DH_TO_LEG: FloatArray = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
"""Rotation taking DH base coordinates (Table 5.3) to the thesis leg frame (Fig. 4.3)."""
DH_TO_LEG.setflags(write=False)

SIDE_SIGN: FloatArray = np.array(
    [1.0 if leg_side(leg) == "right" else -1.0 for leg in range(N_LEGS)]
)
"""+1 for right legs, −1 for left legs: the mirror between leg frames and the body (5.1)."""
SIDE_SIGN.setflags(write=False)


def _frozen(values: object) -> FloatArray:
    array = np.array(values, dtype=np.float64)
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class LegGeometry:
    """Everything the kinematics needs, in metres and radians.

    The configuration builds it (:meth:`whexar.config.RobotConfig.leg_geometry`;
    :func:`whexar.config.default_geometry` is the thesis robot). Arrays are
    stored as read-only float64 copies: one geometry is shared by every caller.
    """

    dh_d: FloatArray
    """DH offsets d of coxa…tarsus (Table 5.3), m."""
    dh_a: FloatArray
    """DH lengths a of coxa…tarsus (Table 5.3), m."""
    dh_alpha: FloatArray
    """DH twists α, rad."""
    theta_offset: FloatArray
    """DH angle offsets: θ_DH = sign·q + offset, rad."""
    theta_sign: FloatArray
    """DH angle signs (±1)."""
    limits: FloatArray
    """(5, 2) joint limits of coxa…tarsus in the joint convention, rad (Table 5.2)."""
    direction_length: float
    """Direction joint to wheel axle, m (Table 5.2: 42 mm)."""
    wheel_radius: float
    """Wheel axle to ground, m (Table 5.2: 33 mm)."""
    mounts: FloatArray
    """(6, 3) coxa joints in the body frame, m (legs in :data:`LEG_NAMES` order)."""

    def __post_init__(self) -> None:
        for name in ("dh_d", "dh_a", "dh_alpha", "theta_offset", "theta_sign", "limits", "mounts"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))
        object.__setattr__(self, "direction_length", float(self.direction_length))
        object.__setattr__(self, "wheel_radius", float(self.wheel_radius))

    @cached_property
    def trochanter_offset(self) -> float:
        """d₁: coxa axis to femur joint along the leg (Table 5.3: 65 mm)."""
        return float(self.dh_d[1])

    @cached_property
    def femur(self) -> float:
        """a₂: femur length (127 mm)."""
        return float(self.dh_a[2])

    @cached_property
    def tibia(self) -> float:
        """a₃: tibia length (124 mm)."""
        return float(self.dh_a[3])

    @cached_property
    def tarsus(self) -> float:
        """a₄: tarsus length (95 mm)."""
        return float(self.dh_a[4])

    @cached_property
    def contact_offset(self) -> float:
        """Tarsus joint to wheel contact along the last segment (95 + 42 + 33 mm)."""
        return self.tarsus + self.direction_length + self.wheel_radius

    @cached_property
    def max_reach(self) -> float:
        """Longest femur-joint-to-tarsus-joint distance (femur + tibia)."""
        return self.femur + self.tibia

    @cached_property
    def min_reach(self) -> float:
        """Shortest femur-joint-to-tarsus-joint distance |femur − tibia|."""
        return abs(self.femur - self.tibia)

    @cached_property
    def lower_limits(self) -> FloatArray:
        """Lower joint limits of coxa…tarsus, rad."""
        return _frozen(self.limits[:, 0])

    @cached_property
    def upper_limits(self) -> FloatArray:
        """Upper joint limits of coxa…tarsus, rad."""
        return _frozen(self.limits[:, 1])


def leg_positions() -> tuple[str, ...]:
    """Position of each leg along the body: ``"front"``, ``"middle"`` or ``"rear"``."""
    return tuple({"F": "front", "M": "middle", "R": "rear"}[name[1]] for name in LEG_NAMES)
