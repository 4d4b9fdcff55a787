"""Leg, joint and servo numbering (Žák 2023, eq. 4.1–4.3, Fig. 4.2)."""

import pytest

from whexar.errors import UsageError
from whexar.robot import (
    JOINT_NAMES,
    LEG_NAMES,
    joint_index,
    joint_of_servo,
    leg_index,
    leg_side,
    servo_id,
)


def test_servo_ids_follow_eq_4_1_and_invert_by_eq_4_2_4_3() -> None:
    seen = set()
    for leg in range(6):
        for joint in range(7):
            sid = servo_id(leg, joint)
            assert sid == 7 * leg + joint + 1
            assert joint_of_servo(sid) == (leg, joint)
            seen.add(sid)
    assert seen == set(range(1, 43))


def test_names_and_sides() -> None:
    assert servo_id("LR", "wheel") == 42
    assert servo_id("RF", "coxa") == 1
    assert [leg_side(n) for n in LEG_NAMES] == ["right", "left"] * 3
    assert leg_index("lm") == 3
    assert leg_index("2") == 2
    assert joint_index("Tarsus") == JOINT_NAMES.index("tarsus")


@pytest.mark.parametrize("bad", ["XX", 6, -1, True, "7"])
def test_unknown_leg_is_named(bad: object) -> None:
    with pytest.raises(UsageError, match="unknown leg"):
        leg_index(bad)  # type: ignore[arg-type]


def test_unknown_joint_and_servo_are_named() -> None:
    with pytest.raises(UsageError, match="'knee'"):
        joint_index("knee")
    with pytest.raises(UsageError, match="43"):
        joint_of_servo(43)
