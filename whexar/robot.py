"""Names and numbering of WHexaR's legs, joints and servos.

Legs are numbered l = 0…5 in the order right front, left front, right middle,
left middle, right rear, left rear; joints j = 0…6 from coxa to wheel; servo
IDs i = 7l + j + 1 (Žák 2023, Fig. 4.2 and eq. 4.1–4.3).
"""

from __future__ import annotations

from typing import Final, Literal

from whexar.errors import UsageError

LEG_NAMES: Final = ("RF", "LF", "RM", "LM", "RR", "LR")
"""Legs in the thesis order (Fig. 4.2)."""

JOINT_NAMES: Final = ("coxa", "trochanter", "femur", "tibia", "tarsus", "direction", "wheel")
"""The seven joints of a leg, from the body outwards (Fig. 4.1)."""

POSITIONING_JOINTS: Final = JOINT_NAMES[:5]
"""The five joints that place the foot; direction and wheel form the chassis."""

N_LEGS: Final = len(LEG_NAMES)
N_JOINTS: Final = len(JOINT_NAMES)

Side = Literal["right", "left"]


def leg_index(leg: int | str) -> int:
    """Return the index 0…5 of a leg given by index or by name (``"RF"``…)."""
    if isinstance(leg, str):
        name = leg.strip().upper()
        if name in LEG_NAMES:
            return LEG_NAMES.index(name)
        if name.isdigit():
            return leg_index(int(name))
        raise UsageError(f"unknown leg {leg!r}; allowed: 0–5 or {', '.join(LEG_NAMES)}")
    if isinstance(leg, int) and not isinstance(leg, bool) and 0 <= leg < N_LEGS:
        return leg
    raise UsageError(f"unknown leg {leg!r}; allowed: 0–5 or {', '.join(LEG_NAMES)}")


def joint_index(joint: int | str) -> int:
    """Return the index 0…6 of a joint given by index or by name (``"femur"``…)."""
    if isinstance(joint, str):
        name = joint.strip().lower()
        if name in JOINT_NAMES:
            return JOINT_NAMES.index(name)
        raise UsageError(f"unknown joint {joint!r}; allowed: 0–6 or {', '.join(JOINT_NAMES)}")
    if isinstance(joint, int) and not isinstance(joint, bool) and 0 <= joint < N_JOINTS:
        return joint
    raise UsageError(f"unknown joint {joint!r}; allowed: 0–6 or {', '.join(JOINT_NAMES)}")


def leg_side(leg: int | str) -> Side:
    """Right legs have even indices, left legs odd ones (Fig. 4.2)."""
    return "right" if leg_index(leg) % 2 == 0 else "left"


def servo_id(leg: int | str, joint: int | str) -> int:
    """Default servo ID of a joint: i = 7l + j + 1 (eq. 4.1)."""
    return N_JOINTS * leg_index(leg) + joint_index(joint) + 1


def joint_of_servo(servo: int) -> tuple[int, int]:
    """(leg, joint) of a default servo ID: j = (i − 1) mod 7, l = (i − j − 1)/7 (eq. 4.2–4.3)."""
    if not 1 <= servo <= N_LEGS * N_JOINTS:
        raise UsageError(f"servo ID {servo!r} is not one of WHexaR's; allowed: 1–42")
    j = (servo - 1) % N_JOINTS
    return (servo - j - 1) // N_JOINTS, j
