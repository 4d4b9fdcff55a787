"""Leg FK and IK: Table 6.5, FK∘IK, joint limits, bad input (Žák 2023, 4.1, 6.2)."""

import json
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from whexar.cli import main
from whexar.config import default_geometry
from whexar.errors import JointLimitError, KinematicsError, UnreachableError, UsageError
from whexar.kinematics.leg import (
    CHAIN_POINTS,
    Target,
    dh_transforms,
    fk,
    fk_chain,
    ik,
    ik_point,
)

# Table 6.5: goal coordinates [mm] and coxa, femur, tibia, tarsus [deg].
TABLE_6_5 = [
    ((190, 120, 0), (0.00, 1.80, -92.69, 0.90)),
    ((190, 160, 100), (27.76, -18.09, -58.39, -13.52)),
    ((190, 80, -100), (-27.76, 18.59, -94.90, -13.68)),
    ((150, 120, 0), (0.00, -1.50, -108.28, 19.78)),
    ((240, 120, 0), (0.00, -2.58, -64.58, -22.84)),
]
G = default_geometry()
LOWER, UPPER = G.limits[:, 0], G.limits[:, 1]


@pytest.mark.parametrize(("goal", "expected"), TABLE_6_5)
def test_ik_reproduces_table_6_5(goal: tuple[int, ...], expected: tuple[float, ...]) -> None:
    solution = ik(np.array(goal) / 1000, G)
    got = solution.degrees[[0, 2, 3, 4]]
    # The table rounds to 0.01°; its tarsus column was computed from rounded
    # femur and tibia, so allow the 0.05°.
    np.testing.assert_allclose(got, expected, atol=0.05)
    assert solution.degrees[1] == 0.0


def test_fk_of_table_angles_gives_table_coordinates() -> None:
    angles = np.radians([[c, 0.0, f, ti, ta] for _, (c, f, ti, ta) in TABLE_6_5])
    goals = np.array([goal for goal, _ in TABLE_6_5], dtype=float)
    # Angles printed to 0.01° move a 250 mm leg by up to ~0.05 mm.
    np.testing.assert_allclose(fk(angles, G) * 1000, goals, atol=0.1)


def test_all_rows_in_one_vectorised_call() -> None:
    goals = np.array([goal for goal, _ in TABLE_6_5]) / 1000
    solution = ik(goals, G)
    np.testing.assert_allclose(fk(solution.angles, G), goals, atol=1e-9)
    assert solution.angles.shape == (5, 5)


def test_dh_transform_is_eq_4_4() -> None:
    q = np.array([0.3, -0.2, 0.5, -1.1, 0.4])
    links = dh_transforms(q, G)
    for k in range(5):
        theta = G.theta_sign[k] * q[k] + G.theta_offset[k]
        ct, st_, ca, sa = (
            math.cos(theta),
            math.sin(theta),
            math.cos(G.dh_alpha[k]),
            math.sin(G.dh_alpha[k]),
        )
        rot_z = np.array([[ct, -st_, 0, 0], [st_, ct, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
        trans_z = np.eye(4)
        trans_z[2, 3] = G.dh_d[k]
        trans_x = np.eye(4)
        trans_x[0, 3] = G.dh_a[k]
        rot_x = np.array([[1, 0, 0, 0], [0, ca, -sa, 0], [0, sa, ca, 0], [0, 0, 0, 1]])
        np.testing.assert_allclose(links[k], rot_z @ trans_z @ trans_x @ rot_x, atol=1e-15)


def test_chain_reaches_the_wheel_contact_below_a_vertical_tarsus() -> None:
    solution = ik([0.19, 0.12, 0.0], G)
    chain = fk_chain(solution.angles, G)
    tarsus = chain[CHAIN_POINTS.index("tarsus")]
    contact = chain[CHAIN_POINTS.index("contact")]
    # 95 + 42 + 33 mm straight down (Table 5.2).
    np.testing.assert_allclose(contact - tarsus, [0.0, 0.170, 0.0], atol=1e-12)
    np.testing.assert_allclose(chain[CHAIN_POINTS.index("femur")], [0.065, 0.0, 0.0], atol=1e-12)
    segment = np.linalg.norm(np.diff(chain[1:4], axis=0), axis=1)
    np.testing.assert_allclose(segment, [0.127, 0.124], atol=1e-12)


def test_contact_target_and_pitch() -> None:
    p = np.array([[0.2, 0.30, 0.05], [0.17, 0.25, -0.08]])
    for pitch in (0.0, 0.25, -0.4):
        sol = ik(p, G, pitch=pitch, target="contact")
        np.testing.assert_allclose(fk(sol.angles, G, point="contact"), p, atol=1e-12)
        np.testing.assert_allclose(sol.angles[:, 1], pitch)
        # The last segment stays parallel to the (pitched) leg plane's vertical.
        chain = fk_chain(sol.angles, G)
        down = chain[:, -1] - chain[:, 3]
        expected = np.array([0.0, math.cos(pitch), math.sin(pitch)])
        rotated = down / np.linalg.norm(down, axis=-1, keepdims=True)
        # Undo the coxa rotation about the vertical (leg y axis) before comparing.
        c = sol.angles[:, 0]
        back = np.stack(
            [
                rotated[:, 0] * np.cos(c) + rotated[:, 2] * np.sin(c),
                rotated[:, 1],
                -rotated[:, 0] * np.sin(c) + rotated[:, 2] * np.cos(c),
            ],
            axis=-1,
        )
        np.testing.assert_allclose(back, np.tile(expected, (2, 1)), atol=1e-12)


def _joint_sample(rng: np.random.Generator, n: int) -> np.ndarray:
    q = np.empty((n, 5))
    q[:, 0] = rng.uniform(LOWER[0], UPPER[0], n)
    q[:, 1] = rng.uniform(-1.2, 1.2, n)
    q[:, 2] = rng.uniform(LOWER[2], UPPER[2], n)
    q[:, 3] = rng.uniform(LOWER[3], 0.0, n)  # the IK's knee branch (tibia folds down)
    q[:, 4] = -math.pi / 2 - q[:, 2] - q[:, 3]
    return q


def test_fk_ik_round_trip_over_the_workspace() -> None:
    rng = np.random.default_rng(2024)
    q = _joint_sample(rng, 20_000)
    p = fk(q, G)
    sol = ik(p, G, pitch=q[:, 1], clamp=True)
    met = ~sol.clamped
    assert met.mean() > 0.5  # most samples lie inside every limit
    err = np.linalg.norm(fk(sol.angles[met], G) - p[met], axis=-1)
    assert err.max() < 1e-6  # 1 µm
    assert sol.reachable.all()  # every FK output is in the workspace


@settings(max_examples=300, deadline=None)
@given(
    coxa=st.floats(-2.3, 2.3),
    pitch=st.floats(-1.2, 1.2),
    femur=st.floats(-2.09, 2.09),
    tibia=st.floats(-2.6, -0.01),
)
def test_fk_of_ik_is_identity(coxa: float, pitch: float, femur: float, tibia: float) -> None:
    tarsus = -math.pi / 2 - femur - tibia
    assume(LOWER[4] <= tarsus <= UPPER[4])
    q = np.array([coxa, pitch, femur, tibia, tarsus])
    p = fk(q, G)
    # The IK picks the branch with the tarsus joint outward of the coxa axis.
    rho = G.trochanter_offset + G.femur * math.cos(femur) + G.tibia * math.cos(femur + tibia)
    assume(rho > 1e-3)
    sol = ik(p, G, pitch=pitch)
    assert np.linalg.norm(fk(sol.angles, G) - p) < 1e-6
    np.testing.assert_allclose(sol.angles, q, atol=1e-6)


@settings(max_examples=300, deadline=None)
@given(
    x=st.floats(-0.6, 0.6),
    y=st.floats(-0.6, 0.6),
    z=st.floats(-0.6, 0.6),
    pitch=st.floats(-1.5, 1.5),
    target=st.sampled_from(["tarsus", "contact"]),
)
def test_no_ik_result_leaves_the_joint_limits(
    x: float, y: float, z: float, pitch: float, target: str
) -> None:
    p = np.array([x, y, z])
    clamped = ik(p, G, pitch=pitch, target=target, clamp=True)  # type: ignore[arg-type]
    assert np.all(clamped.angles >= LOWER)
    assert np.all(clamped.angles <= UPPER)
    if not clamped.clamped:
        assert np.linalg.norm(fk(clamped.angles, G, point=target) - p) < 1e-9  # type: ignore[arg-type]
    try:
        strict = ik(p, G, pitch=pitch, target=target)  # type: ignore[arg-type]
    except KinematicsError:
        assert clamped.clamped
    else:
        assert np.all(strict.angles >= LOWER)
        assert np.all(strict.angles <= UPPER)
        np.testing.assert_allclose(strict.angles, clamped.angles, rtol=0, atol=1e-12)


def test_unreachable_and_limit_errors_name_the_target() -> None:
    with pytest.raises(UnreachableError, match=r"\(400\.0, 0\.0, 0\.0\) mm is out of reach"):
        ik([0.4, 0.0, 0.0], G)
    with pytest.raises(JointLimitError, match=r"femur = 130\.74°, outside its limits"):
        ik([0.05, -0.2, 0.0], G)
    with pytest.raises(UnreachableError, match=r"target \[1\].*\(1 more"):
        ik([[0.19, 0.12, 0.0], [0.5, 0, 0], [0.6, 0, 0]], G)


def test_clamped_result_says_so() -> None:
    sol = ik([[0.19, 0.12, 0.0], [0.5, 0.0, 0.0], [0.05, -0.2, 0.0]], G, clamp=True)
    assert sol.clamped.tolist() == [False, True, True]
    assert sol.reachable.tolist() == [True, False, True]
    assert sol.any_clamped


@pytest.mark.parametrize(
    ("points", "message"),
    [
        ([0.19, math.nan, 0.0], "y = nan"),
        ([[0.19, 0.12, 0.0], [0.19, 0.12, math.inf]], r"point \(1,\) has z = inf"),
        ([0.19, 0.12], r"shape \(2,\)"),
        (0.19, r"shape \(\)"),
    ],
)
def test_bad_points_are_named(points: object, message: str) -> None:
    with pytest.raises(UsageError, match=message):
        ik(points, G)  # type: ignore[arg-type]


def test_bad_options_are_named() -> None:
    with pytest.raises(UsageError, match="pitch"):
        ik([0.19, 0.12, 0.0], G, pitch=math.pi / 2)
    with pytest.raises(UsageError, match="'heel'"):
        ik([0.19, 0.12, 0.0], G, target="heel")  # type: ignore[arg-type]
    with pytest.raises(UsageError, match=r"shape \(4,\)"):
        fk([0.0, 0.0, 0.0, 0.0], G)
    with pytest.raises(UsageError, match="femur = nan"):
        fk([0.0, 0.0, math.nan, 0.0, 0.0], G)


@pytest.mark.parametrize(("goal", "expected"), TABLE_6_5)
def test_cli_ik_json(
    goal: tuple[int, ...], expected: tuple[float, ...], capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["kin", "ik", "--leg", "0", *map(str, goal), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert list(out) == ["coxa", "trochanter", "femur", "tibia", "tarsus"]
    got = [out["coxa"], out["femur"], out["tibia"], out["tarsus"]]
    np.testing.assert_allclose(got, expected, atol=0.05)


def test_cli_fk_json_and_errors(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["kin", "fk", "--leg", "LM", "0", "0", "1.80", "-92.69", "0.90", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert list(out) == ["x", "y", "z"]
    np.testing.assert_allclose([out["x"], out["y"], out["z"]], [190, 120, 0], atol=0.1)

    assert main(["kin", "ik", "--leg", "0", "400", "0", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert "out of reach" in err
    assert len(err.splitlines()) == 1

    assert main(["kin", "ik", "--leg", "0", "nan", "0", "0"]) == 2
    assert "x = nan" in capsys.readouterr().err

    with pytest.raises(SystemExit) as info:
        main(["kin", "ik", "--leg", "FR", "190", "120", "0"])
    assert info.value.code == 2
    assert "unknown leg 'FR'" in capsys.readouterr().err


def test_cli_ik_pitch_and_clamp(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["kin", "ik", "--leg", "1", "190", "120", "0", "--pitch", "10", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["trochanter"] == pytest.approx(10.0)
    assert main(["kin", "ik", "--leg", "1", "400", "0", "0", "--clamp", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["clamped"] is True


def test_ik_point_is_ik_for_one_target() -> None:
    """The plain-Python one-target IK gives ik's angles, and its errors, for any target."""
    rng = np.random.default_rng(11)
    met = 0
    for _ in range(3000):
        point = rng.uniform([0.05, -0.1, -0.25], [0.35, 0.45, 0.25])
        pitch = 0.0 if rng.random() < 0.5 else float(rng.uniform(-0.6, 0.6))
        target: Target = "contact" if rng.random() < 0.5 else "tarsus"
        try:
            want = ik(point, G, pitch=pitch, target=target).angles
        except KinematicsError as exc:
            with pytest.raises(type(exc)):
                ik_point(tuple(point), G, pitch=pitch, target=target)
            continue
        got = ik_point(tuple(point), G, pitch=pitch, target=target)
        assert np.allclose(got, want, rtol=0, atol=1e-12)
        met += 1
    assert met > 500
