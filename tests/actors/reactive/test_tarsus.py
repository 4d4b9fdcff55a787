"""The tarsus reflex's policy, called directly: eq. 4.19 from the present angles, where
the tarsus is off it."""

from __future__ import annotations

import math

import pytest

from whexar.actors.messages import JointGoals, JointState, ServoStates
from whexar.actors.reactive import check_params
from whexar.actors.reactive.tarsus import Tarsus, parallel_to_gravity
from whexar.config import RobotConfig


def tarsus() -> Tarsus:
    return Tarsus(check_params(Tarsus, {}), name="reflex-tarsus", cfg=RobotConfig())


def reading(t: float, femur: float, tibia: float, tarsus_rad: float, leg: int = 3) -> ServoStates:
    angles = {2: femur, 3: tibia, 4: tarsus_rad}
    joints = tuple(
        JointState(leg=leg, joint=j, servo_id=7 * leg + j + 1, position_rad=a)
        for j, a in angles.items()
    )
    return ServoStates(t=t, source="bus", cycle=0, joints=joints)


def test_eq_4_19_keeps_the_last_segment_vertical() -> None:
    # Table 6.5, rows 1 and 2: femur, tibia → the tarsus the thesis's IK gave.
    for femur, tibia, tarsus_deg in ((1.80, -92.69, 0.90), (-18.09, -58.39, -13.52)):
        got = math.degrees(parallel_to_gravity(math.radians(femur), math.radians(tibia)))
        assert got == pytest.approx(tarsus_deg, abs=0.015)  # the table rounds to 0.01°


def test_a_tarsus_off_gravity_is_overridden_one_on_it_left_alone() -> None:
    r = tarsus()
    femur, tibia = 0.4, -1.7
    on = parallel_to_gravity(femur, tibia)
    assert list(r.react(1.0, reading(1.0, femur, tibia, on + 0.01))) == []
    assert not r.active
    (goals,) = r.react(1.1, reading(1.1, femur, tibia, on + 0.2))
    assert isinstance(goals, JointGoals)
    assert goals.reflex
    (g,) = goals.goals
    assert (g.leg, g.joint) == (3, 4)
    assert g.position_rad == pytest.approx(on)
    assert r.active
    assert r.reason == "tarsus of legs [3] off gravity"
