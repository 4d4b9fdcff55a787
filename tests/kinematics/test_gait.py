"""Gait phase tables (Žák 2023, 3.2.1, Fig. 3.3; 5.4, Table 5.9)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from whexar.errors import UsageError
from whexar.kinematics.gait import GAIT_RANKING, GAITS, Gait, gait, stability_rank
from whexar.robot import LEG_NAMES

# Legs on the ground at every instant, from the thesis' description of each gait.
EXPECTED_SUPPORT = {"tripod": 3, "tetrapod": 4, "ripple": 4, "wave": 5}
EXPECTED_DUTY = {"tripod": 1 / 2, "tetrapod": 2 / 3, "ripple": 2 / 3, "wave": 5 / 6}


def _dense_phases() -> np.ndarray:
    # A grid plus the event phases written in several float spellings, to catch rounding at
    # the boundaries between one leg's touchdown and the next one's lift-off.
    grid = np.arange(7200) / 7200
    sixths = np.array([k / 6 for k in range(7)] + [k * (1 / 6) for k in range(7)])
    thirds = np.array([1 - 2 / 3, 2 * (1 / 3), 1 / 3 + 1 / 3, 0.5 + 1 / 6, 1 - 1 / 6])
    return np.concatenate([grid, sixths, thirds, grid + 3.0, sixths - 2.0])


def test_ranking_follows_table_5_9() -> None:
    assert GAIT_RANKING == ("wheels", "tripod", "tetrapod", "ripple", "wave")
    assert stability_rank("wheels") == 0
    ranks = [GAITS[name].stability_rank for name in GAIT_RANKING[1:]]
    assert ranks == [1, 2, 3, 4]
    assert [stability_rank(name) for name in GAIT_RANKING] == [0, 1, 2, 3, 4]
    # More stable gaits keep more legs on the ground (or as many).
    supports = [GAITS[name].min_support_legs() for name in GAIT_RANKING[1:]]
    assert supports == sorted(supports)


@pytest.mark.parametrize("name", list(EXPECTED_SUPPORT))
def test_legs_on_ground_constant_over_cycle(name: str) -> None:
    g = gait(name)
    on_ground = g.support_set(_dense_phases()).sum(axis=-1)
    assert on_ground.min() == EXPECTED_SUPPORT[name]
    assert on_ground.max() == EXPECTED_SUPPORT[name]
    assert g.min_support_legs() == EXPECTED_SUPPORT[name]
    assert g.max_swing_legs() == 6 - EXPECTED_SUPPORT[name]


@pytest.mark.parametrize("name", list(EXPECTED_SUPPORT))
def test_each_leg_swings_for_one_minus_beta(name: str) -> None:
    g = gait(name)
    assert g.duty_factor == pytest.approx(EXPECTED_DUTY[name], abs=1e-15)
    assert g.swing_fraction == pytest.approx(1 - EXPECTED_DUTY[name], abs=1e-15)
    n = 600  # divisible by 6: boundaries fall on grid points
    swing = g.in_swing(np.arange(n) / n)
    expected = round(n * (1 - EXPECTED_DUTY[name]))
    assert swing.sum(axis=0).tolist() == [expected] * 6


@pytest.mark.parametrize("name", list(EXPECTED_SUPPORT))
def test_swing_starts_at_offset_and_lasts_one_minus_beta(name: str) -> None:
    g = gait(name)
    d = 1e-6
    for leg in LEG_NAMES:
        col = LEG_NAMES.index(leg)
        start = g.offset(leg)
        end = start + 1 - EXPECTED_DUTY[name]
        assert not g.in_swing(start - d)[col]
        assert g.in_swing(start)[col]
        assert g.in_swing(end - d)[col]
        assert not g.in_swing(end + d)[col]
        assert g.leg_phase(start)[col] == 0.0


@pytest.mark.parametrize("name", list(EXPECTED_SUPPORT))
def test_groups_match_offsets(name: str) -> None:
    g = gait(name)
    swing = g.in_swing(np.arange(1200) / 1200)
    members = [leg for group in g.groups for leg in group]
    assert sorted(members) == sorted(LEG_NAMES)
    for group in g.groups:
        cols = [LEG_NAMES.index(leg) for leg in group]
        for col in cols[1:]:
            assert np.array_equal(swing[:, col], swing[:, cols[0]])
    firsts = [LEG_NAMES.index(group[0]) for group in g.groups]
    for i, a in enumerate(firsts):
        for b in firsts[i + 1 :]:
            assert not np.array_equal(swing[:, a], swing[:, b])


def test_tripod_groups() -> None:
    g = gait("tripod")
    assert {frozenset(group) for group in g.groups} == {
        frozenset({"RF", "LM", "RR"}),
        frozenset({"LF", "RM", "LR"}),
    }
    first = set(g.swing_legs(0.25))
    second = set(g.swing_legs(0.75))
    assert len(first) == 3
    assert first | second == set(LEG_NAMES)
    assert first & second == set()
    assert set(g.support_legs(0.25)) == second


def test_tetrapod_pairs_and_waves() -> None:
    g = gait("tetrapod")
    assert {frozenset(group) for group in g.groups} == {
        frozenset({"RR", "LM"}),
        frozenset({"RM", "LF"}),
        frozenset({"RF", "LR"}),
    }
    for pair, phase in ((("RR", "LM"), 1 / 6), (("RM", "LF"), 0.5), (("RF", "LR"), 5 / 6)):
        assert set(g.swing_legs(phase)) == set(pair)
    # Back to front on the right side.
    assert g.offset("RR") < g.offset("RM") < g.offset("RF")


def test_ripple_next_leg_starts_at_mid_swing() -> None:
    g = gait("ripple")
    order = sorted(LEG_NAMES, key=g.offset)
    assert order == ["RR", "LF", "RM", "LR", "RF", "LM"]
    starts = [g.offset(leg) for leg in order]
    assert np.allclose(np.diff([*starts, 1.0]), 1 / 6, atol=1e-12)
    half_swing = g.swing_fraction / 2
    for previous, leg in zip(order, order[1:] + order[:1], strict=True):
        phase = g.offset(leg)
        swinging = set(g.swing_legs(phase))
        assert swinging == {previous, leg}
        assert g.leg_phase(phase)[LEG_NAMES.index(previous)] == pytest.approx(half_swing)
    # Each side is a back-to-front wave and the sides are half a cycle apart.
    for right, left in (("RR", "LR"), ("RM", "LM"), ("RF", "LF")):
        assert (g.offset(left) - g.offset(right)) % 1 == pytest.approx(0.5)


def test_wave_one_leg_at_a_time_back_to_front() -> None:
    g = gait("wave")
    order = [g.swing_legs((k + 0.5) / 6) for k in range(6)]
    assert order == [("RR",), ("RM",), ("RF",), ("LR",), ("LM",), ("LF",)]


def test_leg_phase_shape_and_wrap() -> None:
    g = gait("ripple")
    p = np.linspace(-1.3, 2.7, 12).reshape(3, 4)
    psi = g.leg_phase(p)
    assert psi.shape == (3, 4, 6)
    assert np.all((psi >= 0) & (psi < 1))
    assert np.allclose(psi, g.leg_phase(p + 5.0), atol=1e-12)
    expected = np.mod(p[..., None] - np.array(g.offsets), 1.0)
    assert np.allclose(psi, expected, atol=1e-12)
    assert g.in_swing(0.2).shape == (6,)


@given(st.floats(min_value=-100.0, max_value=100.0, allow_nan=False))
def test_swing_count_any_phase(phase: float) -> None:
    for name, support in EXPECTED_SUPPORT.items():
        assert int(gait(name).support_set(phase).sum()) == support


def test_unknown_gait_names_allowed_ones() -> None:
    with pytest.raises(UsageError) as info:
        gait("gallop")
    message = str(info.value)
    assert "gallop" in message
    for name in ("tripod", "tetrapod", "ripple", "wave"):
        assert name in message
    with pytest.raises(UsageError, match="wheels"):
        gait("wheels")
    with pytest.raises(ValueError, match="allowed"):
        stability_rank("trot")
    assert gait(" Tripod ") is GAITS["tripod"]


@pytest.mark.parametrize("bad", [math.nan, math.inf, [0.1, math.nan]])
def test_phase_must_be_finite(bad: object) -> None:
    with pytest.raises(UsageError, match="finite"):
        gait("wave").in_swing(bad)  # type: ignore[arg-type]


def test_gait_validation() -> None:
    groups = (("RF", "LM", "RR"), ("LF", "RM", "LR"))
    offsets = (0.0, 0.5, 0.5, 0.0, 0.0, 0.5)
    Gait("ok", 0.5, offsets, groups, 1)
    with pytest.raises(UsageError, match="duty_factor"):
        Gait("bad", 1.0, offsets, groups, 1)
    with pytest.raises(UsageError, match="exactly once"):
        Gait("bad", 0.5, offsets, (("RF", "LM"), ("LF", "RM", "LR")), 1)
    with pytest.raises(UsageError, match="must be equal"):
        Gait("bad", 0.5, (0.1, 0.5, 0.5, 0.0, 0.0, 0.5), groups, 1)
    with pytest.raises(UsageError, match="offset of RF"):
        Gait("bad", 0.5, (1.0, 0.5, 0.5, 0.0, 0.0, 0.5), (("RF",), *groups[1:], ("LM", "RR")), 1)
