"""Wheel-geometry cases for whexar.kinematics.wheels (Žák 2023, 5.4, eq. 5.8–5.18)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from whexar.config import default_geometry
from whexar.errors import UsageError
from whexar.kinematics.wheels import (
    direction_for_heading,
    heading_from_direction,
    wheel_sideways,
    wheel_spin,
    wheel_straight,
    wheel_turn,
    wheel_twist,
)

# Thesis geometry (Fig. 5.16): W_b between the front coxae (2 × 74 mm, Table 5.2); eq. 5.9 puts
# the front coxa L_b/2 ahead of C, which in the project frame (coxa at x = 0.30 m) is L_b = 0.60.
WHEEL_RADIUS = default_geometry().wheel_radius  # Table 5.2: 33 mm
W_B = 2 * 0.074
L_B = 0.60
P_X = 0.25  # foot reach outwards from the coxa, leg frame (m)
P_Z = 0.04  # foot offset forwards (front legs) / backwards (rear legs) from the coxa (m)

HALF_W = W_B / 2 + P_X  # eq. 5.8: lateral distance of every contact from C
HALF_L = L_B / 2 + P_Z  # eq. 5.9: longitudinal distance of front/rear contacts from C

# Body frame, x forward, y left; legs RF, LF, RM, LM, RR, LR.
CONTACTS = np.array(
    [
        [HALF_L, -HALF_W],
        [HALF_L, HALF_W],
        [0.0, -HALF_W],
        [0.0, HALF_W],
        [-HALF_L, -HALF_W],
        [-HALF_L, HALF_W],
    ]
)
MIRROR = [1, 0, 3, 2, 5, 4]  # the leg on the other side
FRONT, MIDDLE, REAR = [0, 1], [2, 3], [4, 5]


def test_straight_drives_all_wheels_equally_without_steering() -> None:
    cmd = wheel_straight(
        CONTACTS, 0.2, wheel_radius=WHEEL_RADIUS
    )  # 0.2 m/s: maximum wheeled speed, 6.5.1
    np.testing.assert_allclose(cmd.heading, 0.0, atol=0)
    np.testing.assert_allclose(cmd.direction, 0.0, atol=0)
    np.testing.assert_allclose(cmd.speed, 0.2)
    np.testing.assert_allclose(cmd.wheel_rate, 0.2 / 0.033)
    assert cmd.centre_of_rotation is None
    assert cmd.twist == (0.2, 0.0, 0.0)


def test_reversing_keeps_wheels_straight_and_drives_backwards() -> None:
    cmd = wheel_straight(CONTACTS, -0.1, wheel_radius=WHEEL_RADIUS)
    np.testing.assert_allclose(cmd.heading, 0.0, atol=1e-15)
    np.testing.assert_allclose(cmd.speed, -0.1)


@pytest.mark.parametrize("angle_deg", [45.0, -45.0, 30.0, 90.0])
def test_sideways_points_every_wheel_the_same_way(angle_deg: float) -> None:
    # 6.5.2 "Driving Sideways" turned the direction servos to ±45°.
    phi = math.radians(angle_deg)
    cmd = wheel_sideways(CONTACTS, 0.2, phi, wheel_radius=WHEEL_RADIUS)
    np.testing.assert_allclose(cmd.heading, phi, atol=1e-12)
    np.testing.assert_allclose(cmd.speed, 0.2)
    assert cmd.centre_of_rotation is None
    # Mirrored legs: right legs turn their direction joint by +φ, left ones by −φ.
    np.testing.assert_allclose(cmd.direction, [phi, -phi] * 3, atol=1e-12)


@pytest.mark.parametrize(
    ("angle_deg", "heading_deg", "sign"),
    [(-90.0, 90.0, -1.0), (135.0, -45.0, -1.0), (-135.0, 45.0, -1.0), (180.0, 0.0, -1.0)],
)
def test_sideways_beyond_90_degrees_reverses_instead_of_over_steering(
    angle_deg: float, heading_deg: float, sign: float
) -> None:
    cmd = wheel_sideways(CONTACTS, 0.2, math.radians(angle_deg), wheel_radius=WHEEL_RADIUS)
    np.testing.assert_allclose(cmd.heading, math.radians(heading_deg), atol=1e-12)
    np.testing.assert_allclose(cmd.speed, sign * 0.2)


def test_spin_matches_eq_5_10() -> None:
    omega = 2 * math.pi * 4 / 60  # 4 rpm, as measured in 6.5.2 "Rotation on the Spot"
    cmd = wheel_spin(CONTACTS, omega, wheel_radius=WHEEL_RADIUS)
    alpha = math.atan(HALF_L / HALF_W)  # eq. 5.8–5.10: α = arctan(P'_z / P'_x)
    np.testing.assert_allclose(np.abs(cmd.heading[FRONT + REAR]), alpha, rtol=1e-12)
    np.testing.assert_allclose(cmd.heading[MIDDLE], 0.0, atol=1e-15)
    # Counter-clockwise: RF rolls forward-left (+α), RR forward-right (−α); left wheels reverse.
    np.testing.assert_allclose(cmd.heading, [alpha, -alpha, 0, 0, -alpha, alpha], atol=1e-12)
    assert list(np.sign(cmd.speed)) == [1, -1, 1, -1, 1, -1]
    # Speeds proportional to the distance from C (eq. 5.17–5.18).
    np.testing.assert_allclose(np.abs(cmd.speed) / np.hypot(*CONTACTS.T), omega)
    assert cmd.centre_of_rotation is not None
    np.testing.assert_allclose(cmd.centre_of_rotation, np.zeros(2), atol=0)
    # Mirrored legs receive the same direction angle; rear ones the inverse of the front ones.
    np.testing.assert_allclose(cmd.direction, [alpha, alpha, 0, 0, -alpha, -alpha], atol=1e-12)


def test_spin_clockwise_reverses_speeds_only() -> None:
    ccw, cw = (
        wheel_spin(CONTACTS, 0.5, wheel_radius=WHEEL_RADIUS),
        wheel_spin(CONTACTS, -0.5, wheel_radius=WHEEL_RADIUS),
    )
    np.testing.assert_allclose(cw.heading, ccw.heading)
    np.testing.assert_allclose(cw.speed, -ccw.speed)


def thesis_turn_angles(radius: float) -> tuple[float, float]:
    """Eq. 5.11–5.16 as printed; returns (α with R − W_b/2 − P_x, α with R + W_b/2 + P_x)."""
    p1x = radius - W_B / 2 - P_X  # eq. 5.11
    p1z = L_B / 2 + P_Z  # eq. 5.12
    p2x = radius + W_B / 2 + P_X  # eq. 5.13
    p2z = L_B / 2 + P_Z  # eq. 5.14
    return math.atan(p1z / p1x), math.atan(p2z / p2x)  # eq. 5.15, 5.16


@pytest.mark.parametrize("radius", [0.8, 1.5, 4.0])
def test_left_turn_matches_eq_5_11_to_5_16(radius: float) -> None:
    alpha_1, alpha_2 = thesis_turn_angles(radius)
    cmd = wheel_turn(CONTACTS, radius, speed=0.2, wheel_radius=WHEEL_RADIUS)
    # S = (0, R) lies on the left: the left (near) wheels are R − W_b/2 − P_x from S laterally.
    np.testing.assert_allclose(cmd.heading[1], alpha_1, rtol=1e-12)
    np.testing.assert_allclose(cmd.heading[0], alpha_2, rtol=1e-12)
    assert alpha_1 > alpha_2 > 0  # the wheel nearer S steers harder
    # Rear legs: "the inverse of α₁ and α₂"; middle legs point at S.
    np.testing.assert_allclose(cmd.heading[5], -alpha_1, rtol=1e-12)
    np.testing.assert_allclose(cmd.heading[4], -alpha_2, rtol=1e-12)
    np.testing.assert_allclose(cmd.heading[MIDDLE], 0.0, atol=1e-15)
    assert np.all(cmd.speed > 0)
    # All wheels share the angular velocity ω = v/R about S (eq. 5.17–5.18).
    to_s = np.hypot(CONTACTS[:, 0], CONTACTS[:, 1] - radius)
    np.testing.assert_allclose(cmd.speed / to_s, 0.2 / radius, rtol=1e-12)
    assert cmd.centre_of_rotation is not None
    np.testing.assert_allclose(cmd.centre_of_rotation, np.array([0.0, radius]), atol=1e-15)


def test_turn_with_yaw_rate_equals_turn_with_speed() -> None:
    by_speed = wheel_turn(CONTACTS, -1.2, speed=0.3, wheel_radius=WHEEL_RADIUS)
    by_rate = wheel_turn(CONTACTS, -1.2, yaw_rate=0.3 / -1.2, wheel_radius=WHEEL_RADIUS)
    np.testing.assert_allclose(by_rate.heading, by_speed.heading)
    np.testing.assert_allclose(by_rate.speed, by_speed.speed)
    np.testing.assert_allclose(by_speed.twist, (0.3, 0.0, -0.25))


def test_right_turn_mirrors_left_turn_direction_angles() -> None:
    left, right = (
        wheel_turn(CONTACTS, 1.0, speed=0.2, wheel_radius=WHEEL_RADIUS),
        wheel_turn(CONTACTS, -1.0, speed=0.2, wheel_radius=WHEEL_RADIUS),
    )
    np.testing.assert_allclose(right.heading, -left.heading[MIRROR], atol=1e-15)
    np.testing.assert_allclose(right.speed, left.speed[MIRROR])
    # Mirrored legs take the same direction-joint signal for mirrored manoeuvres (5.1).
    np.testing.assert_allclose(right.direction, left.direction[MIRROR], atol=1e-15)


def test_turn_with_large_radius_tends_to_straight() -> None:
    cmd = wheel_turn(CONTACTS, 1e6, speed=0.2, wheel_radius=WHEEL_RADIUS)
    np.testing.assert_allclose(cmd.heading, 0.0, atol=1e-6)
    np.testing.assert_allclose(cmd.speed, 0.2, rtol=1e-6)


def test_coxa_angles_offset_the_direction_joints() -> None:
    coxa = np.array([0.1, -0.2, 0.3, 0.05, -0.4, 0.25])
    plain = wheel_spin(CONTACTS, 0.4, wheel_radius=WHEEL_RADIUS)
    rotated = wheel_spin(CONTACTS, 0.4, coxa=coxa, wheel_radius=WHEEL_RADIUS)
    np.testing.assert_allclose(rotated.heading, plain.heading)
    np.testing.assert_allclose(rotated.direction, plain.direction - coxa)
    # ψ = s·(coxa + direction): the coxa-rotated leg still points the wheel the same way.
    np.testing.assert_allclose(heading_from_direction(rotated.direction, coxa), plain.heading)
    np.testing.assert_allclose(direction_for_heading(plain.heading, coxa), rotated.direction)


def test_left_and_right_frames_mirror_the_direction_joint() -> None:
    heading = np.full(6, 0.3)
    np.testing.assert_allclose(direction_for_heading(heading), [0.3, -0.3] * 3)


@settings(max_examples=150, deadline=None)
@given(
    vx=st.floats(-1, 1),
    vy=st.floats(-1, 1),
    omega=st.floats(-3, 3),
    offsets=st.lists(st.floats(-0.1, 0.1), min_size=12, max_size=12),
)
def test_twist_reproduces_the_rigid_body_velocity(
    vx: float, vy: float, omega: float, offsets: list[float]
) -> None:
    contacts = CONTACTS + np.reshape(offsets, (6, 2))
    cmd = wheel_twist(contacts, vx, vy, omega, wheel_radius=WHEEL_RADIUS)
    assert np.all(cmd.heading > -math.pi / 2)
    assert np.all(cmd.heading <= math.pi / 2)
    # Independently: v_i = v + ω ẑ × c_i must equal speed·(cos ψ, sin ψ).
    expected = np.column_stack([vx - omega * contacts[:, 1], vy + omega * contacts[:, 0]])
    rolled = cmd.speed[:, None] * np.column_stack([np.cos(cmd.heading), np.sin(cmd.heading)])
    np.testing.assert_allclose(rolled, expected, atol=1e-12)
    np.testing.assert_allclose(cmd.wheel_rate * WHEEL_RADIUS, cmd.speed, atol=1e-15)
    if cmd.centre_of_rotation is not None:
        distance = np.hypot(*(contacts - cmd.centre_of_rotation).T)
        np.testing.assert_allclose(np.abs(cmd.speed), abs(omega) * distance, rtol=1e-9, atol=1e-12)


def test_wheel_radius_sets_wheel_rate() -> None:
    cmd = wheel_straight(CONTACTS, 0.1, wheel_radius=0.05)
    np.testing.assert_allclose(cmd.wheel_rate, 2.0)


def test_contacts_with_z_are_accepted() -> None:
    with_z = np.column_stack([CONTACTS, np.full(6, -0.3)])
    np.testing.assert_allclose(
        wheel_spin(with_z, 1.0, wheel_radius=WHEEL_RADIUS).heading,
        wheel_spin(CONTACTS, 1.0, wheel_radius=WHEEL_RADIUS).heading,
    )


def test_command_arrays_are_read_only() -> None:
    cmd = wheel_straight(CONTACTS, 0.1, wheel_radius=WHEEL_RADIUS)
    with pytest.raises(ValueError, match="read-only"):
        cmd.speed[0] = 1.0


def test_turn_radius_zero_points_to_spin() -> None:
    with pytest.raises(UsageError, match="wheel_spin"):
        wheel_turn(CONTACTS, 0.0, speed=0.1, wheel_radius=WHEEL_RADIUS)


@pytest.mark.parametrize(("speed", "yaw_rate"), [(None, None), (0.1, 0.1)], ids=["neither", "both"])
def test_turn_needs_exactly_one_rate(speed: float | None, yaw_rate: float | None) -> None:
    with pytest.raises(UsageError, match="exactly one"):
        wheel_turn(CONTACTS, 1.0, speed=speed, yaw_rate=yaw_rate, wheel_radius=WHEEL_RADIUS)


@pytest.mark.parametrize(
    "contacts",
    [CONTACTS[:5], CONTACTS.ravel(), np.zeros((6, 4))],
    ids=["five legs", "flat", "four columns"],
)
def test_bad_contact_shapes_are_rejected(contacts: np.ndarray) -> None:
    with pytest.raises(UsageError, match="shape"):
        wheel_straight(contacts, 0.1, wheel_radius=WHEEL_RADIUS)


def test_non_finite_inputs_are_rejected() -> None:
    bad = CONTACTS.copy()
    bad[3, 1] = np.nan
    with pytest.raises(UsageError, match=r"contacts\[3, 1\]"):
        wheel_straight(bad, 0.1, wheel_radius=WHEEL_RADIUS)
    with pytest.raises(UsageError, match="speed"):
        wheel_straight(CONTACTS, math.inf, wheel_radius=WHEEL_RADIUS)
    with pytest.raises(UsageError, match="coxa"):
        wheel_straight(CONTACTS, 0.1, coxa=[0.0] * 5, wheel_radius=WHEEL_RADIUS)


@pytest.mark.parametrize("radius", [0.0, -0.033, math.nan])
def test_wheel_radius_must_be_positive(radius: float) -> None:
    with pytest.raises(UsageError, match="wheel_radius"):
        wheel_straight(CONTACTS, 0.1, wheel_radius=radius)
