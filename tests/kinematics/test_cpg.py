"""CPG oscillators and their normalised orbits (Grzelczyk et al., 8.4)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from whexar.errors import UsageError
from whexar.kinematics.cpg import (
    OSCILLATORS,
    RK4_STABILITY_LIMIT,
    CpgOrbit,
    cpg_orbit,
    default_step,
    simulate,
    vector_field,
)


def _aligned_difference(a: CpgOrbit, b: CpgOrbit) -> float:
    """Largest normalised difference after the best circular shift of b against a."""
    best = math.inf
    for k in range(a.phase.size):
        dx = np.abs(a.x_norm - np.roll(b.x_norm, k)).max()
        dz = np.abs(a.z_norm - np.roll(b.z_norm, k)).max()
        best = min(best, float(max(dx, dz)))
    return best


@pytest.mark.parametrize("name", OSCILLATORS)
def test_normalised_exactly_to_unit_ranges(name: str) -> None:
    orbit = cpg_orbit(name)
    assert orbit.phase.size == 256
    assert np.allclose(orbit.phase, np.arange(256) / 256)
    assert orbit.x_norm.min() == pytest.approx(-0.5, abs=1e-9)
    assert orbit.x_norm.max() == pytest.approx(0.5, abs=1e-9)
    assert orbit.z_norm.min() == pytest.approx(0.0, abs=1e-9)
    assert orbit.z_norm.max() == pytest.approx(1.0, abs=1e-9)
    # Phase 0 is the posterior extreme position.
    assert orbit.x_norm[0] == pytest.approx(-0.5, abs=1e-6)


@pytest.mark.parametrize("name", OSCILLATORS)
def test_orbit_closes_after_one_period(name: str) -> None:
    orbit = cpg_orbit(name)
    start = (float(orbit.x_raw[0]), float(orbit.z_raw[0]))
    steps = math.ceil(orbit.period / default_step(name))
    _, x, z = simulate(name, start, orbit.period, dt=orbit.period / steps)
    assert x.size == steps + 1
    size = max(np.ptp(orbit.x_raw), np.ptp(orbit.z_raw))
    assert abs(x[-1] - start[0]) <= 1e-6 * size
    assert abs(z[-1] - start[1]) <= 1e-6 * size
    # Half a period later the state is far from the start: the period is not a multiple.
    half = steps // 2
    assert math.hypot(x[half] - start[0], z[half] - start[1]) > 0.1 * size


@pytest.mark.parametrize(
    ("name", "initial"),
    [
        ("hopf", (0.1, 0.0)),
        ("hopf", (4.0, -3.0)),
        ("van_der_pol", (0.2, 3.0)),
        ("stick_slip", (2.0, 0.0)),
        ("stick_slip", (-1.0, -1.0)),
    ],
)
def test_converges_from_other_initial_conditions(name: str, initial: tuple[float, float]) -> None:
    reference = cpg_orbit(name)
    other = cpg_orbit(name, initial=initial)
    assert other.period == pytest.approx(reference.period, rel=1e-7)
    assert _aligned_difference(reference, other) <= 1e-6


def test_stick_slip_step_converged() -> None:
    reference = cpg_orbit("stick_slip")
    finer = cpg_orbit("stick_slip", dt=reference.dt / 2)
    assert finer.period == pytest.approx(reference.period, rel=1e-7)
    assert np.abs(finer.x_norm - reference.x_norm).max() <= 1e-6
    assert np.abs(finer.z_norm - reference.z_norm).max() <= 1e-6
    assert finer.stick_fraction == pytest.approx(reference.stick_fraction, abs=1e-3)


@pytest.mark.parametrize("name", OSCILLATORS)
def test_stance_moves_backwards(name: str) -> None:
    orbit = cpg_orbit(name)
    # Periodic central differences of X against phase.
    dx = np.roll(orbit.x_norm, -1) - np.roll(orbit.x_norm, 1)
    low, high = orbit.z_norm < 0.25, orbit.z_norm > 0.75
    assert low.any()
    assert high.any()
    assert np.all(dx[low] < 0)  # stance: foot moves from +0.5 towards −0.5
    assert np.all(dx[high] > 0)  # swing: forwards
    assert orbit.x_norm[np.argmin(orbit.z_norm)] > -0.5  # the lowest point is not the PEP


def test_stick_phase_is_flat_stance() -> None:
    orbit = cpg_orbit("stick_slip")
    v_dr = 0.5
    assert orbit.x_sign == -1.0
    assert orbit.z_sign == -1.0
    stick = np.abs(v_dr - orbit.z_raw) <= 1e-3  # Ẋ = v_dr: sticking
    idx = np.nonzero(stick)[0]
    assert np.array_equal(idx, np.arange(idx[0], idx[-1] + 1))  # one segment
    assert 0.4 < idx.size / orbit.phase.size < 0.6
    assert np.all(orbit.z_norm[stick] <= 1e-3)  # flat at Z ≈ 0
    # X falls at the constant rate v_dr·T/range per period.
    slope = np.diff(orbit.x_norm[idx]) / np.diff(orbit.phase[idx])
    expected = -v_dr * orbit.period / float(np.ptp(orbit.x_raw))
    assert np.allclose(slope, expected, rtol=2e-3)
    assert orbit.stick_fraction is not None
    assert orbit.stick_fraction == pytest.approx(idx.size / orbit.phase.size, abs=2 / 256)
    assert orbit.natural_duty_factor == pytest.approx(orbit.stick_fraction)
    assert orbit.touchdown == pytest.approx(idx[0] / 256, abs=1 / 256)
    assert orbit.lift_off == pytest.approx((idx[-1] + 1) / 256, abs=1 / 256)


def test_hopf_circle_before_normalisation() -> None:
    orbit = cpg_orbit("hopf")
    mu, omega = 6.0, 2.0
    assert np.allclose(np.hypot(orbit.x_raw, orbit.z_raw), math.sqrt(mu), atol=1e-9)
    assert orbit.period == pytest.approx(2 * math.pi / omega, rel=1e-9)
    # Uniform in time: equal angles between samples.
    angle = np.unwrap(np.arctan2(orbit.z_raw, orbit.x_raw))
    assert np.allclose(np.diff(angle), omega * orbit.period / 256, atol=1e-9)
    assert np.allclose(orbit.x_norm**2 + (orbit.z_norm - 0.5) ** 2, 0.25, atol=1e-9)
    assert orbit.stick_fraction is None
    assert orbit.swing_fraction == pytest.approx(0.5, abs=1e-9)


def _independent_van_der_pol_period(mu: float, omega: float, dt: float) -> float:
    """Mean spacing of upward zero crossings of x, with a separately written RK4."""

    def f(x: float, v: float) -> tuple[float, float]:
        return v, mu * (1 - x * x) * v - omega * omega * x

    x, v, t = 1.0, 0.0, 0.0
    crossings: list[float] = []
    while len(crossings) < 5:
        k1 = f(x, v)
        k2 = f(x + dt / 2 * k1[0], v + dt / 2 * k1[1])
        k3 = f(x + dt / 2 * k2[0], v + dt / 2 * k2[1])
        k4 = f(x + dt * k3[0], v + dt * k3[1])
        xn = x + dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        vn = v + dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        if x < 0 <= xn and t > 10.0:  # after the transient
            crossings.append(t + dt * x / (x - xn))
        x, v, t = xn, vn, t + dt
    return (crossings[-1] - crossings[0]) / (len(crossings) - 1)


def test_van_der_pol_period_independent_estimate() -> None:
    orbit = cpg_orbit("van_der_pol")
    estimate = _independent_van_der_pol_period(6.0, 2.0, orbit.dt / 2)
    assert orbit.period == pytest.approx(estimate, rel=1e-6)
    # μ/ω = 3 is a relaxation oscillator: slower than the harmonic 2π/ω.
    assert orbit.period > 1.3 * math.pi
    # The Rayleigh oscillator's ẋ obeys van der Pol (scaled by 1/√3): same period.
    assert cpg_orbit("rayleigh").period == pytest.approx(orbit.period, rel=1e-6)


def test_stick_slip_vector_field_is_eq_8_15() -> None:
    f = vector_field("stick_slip")
    x, z = 0.3, -0.2
    v_r = 0.5 - z
    friction = 1.2 / (1 + 3 * abs(v_r)) * math.tanh(v_r / 1e-4)
    assert f(x, z) == pytest.approx((z, -0.01 * z - x + friction), rel=1e-15)
    g = vector_field("hopf", mu=1.0, omega=3.0)
    assert g(1.0, 0.0) == pytest.approx((0.0, 3.0))


def test_stiff_step_respects_rk4_stability() -> None:
    dt = default_step("stick_slip")
    slope = 0.01 + 1.2 / 1e-4  # |λ| of the friction mode (8.4.2 parameters)
    assert dt * slope < RK4_STABILITY_LIMIT
    assert dt == pytest.approx(1e-4, rel=1e-3)
    with pytest.raises(UsageError, match="dt"):
        cpg_orbit("stick_slip", dt=3e-4)
    with pytest.raises(UsageError, match="dt"):
        simulate("stick_slip", (0.0, 0.5), 1.0, dt=1e-3)


def test_at_interpolates_periodically() -> None:
    orbit = cpg_orbit("van_der_pol")
    x, z = orbit.at(orbit.phase)
    assert np.allclose(x, orbit.x_norm)
    assert np.allclose(z, orbit.z_norm)
    mid = (orbit.phase[:-1] + orbit.phase[1:]) / 2
    x, _ = orbit.at(mid + 3.0)
    assert np.allclose(x, (orbit.x_norm[:-1] + orbit.x_norm[1:]) / 2)
    x_end, _ = orbit.at(1.0 - 0.5 / 256)
    assert float(x_end) == pytest.approx((orbit.x_norm[-1] + orbit.x_norm[0]) / 2)
    with pytest.raises(UsageError, match="finite"):
        orbit.at([0.1, math.nan])


def test_scaled_to_stride() -> None:
    orbit = cpg_orbit("stick_slip")
    s, h = orbit.scaled(0.06, 0.03)  # Fig. 8.8b: l = 60 mm, h = 30 mm
    assert s.min() == pytest.approx(-0.03)
    assert s.max() == pytest.approx(0.03)
    assert h.min() == pytest.approx(0.0, abs=1e-12)
    assert h.max() == pytest.approx(0.03)
    s_at, _ = orbit.scaled(0.06, 0.03, orbit.phase[:5])
    assert np.allclose(s_at, s[:5])
    with pytest.raises(UsageError, match="stride_length"):
        orbit.scaled(0.0, 0.03)
    with pytest.raises(UsageError, match="stride_height"):
        orbit.scaled(0.06, -0.01)


def test_orbits_are_cached_and_read_only() -> None:
    assert cpg_orbit("hopf") is cpg_orbit("HOPF")
    assert cpg_orbit("hopf", mu=6.0) is cpg_orbit("hopf")
    orbit = cpg_orbit("hopf")
    with pytest.raises(ValueError, match="read-only"):
        orbit.x_norm[0] = 1.0
    assert cpg_orbit("hopf", n_samples=64).phase.size == 64


def test_bad_names_and_parameters() -> None:
    with pytest.raises(UsageError) as info:
        cpg_orbit("duffing")
    for name in OSCILLATORS:
        assert name in str(info.value)
    with pytest.raises(UsageError, match="allowed: mu, omega"):
        cpg_orbit("hopf", v_dr=0.5)
    with pytest.raises(UsageError, match="mu"):
        cpg_orbit("van_der_pol", mu=-1.0)
    with pytest.raises(UsageError, match="epsilon"):
        cpg_orbit("stick_slip", epsilon=math.nan)
    with pytest.raises(UsageError, match="n_samples"):
        cpg_orbit("hopf", n_samples=2)
