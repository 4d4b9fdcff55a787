"""Foot trajectories in the step frame (Diosdado 2014, 3.3–3.5; Grzelczyk et al., 8.4.3)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from whexar._typing import ArrayLike
from whexar.errors import UsageError
from whexar.kinematics.cpg import cpg_orbit
from whexar.kinematics.gait import gait
from whexar.kinematics.trajectory import (
    FootTrajectory,
    SwingTracker,
    adapt_swing,
    half_sine_swing,
    parabolic_swing,
    sample_swing,
    stance,
)

L, H = 0.10, 0.04  # Grzelczyk et al., 8.5: stride length 100 mm, height 40 mm


def test_parabola_matches_diosdado_form() -> None:
    u = np.linspace(0.0, 1.0, 101)
    s, h = parabolic_swing(u, L, H)
    assert np.allclose(s, -L / 2 + L * u, atol=1e-15)
    # Diosdado 2014, eq. 10–11: a = 2√(4H)/L, z = H − (a·y)²/4.
    a = 2 * math.sqrt(4 * H) / L
    assert np.allclose(h, H - (a * s) ** 2 / 4, atol=1e-15)
    assert h[0] == 0.0
    assert h[-1] == 0.0
    assert h[50] == pytest.approx(H, abs=1e-15)
    assert np.all(h >= 0.0)


@given(
    st.floats(0.0, 1.0),
    st.floats(1e-3, 1.0),
    st.floats(0.0, 0.5),
)
def test_parabola_properties(u: float, length: float, height: float) -> None:
    s, h = parabolic_swing(u, length, height)
    assert -length / 2 - 1e-15 <= float(s) <= length / 2 + 1e-15
    assert 0.0 <= float(h) <= height + 1e-15
    assert float(h) == pytest.approx(height * (1 - (2 * float(s) / length) ** 2), abs=1e-12)
    # Diosdado 2014, eq. 12–14: the step length is recovered from any point of the parabola.
    # Heights below a micrometre underflow the recovery (5e-324 squares to 0).
    if height > 1e-6 and 0 < u < 1:
        a = 2 * math.sqrt(4 * height) / length
        h_test = float(h) + (a * float(s)) ** 2 / 4
        assert 2 * math.sqrt(4 * h_test) / a == pytest.approx(length, rel=1e-9)


def test_half_sine() -> None:
    u = np.linspace(0.0, 1.0, 33)
    s, h = half_sine_swing(u, L, H)
    assert np.allclose(s, L * (u - 0.5), atol=1e-15)
    assert np.allclose(h, H * np.sin(np.pi * u), atol=1e-15)
    assert np.all(h >= 0.0)
    assert float(h[16]) == pytest.approx(H)


def test_stance_moves_back_on_the_ground() -> None:
    u = np.linspace(0.0, 1.0, 11)
    s, h = stance(u, L)
    assert np.allclose(s, L / 2 - L * u, atol=1e-15)
    assert np.all(h == 0.0)


def test_vectorised_shapes() -> None:
    u = np.linspace(0, 1, 12).reshape(3, 4)
    for s, h in (parabolic_swing(u, L, H), half_sine_swing(u, L, H), stance(u, L)):
        assert s.shape == (3, 4)
        assert h.shape == (3, 4)


@pytest.mark.parametrize(
    ("u", "length", "height", "match"),
    [
        (0.5, 0.0, H, "step_length"),
        (0.5, -0.1, H, "step_length"),
        (0.5, math.nan, H, "step_length"),
        (0.5, math.inf, H, "step_length"),
        (0.5, L, -0.01, "step_height"),
        (0.5, L, math.nan, "step_height"),
        (-0.01, L, H, "-0.01"),
        (1.01, L, H, "1.01"),
        ([0.2, math.nan], L, H, "nan"),
    ],
)
def test_swing_validation(u: ArrayLike, length: float, height: float, match: str) -> None:
    for fn in (parabolic_swing, half_sine_swing):
        with pytest.raises(UsageError, match=match):
            fn(u, length, height)


def test_stance_validation() -> None:
    with pytest.raises(UsageError, match="step_length"):
        stance(0.5, -1.0)
    with pytest.raises(UsageError, match=r"\[0, 1\]"):
        stance(2.0, L)


@pytest.mark.parametrize("shape", ["parabola", "half_sine"])
@pytest.mark.parametrize("beta", [0.5, 2 / 3, 5 / 6])
def test_foot_trajectory_cycle(shape: str, beta: float) -> None:
    traj = FootTrajectory(L, H, beta, shape)  # type: ignore[arg-type]
    sw = 1 - beta
    s, h = traj.at([0.0, sw / 2, sw, sw + beta / 2, 1.0])
    assert np.allclose(s, [-L / 2, 0.0, L / 2, 0.0, -L / 2], atol=1e-12)
    assert np.allclose(h, [0.0, H, 0.0, 0.0, 0.0], atol=1e-12)
    phases = np.linspace(0, 1, 6001)
    s, h = traj.at(phases)
    in_swing = traj.in_swing(phases)
    assert np.all(h[~in_swing] == 0.0)
    inner = (phases > 1e-9) & (phases < sw - 1e-9)  # away from lift-off and touchdown
    assert np.array_equal(in_swing & inner, inner)
    assert np.all(h[inner] > 0.0)
    assert in_swing[:-1].mean() == pytest.approx(sw, abs=1e-3)
    # Stance at constant speed L/β (per cycle) backwards; continuity everywhere.
    stance_speed = np.diff(s)[(phases[:-1] > sw + 1e-9) & (phases[1:] < 1)] / np.diff(phases)[0]
    assert np.allclose(stance_speed, -L / beta, rtol=1e-9)
    assert np.abs(np.diff(s)).max() <= L / min(beta, sw) / 6000 * 1.0001
    assert np.abs(np.diff(h)).max() <= 4 * H / sw / 6000 * 1.0001  # parabola: dh/du ≤ 4H


@pytest.mark.parametrize("name", ["tripod", "tetrapod", "ripple", "wave"])
def test_foot_trajectory_follows_gait(name: str) -> None:
    g = gait(name)
    traj = FootTrajectory(L, H, g.duty_factor)
    # Include lift-off/touchdown phases in several float spellings.
    phases = np.concatenate(
        [np.linspace(0, 1, 721), [k / 6 for k in range(6)], [k * (1 / 6) for k in range(6)]]
    )
    psi = g.leg_phase(phases)
    _, h = traj.at(psi)
    swinging = g.in_swing(phases)
    assert np.array_equal(traj.in_swing(psi), swinging)
    assert np.all(h[~swinging] == 0.0)
    assert np.all((h > 0).sum(axis=-1) <= 6 - g.min_support_legs())


def test_foot_trajectory_with_hopf_orbit() -> None:
    orbit = cpg_orbit("hopf")
    traj = FootTrajectory(0.06, 0.03, 0.5, orbit)  # Fig. 8.8b: l = 60 mm, h = 30 mm
    s, h = traj.at([0.0, 0.25, 0.5, 0.75])
    # Hopf, X mirrored: lift-off at the back at mid height, top at mid-swing.
    assert np.allclose(s, [-0.03, 0.0, 0.03, 0.0], atol=1e-6)
    assert np.allclose(h, [0.015, 0.03, 0.015, 0.0], atol=1e-6)


def test_foot_trajectory_with_stick_slip_orbit() -> None:
    orbit = cpg_orbit("stick_slip")
    beta = 0.6
    traj = FootTrajectory(L, H, beta, orbit)
    phases = np.linspace(1 - beta + 0.01, 0.99, 200)  # stance, away from the ends
    s, h = traj.at(phases)
    assert np.all(h <= 1e-3 * H)
    speed = np.diff(s) / np.diff(phases)
    assert np.all(speed < 0)
    assert np.ptp(speed) <= 0.02 * abs(speed.mean())  # stick: constant speed
    _, h_swing = traj.at(np.linspace(0.05, 1 - beta - 0.05, 50))
    assert np.all(h_swing > 0.05 * H)


def test_foot_trajectory_validation() -> None:
    with pytest.raises(UsageError, match="duty_factor"):
        FootTrajectory(L, H, 1.0)
    with pytest.raises(UsageError, match="duty_factor"):
        FootTrajectory(L, H, 0.0)
    with pytest.raises(UsageError, match="swing shape"):
        FootTrajectory(L, H, 0.5, "square")  # type: ignore[arg-type]
    with pytest.raises(UsageError, match="step_height"):
        FootTrajectory(L, -H, 0.5)
    with pytest.raises(UsageError, match="phase"):
        FootTrajectory(L, H, 0.5).at(1.5)


def _parabola(n: int = 101) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return sample_swing(n, L, H, "parabola")


def test_flat_ground_completes() -> None:
    for shape in ("parabola", "half_sine"):
        u, s, h = sample_swing(101, L, H, shape)
        result = adapt_swing(u, s, h, lambda x: np.zeros_like(x))
        assert result.outcome == "completed"
        assert result.index == 100
        assert result.contact_u == 1.0
        assert not result.ended_early
        assert result.s.size == 101


def test_obstacle_after_apex_is_early_contact() -> None:
    u, s, h = _parabola()
    step = 0.5 * H
    result = adapt_swing(u, s, h, lambda x: np.where(x > 0.0, step, 0.0))
    # 4H·u(1 − u) = H/2 on the way down at u = (1 + √½)/2.
    u_contact = (1 + math.sqrt(0.5)) / 2
    expected = int(np.nonzero((u > 0.5) & (u >= u_contact - 1e-12))[0][0])
    assert result.outcome == "early_contact"
    assert result.ended_early
    assert result.index == expected
    assert result.contact_u == pytest.approx(u[expected])
    assert result.contact_ground == step
    assert result.u.size == result.s.size == result.h.size == expected + 1
    assert np.array_equal(result.h, h[: expected + 1])


def test_obstacle_on_the_way_up_is_blocked() -> None:
    u, s, h = _parabola()
    wall = 0.9 * H  # higher than the foot at s = −L/4 (0.75 H)
    result = adapt_swing(u, s, h, np.where(s >= -L / 4, wall, 0.0))
    expected = int(np.nonzero(s >= -L / 4)[0][0])
    assert result.outcome == "blocked"
    assert result.ended_early
    assert result.index == expected
    assert result.index < int(np.argmax(h))


def test_hole_gives_no_contact() -> None:
    u, s, h = _parabola()
    result = adapt_swing(u, s, h, np.full_like(s, -0.02))
    assert result.outcome == "no_contact"
    assert result.index is None
    assert result.contact_u is None
    assert not result.ended_early
    assert np.array_equal(result.s, s)


def test_lift_off_sample_is_not_a_contact() -> None:
    u, s, h = _parabola(11)
    ground = np.zeros_like(s)
    ground[-1] = -0.001  # a hole at the nominal touchdown: only the lift-off touches
    assert adapt_swing(u, s, h, ground).outcome == "no_contact"


@given(st.floats(0.01, 0.99), st.floats(-0.45, 0.45))
def test_step_obstacle_classification(height_frac: float, s_frac: float) -> None:
    u, s, h = _parabola(201)
    edge, top = s_frac * L, height_frac * H
    result = adapt_swing(u, s, h, lambda x: np.where(x >= edge, top, 0.0))
    # Independent brute force over the samples.
    hits = [i for i in range(1, 201) if h[i] <= (top if s[i] >= edge else 0.0) + 1e-9]
    first = hits[0]
    assert result.index == first
    if first == 200:
        assert result.outcome == "completed"
    elif u[first] < 0.5:
        assert result.outcome == "blocked"
    else:
        assert result.outcome == "early_contact"


def test_adapt_swing_validation() -> None:
    u, s, h = _parabola(11)
    with pytest.raises(UsageError, match="non-decreasing"):
        adapt_swing(u[::-1], s, h, 0.0 * s)
    with pytest.raises(UsageError, match="shape"):
        adapt_swing(u, s[:-1], h, 0.0 * s)
    with pytest.raises(UsageError, match="ground has shape"):
        adapt_swing(u, s, h, np.zeros(3))
    with pytest.raises(UsageError, match="finite"):
        adapt_swing(u, s, h, np.full_like(s, math.nan))
    with pytest.raises(UsageError, match=r"\[0, 1\]"):
        adapt_swing(u * 2, s, h, 0.0 * s)
    # A callable returning a constant is broadcast.
    assert adapt_swing(u, s, h, lambda x: 0.0).outcome == "completed"


def test_swing_tracker() -> None:
    tracker = SwingTracker()
    assert tracker.step(0.0, True) == "swinging"  # lift-off
    assert tracker.step(0.3, False) == "swinging"
    assert tracker.step(0.7, True) == "early_contact"
    assert tracker.contact_u == 0.7
    assert tracker.step(0.8, False) == "early_contact"  # latched
    tracker.reset()
    assert tracker.step(0.2, True) == "blocked"
    tracker.reset()
    assert tracker.step(0.5, False) == "swinging"
    assert tracker.step(1.0, True) == "completed"
    tracker.reset()
    assert tracker.step(0.9, False) == "swinging"
    assert tracker.step(1.0, False) == "no_contact"
    assert tracker.contact_u is None
    tracker.reset()
    tracker.step(0.5, False)
    with pytest.raises(UsageError, match="decrease"):
        tracker.step(0.4, False)
    with pytest.raises(UsageError, match=r"\[0, 1\]"):
        SwingTracker().step(1.5, False)
    assert SwingTracker(completion_margin=0.05).step(0.97, True) == "completed"


def test_tracker_agrees_with_adapt_swing() -> None:
    u, s, h = _parabola(101)
    ground = np.where(s > 0.2 * L, 0.3 * H, 0.0)
    offline = adapt_swing(u, s, h, ground)
    tracker = SwingTracker(apex_u=float(u[np.argmax(h)]))
    for ui, hi, gi in zip(u, h, ground, strict=True):
        status = tracker.step(float(ui), bool(hi <= gi + 1e-9))
        if status != "swinging":
            break
    assert status == offline.outcome == "early_contact"
    assert tracker.contact_u == offline.contact_u
