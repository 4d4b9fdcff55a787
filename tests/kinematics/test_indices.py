"""Performance indices and the leg load indicator (Žák 2023, eq. 3.7–3.12, 5.19, 6.1–6.5)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from whexar.errors import UsageError
from whexar.kinematics.indices import (
    cost_of_transport,
    cost_of_transport_from_current,
    duty_factor,
    electric_power,
    froude_number,
    froude_number_from_frequency,
    leg_torque_estimate,
    servo_currents,
    stance_current,
)

# Žák 2023, Table 6.7, copied as printed: movement, slope [°], speed [m/s], current without /
# with the trochanter joint [A], CoT without / with. "-" = not measured; the thesis prints the
# first CoT with a decimal comma ("6,05").
TABLE_6_7 = """
tripod  0   0.12  5.22  -     6,05   -
tripod  14  0.12  7.87  6.30  9.12   7.30
tripod  23  0.10  7.83  7.16  10.88  9.95
tripod  32  0.07  -     8.04  -      15.97
wheels  0   0.20  3.47  -     2.41   -
wheels  14  0.20  5.37  4.52  3.73   3.14
wheels  23  0.20  6.29  4.59  4.37   3.19
wheels  32  0.20  7.35  4.80  5.11   3.34
wheels  40  0.15  -     4.72  -      4.37
"""


def table_6_7_cases() -> list[tuple[str, float, float, float]]:
    """(label, speed, current, published CoT) for every filled CoT cell of Table 6.7."""
    cases = []
    for line in TABLE_6_7.strip().splitlines():
        movement, slope, speed, *cells = line.split()
        for column, (current, cot) in (("w/o", cells[0::2]), ("with", cells[1::2])):
            if current != "-":
                label = f"{movement}-{slope}deg-{column}"
                cases.append((label, float(speed), float(current), float(cot.replace(",", "."))))
    return cases


CASES = table_6_7_cases()


def test_table_6_7_has_every_entry() -> None:
    assert len(CASES) == 14  # 7 + 7 filled cells in the two CoT columns


@pytest.mark.parametrize(
    ("speed", "current", "published"), [c[1:] for c in CASES], ids=[c[0] for c in CASES]
)
def test_cost_of_transport_reproduces_table_6_7(
    speed: float, current: float, published: float
) -> None:
    # 6.8.1: m = 8.8 kg, U = 12 V, g = 9.81 m/s²; the table is rounded to 0.01.
    assert cost_of_transport_from_current(current, speed) == pytest.approx(published, abs=0.005)


def test_cost_of_transport_vectorised_over_table_6_7() -> None:
    speed, current, published = np.array([c[1:] for c in CASES]).T
    cot = cost_of_transport_from_current(current, speed)
    assert isinstance(cot, np.ndarray)
    np.testing.assert_allclose(cot, published, atol=0.005)


def test_cost_of_transport_from_power() -> None:
    # eq. 3.11: P = 62.64 W, m = 8.8 kg, v = 0.12 m/s → 62.64 / (8.8 · 9.81 · 0.12)
    assert cost_of_transport(62.64, 8.8, 0.12) == pytest.approx(62.64 / 10.35936)
    assert cost_of_transport(10.0, 1.0, 1.0, g=10.0) == pytest.approx(1.0)


def test_electric_power() -> None:
    assert electric_power(12.0, 5.22) == pytest.approx(62.64)
    np.testing.assert_allclose(electric_power(12.0, [1.0, 2.5]), [12.0, 30.0])


def test_duty_factor() -> None:
    # Tripod: each leg supports for half the 1.6 s period (6.8.1) → β = 0.5, the walk/run border.
    assert duty_factor(0.8, 1.6) == pytest.approx(0.5)
    # Wave gait: one leg of six in swing → β = 5/6.
    assert duty_factor(5.0, 6.0) == pytest.approx(5 / 6)
    np.testing.assert_allclose(duty_factor([0.0, 1.6], 1.6), [0.0, 1.0])


def test_froude_number() -> None:
    # 0.2 m/s on wheels at a 0.15 m hip height: 0.04 / (9.81 · 0.15)
    assert froude_number(0.2, 0.15) == pytest.approx(0.04 / 1.4715)
    # Fr = 1 is the walk/run transition (3.2.3): v = √(g·h).
    assert froude_number(math.sqrt(9.81 * 0.5), 0.5) == pytest.approx(1.0)


def test_froude_number_from_frequency_matches_eq_3_8_with_hf() -> None:
    h, f = 0.15, 1 / 1.6  # tripod period 1.6 s (6.8.1)
    assert froude_number_from_frequency(h, f) == pytest.approx(froude_number(h * f, h))
    assert froude_number_from_frequency(h, f) == pytest.approx(0.15 * 0.390625 / 9.81)


def test_leg_torque_estimate_follows_eq_5_19() -> None:
    # F = I / (L · sin α): 0.5 A on the femur (127 mm, Table 5.2) with the tibia at 30°.
    assert leg_torque_estimate(0.5, 0.127, math.radians(30)) == pytest.approx(0.5 / 0.0635)
    np.testing.assert_allclose(
        leg_torque_estimate([0.5, -0.5], 0.124, [math.pi / 2, -math.pi / 2]),
        [0.5 / 0.124, 0.5 / 0.124],
    )


@pytest.mark.parametrize("angle", [0.0, math.pi, -math.pi, 1e-9])
def test_leg_torque_estimate_singularity_is_an_error(angle: float) -> None:
    with pytest.raises(UsageError, match="singular"):
        leg_torque_estimate(0.5, 0.127, angle)


def test_leg_torque_estimate_singular_element_in_array() -> None:
    with pytest.raises(UsageError, match=r"next_joint_angle = 0\.0 rad"):
        leg_torque_estimate(0.5, 0.127, [0.3, 0.0, 1.0])


def test_servo_currents_mean_absolute_value() -> None:
    # eq. 6.1: mean of |x_i| over the accepted readings.
    samples = np.array([[0.2, -0.4, 0.3, 9.9]])
    valid = np.array([[True, True, True, False]])  # the last reading was corrupted
    np.testing.assert_allclose(servo_currents(samples, valid), [0.3])
    np.testing.assert_allclose(servo_currents(samples), [(0.2 + 0.4 + 0.3 + 9.9) / 4])


def test_stance_current_sums_servos_and_legs() -> None:
    # eq. 6.1–6.3: servo s of leg l reads ±(l + 1)·0.1·(s + 1) A alternately.
    legs, servos, n = 6, 7, 4
    base = 0.1 * np.outer(np.arange(1, legs + 1), np.arange(1, servos + 1))
    signs = np.array([1.0, -1.0, 1.0, -1.0])
    samples = base[:, :, None] * signs[None, None, :]
    expected = 0.1 * sum(range(1, legs + 1)) * sum(range(1, servos + 1))  # 0.1 · 21 · 28
    assert stance_current(samples) == pytest.approx(expected)
    assert samples.shape == (legs, servos, n)


def test_servo_without_accepted_reading_is_rejected() -> None:
    with pytest.raises(UsageError, match="no accepted reading"):
        servo_currents([[0.1, 0.2], [0.3, 0.4]], [[True, True], [False, False]])


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: cost_of_transport(10.0, 8.8, 0.0), "speed"),
        (lambda: cost_of_transport(10.0, -8.8, 0.1), "mass"),
        (lambda: cost_of_transport(-1.0, 8.8, 0.1), "power"),
        (lambda: cost_of_transport_from_current(math.nan, 0.1), "current"),
        (lambda: cost_of_transport_from_current(1.0, 0.1, voltage=0.0), "voltage"),
        (lambda: froude_number(0.2, 0.0), "hip_height"),
        (lambda: froude_number(0.2, 0.1, g=-9.81), "g"),
        (lambda: duty_factor(2.0, 1.6), "support_time"),
        (lambda: duty_factor(0.5, 0.0), "cycle_time"),
        (lambda: leg_torque_estimate(0.5, 0.0, 1.0), "segment_length"),
        (lambda: stance_current(np.ones((6, 7))), "servo_samples"),
    ],
)
def test_non_physical_inputs_are_rejected(call: Callable[[], object], name: str) -> None:
    with pytest.raises(UsageError, match=name):
        call()
