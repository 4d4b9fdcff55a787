"""Leg frames ↔ body frame, body poses and stances (Diosdado 2014, 3.2; Žák 2023, 5.2, 6.4)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from whexar.config import RobotConfig
from whexar.errors import UsageError
from whexar.kinematics.body import (
    BodyPose,
    apply_body_pose,
    body_to_leg,
    leg_to_body,
    pose_ik,
    stance_feet,
)
from whexar.kinematics.leg import fk

CFG = RobotConfig()
G = CFG.leg_geometry()


def test_leg_frames_point_outward_down_forward() -> None:
    p = np.tile([0.19, 0.12, 0.05], (6, 1))
    body = leg_to_body(p, G)
    # RF: outward is −y, down is −z, forward is +x, from the coxa at (0.30, −0.074, 0).
    np.testing.assert_allclose(body[0], [0.35, -0.264, -0.12])
    # LF mirrors it across the body's x–z plane.
    np.testing.assert_allclose(body[1], [0.35, 0.264, -0.12])
    np.testing.assert_allclose(body[4], [-0.25, -0.264, -0.12])  # RR
    np.testing.assert_allclose(body[3], [0.05, 0.264, -0.12])  # LM


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-1, 1), min_size=18, max_size=18))
def test_frames_round_trip(values: list[float]) -> None:
    p = np.array(values).reshape(6, 3)
    np.testing.assert_allclose(body_to_leg(leg_to_body(p, G), G), p, atol=1e-12)
    np.testing.assert_allclose(leg_to_body(body_to_leg(p, G), G), p, atol=1e-12)


def test_stance_is_symmetric_and_reproduces_table_6_5_row_1() -> None:
    feet = stance_feet(CFG.stance("default"))
    body = leg_to_body(feet, G)
    np.testing.assert_allclose(body[1::2, 1], -body[0::2, 1])  # left mirrors right
    np.testing.assert_allclose(body[:, 2], -0.29)  # contacts 290 mm below the coxae
    yaw = np.degrees(np.arctan2(feet[:, 2], feet[:, 0]))
    np.testing.assert_allclose(yaw, [25, 25, 0, 0, -25, -25])
    solution = pose_ik(body, G)
    np.testing.assert_allclose(
        solution.degrees[2, [0, 2, 3, 4]], [0.0, 1.80, -92.69, 0.90], atol=0.01
    )


def test_every_stance_preset_is_reachable() -> None:
    for name, stance in CFG.stances.items():
        solution = pose_ik(leg_to_body(stance_feet(stance.to_stance()), G), G)
        assert not solution.any_clamped, name


def test_rotation_is_proper_and_zyx() -> None:
    pose = BodyPose(roll=0.2, pitch=-0.3, yaw=0.7)
    r = pose.rotation
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(r) == pytest.approx(1.0)
    # Positive pitch lowers the nose: the body x axis tips towards −z.
    nose = BodyPose(pitch=0.1).rotation @ [1.0, 0.0, 0.0]
    assert nose[2] < 0
    # Yaw turns x towards y (counter-clockwise from above).
    np.testing.assert_allclose(
        BodyPose(yaw=math.pi / 2).rotation @ [1, 0, 0], [0, 1, 0], atol=1e-15
    )


def test_body_pose_moves_feet_the_other_way() -> None:
    feet = leg_to_body(stance_feet(CFG.stance("basic")), G)
    shifted = apply_body_pose(feet, BodyPose(x=0.05, z=0.02))
    np.testing.assert_allclose(shifted - feet, np.tile([-0.05, 0.0, -0.02], (6, 1)))
    turned = apply_body_pose(feet, BodyPose(yaw=0.1))
    np.testing.assert_allclose(np.linalg.norm(turned, axis=1), np.linalg.norm(feet, axis=1))
    # The feet stay where they were in the world: R·p' + t = p.
    pose = BodyPose(x=0.01, y=-0.02, z=0.03, roll=0.05, pitch=-0.04, yaw=0.2)
    moved = apply_body_pose(feet, pose)
    np.testing.assert_allclose(moved @ pose.rotation.T + pose.translation, feet, atol=1e-15)


def test_pose_ik_keeps_the_feet_on_the_ground() -> None:
    feet = leg_to_body(stance_feet(CFG.stance("default")), G)
    pose = BodyPose(x=0.02, z=0.03, roll=0.05, pitch=0.08, yaw=-0.1)
    for follow in (False, True):
        solution = pose_ik(feet, G, pose, trochanter_follows_pitch=follow)
        contacts = leg_to_body(fk(solution.angles, G, point="contact"), G)
        world = contacts @ pose.rotation.T + pose.translation
        np.testing.assert_allclose(world, feet, atol=1e-12)
        assert np.allclose(solution.angles[:, 1], 0.08 if follow else 0.0)


def test_bad_shapes_and_values_are_named() -> None:
    with pytest.raises(UsageError, match=r"shape \(5, 3\)"):
        leg_to_body(np.zeros((5, 3)), G)
    bad = np.zeros((6, 3))
    bad[2, 1] = math.nan
    with pytest.raises(UsageError, match=r"\(2, 1\) = nan"):
        body_to_leg(bad, G)
    with pytest.raises(UsageError, match="yaw = inf"):
        BodyPose(yaw=math.inf)
