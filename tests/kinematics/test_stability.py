"""Static stability margin (Žák 2023, 3.2.2, eq. 3.1–3.6)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from whexar.errors import UsageError
from whexar.kinematics.stability import (
    static_stability_margin,
    static_stability_margins,
    triangle_margin,
)

P1, P2, P3 = (0.0, 0.0), (4.0, 0.0), (0.0, 3.0)  # legs 4 and 3, hypotenuse 3x + 4y = 12
RIGHT_TRIANGLE = [P1, P2, P3]


@pytest.mark.parametrize(
    ("cog", "expected"),
    [
        ((1.0, 1.0), 1.0),  # 1 from both legs, (12 − 3 − 4)/5 = 1 from the hypotenuse
        ((1.0, 0.5), 0.5),  # nearest the x axis
        ((2.0, 1.2), 0.24),  # (12 − 6 − 4.8)/5 from the hypotenuse
        ((2.0, 0.0), 0.0),  # on an edge: critically stable
    ],
)
def test_triangle_against_hand_computed_altitudes(
    cog: tuple[float, float], expected: float
) -> None:
    assert triangle_margin(P1, P2, P3, cog=cog) == pytest.approx(expected, abs=1e-12)
    assert static_stability_margin(RIGHT_TRIANGLE, cog) == pytest.approx(expected, abs=1e-12)


def test_thesis_tripod_right_front_left_middle_right_rear() -> None:
    # Fig. 3.5: RF, LM, RR on the ground; feet 0.25 m outside the coxae (x = ±0.30, y = ∓0.074).
    rf, lm, rr = (0.30, -0.324), (0.0, 0.324), (-0.30, -0.324)
    # C to the line RF–LM: |x_rf·y_lm − x_lm·y_rf| / |RF − LM| (the RR–LM edge is its mirror).
    expected = abs(0.30 * 0.324 - 0.0 * -0.324) / math.hypot(0.30, 0.648)
    assert expected < 0.324  # the diagonal edges bind, not the right-hand edge
    assert triangle_margin(rf, lm, rr) == pytest.approx(expected, rel=1e-12)
    assert static_stability_margin([rf, lm, rr]) == pytest.approx(expected, rel=1e-12)


def test_triangle_orientation_does_not_matter() -> None:
    a, b, c = RIGHT_TRIANGLE
    assert triangle_margin(a, c, b, cog=(1.0, 0.5)) == pytest.approx(0.5)


def regular_hexagon(radius: float, centre: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    angles = np.arange(6) * math.pi / 3
    return np.column_stack(
        [centre[0] + radius * np.cos(angles), centre[1] + radius * np.sin(angles)]
    )


def test_regular_hexagon_centre_margin_is_the_apothem() -> None:
    assert static_stability_margin(regular_hexagon(0.4)) == pytest.approx(0.4 * math.sqrt(3) / 2)


def test_hexagon_with_z_column_ignores_z() -> None:
    hexagon = np.column_stack([regular_hexagon(0.4), np.linspace(-0.3, -0.2, 6)])
    assert static_stability_margin(hexagon, (0.0, 0.0, 0.5)) == pytest.approx(0.2 * math.sqrt(3))


def test_cog_outside_is_negative_distance_to_the_polygon() -> None:
    # (0.8, 0): the nearest boundary point is the corner (0.4, 0), 0.4 away.
    assert static_stability_margin(regular_hexagon(0.4), (0.8, 0.0)) == pytest.approx(-0.4)
    # Straight below the bottom edge (y = −0.4·√3/2): distance 0.1 to that edge.
    below = (0.0, -0.4 * math.sqrt(3) / 2 - 0.1)
    assert static_stability_margin(regular_hexagon(0.4), below) == pytest.approx(-0.1)


def test_outside_near_a_corner_eq_3_6_understates_the_distance() -> None:
    # Eq. 3.6 measures to edge *lines*; outside a corner the true distance is to the corner.
    cog = (5.0, -1.0)
    assert triangle_margin(P1, P2, P3, cog=cog) == pytest.approx(-1.0)
    assert static_stability_margin(RIGHT_TRIANGLE, cog) == pytest.approx(-math.sqrt(2))


def test_collinear_supports_enclose_nothing() -> None:
    line = [(0.0, 0.0), (1.0, 0.0), (2.0, 0.0)]
    assert static_stability_margin(line, (1.5, 0.0)) == 0.0
    assert static_stability_margin(line, (1.0, 0.3)) == pytest.approx(-0.3)
    assert static_stability_margin(line, (3.0, 0.0)) == pytest.approx(-1.0)
    assert triangle_margin(line[0], line[1], line[2], cog=(1.0, 0.3)) == pytest.approx(-0.3)


def test_coincident_supports_are_a_point() -> None:
    same = [(1.0, 1.0)] * 4
    assert static_stability_margin(same, (4.0, 5.0)) == pytest.approx(-5.0)


def test_vectorised_margins_match_single_cogs() -> None:
    hexagon = regular_hexagon(0.3, (0.05, -0.02))
    cogs = np.array([[0.0, 0.0], [0.2, 0.1], [0.5, 0.5], [-0.31, 0.0]])
    expected = [static_stability_margin(hexagon, c) for c in cogs]
    np.testing.assert_allclose(static_stability_margins(hexagon, cogs), expected)


@pytest.mark.parametrize("count", [0, 1, 2, 7])
def test_support_count_outside_3_to_6_is_rejected(count: int) -> None:
    with pytest.raises(UsageError, match=f"{count} points"):
        static_stability_margin(np.arange(2 * count, dtype=float).reshape(count, 2))


def test_bad_values_are_rejected() -> None:
    with pytest.raises(UsageError, match=r"support_points\[1, 0\]"):
        static_stability_margin([(0.0, 0.0), (math.nan, 0.0), (0.0, 1.0)])
    with pytest.raises(UsageError, match="cog"):
        static_stability_margin(RIGHT_TRIANGLE, (0.0, 0.0, 0.0, 0.0))
    with pytest.raises(UsageError, match="cog"):
        triangle_margin(P1, P2, P3, cog=(math.inf, 0.0))
    with pytest.raises(UsageError, match="shape"):
        static_stability_margin([1.0, 2.0, 3.0])


def triangle_area(corners: np.ndarray) -> float:
    (x1, y1), (x2, y2), (x3, y3) = corners
    return 0.5 * float(abs((x2 - x1) * (y3 - y1) - (x3 - x1) * (y2 - y1)))


coordinate = st.floats(-1.0, 1.0, allow_nan=False)
point = st.tuples(coordinate, coordinate)


@settings(max_examples=100, deadline=None)
@given(
    a=point,
    b=point,
    c=point,
    weights=st.tuples(*[st.floats(0.01, 1.0)] * 3),
)
def test_general_margin_equals_eq_3_6_inside_a_triangle(
    a: tuple[float, float],
    b: tuple[float, float],
    c: tuple[float, float],
    weights: tuple[float, float, float],
) -> None:
    corners = np.array([a, b, c])
    if triangle_area(corners) < 1e-3:
        return
    cog = np.asarray(weights) @ corners / sum(weights)  # strictly inside
    expected = triangle_margin(a, b, c, cog)
    assert expected > 0
    assert static_stability_margin(corners, cog) == pytest.approx(expected, rel=1e-9, abs=1e-12)


@settings(max_examples=100, deadline=None)
@given(a=point, b=point, c=point, cog=point)
def test_outside_a_triangle_the_true_distance_is_at_least_eq_3_6(
    a: tuple[float, float],
    b: tuple[float, float],
    c: tuple[float, float],
    cog: tuple[float, float],
) -> None:
    corners = np.array([a, b, c])
    if triangle_area(corners) < 1e-3:
        return
    general, literal = static_stability_margin(corners, cog), triangle_margin(a, b, c, cog)
    if literal < 0:
        assert general <= literal + 1e-12
    else:
        assert general == pytest.approx(literal, abs=1e-12)


@settings(max_examples=100, deadline=None)
@given(st.lists(point, min_size=3, max_size=6), point, st.data())
def test_margin_is_permutation_invariant(
    supports: list[tuple[float, float]], cog: tuple[float, float], data: st.DataObject
) -> None:
    shuffled = data.draw(st.permutations(supports))
    assert static_stability_margin(shuffled, cog) == pytest.approx(
        static_stability_margin(supports, cog), abs=1e-12
    )


@settings(max_examples=100, deadline=None)
@given(
    angles=st.lists(st.floats(0.0, 2 * math.pi), min_size=3, max_size=6, unique=True),
    radius=st.floats(0.05, 1.0),
    centre=point,
    cog=point,
)
def test_margin_never_exceeds_distance_to_a_support(
    angles: list[float], radius: float, centre: tuple[float, float], cog: tuple[float, float]
) -> None:
    # Feet on a circle are all corners of the polygon. (A foot strictly inside the polygon
    # is not on its boundary, so the margin can exceed the distance to *that* foot.)
    feet = np.column_stack(
        [centre[0] + radius * np.cos(angles), centre[1] + radius * np.sin(angles)]
    )
    nearest = np.hypot(*(feet - np.asarray(cog)).T).min()
    assert static_stability_margin(feet, cog) <= nearest + 1e-12


@settings(max_examples=100, deadline=None)
@given(st.lists(point, min_size=3, max_size=5), point, point)
def test_adding_a_support_never_decreases_the_margin(
    supports: list[tuple[float, float]], extra: tuple[float, float], cog: tuple[float, float]
) -> None:
    before = static_stability_margin(supports, cog)
    after = static_stability_margin([*supports, extra], cog)
    assert after >= before - 1e-12
