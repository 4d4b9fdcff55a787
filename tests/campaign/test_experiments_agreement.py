"""The experiments' table summed up: the median deviation, the rows far off, the ranges."""

from __future__ import annotations

import math

import pytest

from whexar.campaign.experiments import Figure, agreement
from whexar.campaign.experiments.agreement import bounds, compare
from whexar.campaign.experiments.report import agreement_lines


def _f(name: str, thesis: float | str | None, sim: float | str | None) -> Figure:
    return Figure(name=name, unit="m/s", thesis=thesis, sim=sim)


@pytest.mark.parametrize(
    ("text", "span"),
    [
        ("0.07–0.12", (0.07, 0.12)),
        ("32-40", (32.0, 40.0)),
        ("≥ 50", (50.0, math.inf)),
        (">23", (23.0, math.inf)),
        ("40–32", None),  # upside down: no range
        ("about 5", None),
    ],
)
def test_a_thesis_text_reads_as_its_range_or_bound(
    text: str, span: tuple[float, float] | None
) -> None:
    assert bounds(text) == span


def test_a_number_is_compared_by_its_relative_deviation_and_its_ratio() -> None:
    c = compare(_f("speed", 0.10, 0.04))
    assert c is not None
    assert c.deviation == pytest.approx(0.6)
    assert c.ratio == pytest.approx(0.4)
    assert c.far
    near = compare(_f("speed", 0.10, 0.19))
    assert near is not None
    assert not near.far  # 1.9×: within ½ … 2
    wrong_sign = compare(_f("speed", 0.10, -0.01))
    assert wrong_sign is not None
    assert wrong_sign.far


def test_a_range_is_met_inside_and_missed_by_the_distance_to_its_nearer_end() -> None:
    inside = compare(_f("slope", "32–40", 36.6))
    assert inside is not None
    assert (inside.deviation, inside.ratio) == (0.0, 1.0)
    below = compare(_f("slope", "23–32", 19.9))
    assert below is not None
    assert below.deviation == pytest.approx((23 - 19.9) / 23)
    above = compare(_f("slope", "23–32", 80.0))
    assert above is not None
    assert above.ratio == pytest.approx(2.5)
    assert above.far
    bound = compare(_f("slope", "≥ 50", 46.0))
    assert bound is not None
    assert bound.deviation == pytest.approx(0.08)


def test_nothing_is_compared_without_two_numbers_or_against_a_zero() -> None:
    assert compare(_f("direction", 0, 0.05)) is None  # no relative deviation from 0
    assert compare(_f("x", None, 1.0)) is None
    assert compare(_f("x", 1.0, None)) is None
    assert compare(_f("x", 1.0, "not simulated")) is None
    assert compare(_f("x", "kept its direction", 1.0)) is None


def test_the_table_is_summed_up_in_its_median_its_far_rows_and_its_ranges() -> None:
    found = [
        _f("a", 1.0, 1.1),  # 10 %
        _f("b", 1.0, 0.8),  # 20 %
        _f("c", 2.0, 5.0),  # 150 %, far
        _f("d", 0, 0.3),  # left out
        _f("e", None, 3.0),  # no thesis figure: left out
        _f("f", "32–40", 36.0),  # inside
        _f("g", "≥ 50", 46.0),  # outside, 8 %
        _f("h", 0.5, None),  # no number from the simulation
    ]
    a = agreement(found)
    assert [c.figure.name for c in a.numbers] == ["a", "b", "c"]
    assert a.median_deviation == pytest.approx(0.2)
    assert [c.figure.name for c in a.far_off] == ["c"]
    assert [c.figure.name for c in a.outside] == ["g"]
    assert [f.name for f in a.without_value] == ["h"]
    doc = a.to_json()
    assert (doc["numbers"], doc["ranges"], doc["ranges_inside"]) == (3, 2, 1)
    assert doc["far_off"][0]["ratio"] == pytest.approx(2.5)
    lines = agreement_lines(a, bullet="- ")
    assert lines[0].startswith("- 3 figures with one thesis number")
    assert lines[0].endswith("median deviation 20.0 %.")
    assert "  - c: 5 against 2 m/s (×2.5)" in lines
    assert "  - g: 46 against ≥ 50 m/s (8 % off)" in lines
    assert "  - h" in lines


def test_an_empty_table_has_no_median() -> None:
    a = agreement([])
    assert a.median_deviation is None
    assert agreement_lines(a)[0].endswith("none.")


def test_a_figure_measured_a_second_way_is_named_apart_and_never_counted() -> None:
    board = _f("steepest", 32, 36.6)  # 14 %
    planes = Figure(name="steepest: planes", unit="°", thesis=32, sim=32, counted=False)
    far = Figure(name="stood: planes", unit="°", thesis=50, sim=20, counted=False)  # ×0.4
    none = Figure(name="ridden: planes", unit="°", thesis=40, sim=None, counted=False)
    a = agreement([board, planes, far, none])
    assert [c.figure.name for c in a.numbers] == ["steepest"]
    assert a.median_deviation == pytest.approx(0.1437, abs=1e-4)
    assert a.far_off == ()  # the second way's far row is not among them
    assert a.without_value == ()
    assert [c.figure.name for c in a.second] == ["steepest: planes", "stood: planes"]
    assert [c["name"] for c in a.to_json()["second"]] == ["steepest: planes", "stood: planes"]
    lines = agreement_lines(a)
    assert "2 measured a second way, not counted above: 1 equal to the thesis's; the others:" in (
        lines
    )
    assert "  stood: planes: 20 against 50° (60 % off)" in lines
