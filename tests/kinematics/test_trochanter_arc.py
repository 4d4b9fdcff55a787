"""The trochanter as the thesis moves it (eq. 4.7–4.18), and the CoG along gravity (3.2.2)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from whexar.config import RobotConfig
from whexar.kinematics.body import leg_to_body, stance_feet
from whexar.kinematics.leg import fk_point, ik_point, trochanter_arc
from whexar.kinematics.stability import gravity_cog, support_margin

CFG = RobotConfig()
GEOMETRY = CFG.leg_geometry()
FEET = stance_feet(CFG.stance("default"))
# RM's neutral contact point in its leg frame (x outward, y down, z forward): coxa 0.
NEUTRAL = (float(FEET[2][0]), float(FEET[2][1]), float(FEET[2][2]))


@pytest.mark.parametrize("deg", [-45.0, -32.0, -14.0, 5.0, 23.0])
def test_the_arc_of_a_neutral_foot_is_where_the_thesis_leg_puts_it(deg: float) -> None:
    # The thesis's IK leaves the trochanter out: coxa, femur and tibia are the level
    # solution, and turning the trochanter turns that whole leg about its long axis.
    theta = math.radians(deg)
    level = ik_point(NEUTRAL, GEOMETRY, target="contact")
    rigid = fk_point((level[0], theta, level[2], level[3], level[4]), GEOMETRY)
    arc = trochanter_arc(NEUTRAL, theta)
    assert arc == pytest.approx(rigid, abs=1e-9)
    # whexar's IK at that trochanter angle gives the thesis's joints back.
    turned = ik_point(arc, GEOMETRY, pitch=theta, target="contact")
    assert turned[0] == pytest.approx(level[0], abs=1e-9)
    assert turned[2:] == pytest.approx(level[2:], abs=1e-9)


@pytest.mark.parametrize("leg", range(6))
def test_every_foot_moves_along_the_body_so_the_polygon_shifts_whole(leg: int) -> None:
    theta = math.radians(-32.0)
    foot = (float(FEET[leg][0]), float(FEET[leg][1]), float(FEET[leg][2]))
    arc = trochanter_arc(foot, theta)
    d = foot[1]
    assert np.subtract(arc, foot) == pytest.approx(
        (0.0, -d * (1 - math.cos(theta)), d * math.sin(theta))
    )
    # …and the leg reaches it with the trochanter at θ₁.
    ik_point(arc, GEOMETRY, pitch=theta, target="contact")


def test_nose_up_the_feet_go_back_and_up_nose_down_forward() -> None:
    # A middle leg (coxa 0): the arc is along the body's x only (leg frame z forward).
    depth, t = 0.25, math.radians(32.0)
    x, y, z = trochanter_arc((0.19, depth, 0.0), -t)
    assert (x, y, z) == pytest.approx((0.19, depth * math.cos(t), -depth * math.sin(t)))
    assert trochanter_arc((0.19, depth, 0.0), t)[2] == pytest.approx(-z)
    assert trochanter_arc((0.19, depth, 0.0), 0.0) == (0.19, depth, 0.0)
    # A foot in the air moves as the ground below it does: the path keeps its shape.
    lifted = trochanter_arc((0.19, depth - 0.06, 0.03), -t, depth)
    on_ground = trochanter_arc((0.19, depth, 0.03), -t)
    assert np.subtract(lifted, on_ground) == pytest.approx((0.0, -0.06, 0.0))


def _rotation(roll: float, pitch: float) -> np.ndarray:
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    product: np.ndarray = ry @ rx
    return product


@pytest.mark.parametrize(("roll", "pitch"), [(0.0, -0.4), (0.3, 0.0), (-0.2, 0.5), (0.1, -0.6)])
def test_the_cog_falls_along_gravity_onto_the_support_plane(roll: float, pitch: float) -> None:
    # Independently: gravity (0, 0, −1) of the world seen in the plane's frame, a ray from
    # the CoG along it, cut with the plane z = −h.
    cog, h = np.array([0.02, -0.01, 0.0]), 0.29
    g = _rotation(roll, pitch).T @ np.array([0.0, 0.0, -1.0])
    hit = cog + g * (h / -g[2])
    assert hit[2] == pytest.approx(-h)
    assert gravity_cog((0.02, -0.01), h, roll, pitch) == pytest.approx(tuple(hit[:2]), abs=1e-12)
    assert gravity_cog((0.02, -0.01), h, 0.0, 0.0) == (0.02, -0.01)


def test_a_tripod_margin_on_a_slope_is_the_notes_158_minus_233_tan() -> None:
    # The measured margin to the LM–RR edge with the CoG 0.29 m over the plane
    # (slopes-and-currents note): 158 − 233·tan θ mm, 0 at about 34°.
    feet = leg_to_body(stance_feet(CFG.stance("default")), GEOMETRY)
    tripod = [(float(feet[i][0]), float(feet[i][1])) for i in (0, 3, 4)]  # RF, LM, RR
    h = CFG.stance("default").height
    for deg in (0.0, 14.0, 23.0, 32.0):
        t = math.radians(deg)
        margin = support_margin(tripod, gravity_cog((0.0, 0.0), h, 0.0, -t))
        assert margin == pytest.approx(0.158 - 0.233 * math.tan(t) * h / 0.29, abs=0.003)
