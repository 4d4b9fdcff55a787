"""The thesis's reference figures: the data file, checked at load and against the thesis."""

from __future__ import annotations

import copy
import tomllib
from typing import Any

import pytest

from whexar.campaign import Row
from whexar.campaign.experiments import (
    REFERENCE_PATH,
    SLOPE_KEY,
    TROCHANTER_KEY,
    figures,
    load_reference,
    parse_reference,
    reference,
)
from whexar.errors import ConfigError


def _doc() -> dict[str, Any]:
    """The shipped file as parsed TOML, to be spoiled by a test."""
    with REFERENCE_PATH.open("rb") as f:
        return tomllib.load(f)


def _problems(doc: dict[str, Any]) -> list[str]:
    with pytest.raises(ConfigError) as info:
        parse_reference(doc, "reference.toml")
    assert info.value.source == "reference.toml"
    return [str(p) for p in info.value.problems]


# --------------------------------------------------------------------------- the thesis's figures

# Žák 2023, Table 6.7, typed in again from the thesis: movement, slope, speed, current and
# CoT without / with the trochanter ("-" is None).
TABLE_6_7 = [
    ("tripod", 0, 0.12, 5.22, None, 6.05, None),
    ("tripod", 14, 0.12, 7.87, 6.30, 9.12, 7.30),
    ("tripod", 23, 0.10, 7.83, 7.16, 10.88, 9.95),
    ("tripod", 32, 0.07, None, 8.04, None, 15.97),
    ("wheels", 0, 0.20, 3.47, None, 2.41, None),
    ("wheels", 14, 0.20, 5.37, 4.52, 3.73, 3.14),
    ("wheels", 23, 0.20, 6.29, 4.59, 4.37, 3.19),
    ("wheels", 32, 0.20, 7.35, 4.80, 5.11, 3.34),
    ("wheels", 40, 0.15, None, 4.72, None, 4.37),
]


def test_the_shipped_file_loads_with_the_thesis_figures() -> None:
    ref = load_reference()
    rows = [
        (r.movement, r.slope_deg, r.speed_m_s, r.current_a, r.current_t_a, r.cot, r.cot_t)
        for r in ref.table_6_7.rows
    ]
    assert rows == TABLE_6_7
    # 6.5.1, 6.5.2, 6.8.1: one figure each, typed as the JSON shows them (10.0, not 10).
    single = {f.name: f.thesis for f in ref.figures}
    assert single == {
        "tripod gait on the flat: speed": "0.07–0.12",
        "tripod gait on the flat: period": 1.6,
        "riding straight: time for the 2 m track": 10.0,
        "riding straight: top speed": 0.2,
        "riding straight: direction of travel": 0.0,
        "riding sideways at +45°: direction of travel": 45.0,
        "riding sideways at +45°: time for the 2 m track": 10.0,
        "riding sideways at +45°: top speed": 0.2,
        "riding sideways at -45°: direction of travel": -45.0,
        "riding sideways at -45°: time for the 2 m track": 10.0,
        "riding sideways at -45°: top speed": 0.2,
        "spinning in place: rate": 4.0,
        "circle (2 laps): distance from the start": 0.015,
        # The thesis does not say how its laps ended: this one is shown, not judged.
        "circle (2 laps as the robot counts them): distance from the start": None,
    }
    assert all(isinstance(v, str | float) for v in single.values() if v is not None)
    # 6.7.6 and 6.8.1: the steepest slopes; 6.8.1: more than 23 % saved at 32°.
    steepest = {(s.mode, s.trochanter): s.thesis_deg for s in ref.steepest.slopes}
    assert steepest == {
        ("walk", True): 32,
        ("ride", True): 40,
        ("stand", True): 50,
        ("walk", False): 23,
        ("ride", False): 32,
        ("stand", False): 32,
    }
    # Table 6.6 tried 0…50° in steps: the next inclination, which each did not manage.
    failed = {(s.mode, s.trochanter): s.failed_deg for s in ref.steepest.slopes}
    assert failed == {
        ("walk", True): 40,
        ("ride", True): 50,
        ("stand", True): None,
        ("walk", False): 32,
        ("ride", False): 40,
        ("stand", False): 40,
    }
    assert (ref.table_6_6.saving.slope_deg, ref.table_6_6.saving.thesis_pct) == (32, 23.0)
    assert ref.table_6_6.slopes_deg == (0, 14, 23, 32, 40, 50)
    assert ref is not reference()  # load_reference reads afresh; reference() once
    assert reference() is reference()


def test_every_explanation_named_exists_and_says_something() -> None:
    ref = reference()
    named = {f.why for f in ref.figures} | {ref.steepest.why}
    named |= {s.why for s in ref.steepest.slopes} | {s.sweep_why for s in ref.steepest.slopes}
    named |= {ref.table_6_7.current_why, ref.table_6_7.cot_why, *ref.table_6_7.speed_why.values()}
    named.discard(None)
    assert named == set(ref.why), "an explanation nobody names, or one named and missing"
    assert all(w.higher or w.lower for w in ref.why.values())


# --------------------------------------------------------------------------- a malformed file


@pytest.mark.parametrize(
    ("spoil", "expected"),
    [
        (
            lambda d: d["table_6_7"]["rows"][1].update(current_a="7.87"),
            "table_6_7.rows[1].current_a = '7.87': Input should be a valid number",
        ),
        (
            lambda d: d["table_6_7"]["rows"][0].pop("speed_m_s"),
            "table_6_7.rows[0].speed_m_s = (missing): required key is missing",
        ),
        (
            lambda d: d["figures"][1].update(thesis=True),
            "figures[1].thesis = True: a number, or text where the thesis gives no single number",
        ),
        (
            lambda d: d["figures"][0].pop("source"),
            "figures[0].source = (missing): required key is missing",
        ),
        (
            lambda d: d["steepest"]["slopes"][0].update(thesis_deg="32°"),
            "steepest.slopes[0].thesis_deg = '32°': a number",
        ),
        (lambda d: d["rules"].pop("max_slide_m"), "rules.max_slide_m = (missing)"),
        (lambda d: d["figures"][2].update(tolerance=-0.1), "figures[2].tolerance = -0.1:"),
        (
            lambda d: d["figures"][2].update(thesis_s=10.0),
            "figures[2].thesis_s = 10.0: unknown key",
        ),
        (
            lambda d: d["figures"][1].update(why="periods"),
            "figures[1].why = 'periods': the name of an explanation of [why]: period, track",
        ),
        (
            lambda d: d["table_6_7"]["speed_why"].pop("wheels"),
            "table_6_7.rows[4].movement = 'wheels': a movement of table_6_7.speed_why: tripod",
        ),
        (
            lambda d: d["table_6_6"]["saving"].update(lower="{one:.2f} against {two}"),
            "table_6_6.saving.lower = '{one:.2f} against {two}': a note quoting only {one}, "
            "{three} (found {two})",
        ),
        (
            lambda d: d["table_6_6"].update(labels=["stance-1", "stance-2"]),
            "table_6_6.labels[2] = (missing)",
        ),
        (
            lambda d: d["steepest"]["slopes"][1].update(mode="walk"),
            "steepest.slopes[1].mode = 'walk': a mode and trochanter no other slope has",
        ),
        (
            lambda d: d["steepest"]["slopes"][0].update(failed_deg=32),
            "steepest.slopes[0].failed_deg = 32: above thesis_deg (32)",
        ),
        (
            lambda d: d["steepest"]["slopes"][2].update(sweep_why="fixed_stance"),
            "steepest.slopes[2].sweep_why = 'fixed_stance': the name of an explanation of [why]",
        ),
        (
            lambda d: d["steepest"].update(sweep_note="the {label} runs"),
            "steepest.sweep_note = 'the {label} runs': a note quoting only {runs}",
        ),
        (
            lambda d: d["steepest"]["slopes"][0].update(why="steepest_walking"),
            "steepest.slopes[0].why = 'steepest_walking': the name of an explanation of [why]",
        ),
    ],
)
def test_a_malformed_file_names_the_key_the_value_and_what_is_allowed(
    spoil: Any, expected: str
) -> None:
    doc = _doc()
    spoil(doc)
    found = _problems(doc)
    assert any(p.startswith(expected) for p in found), found


def test_every_problem_is_listed_at_once() -> None:
    doc = _doc()
    doc["table_6_7"]["rows"][0]["cot"] = "6,05"  # the thesis's own decimal comma
    del doc["steepest"]["source"]
    found = _problems(doc)
    assert len(found) == 2, found


def test_a_file_that_is_no_toml_names_its_line(tmp_path: Any) -> None:
    bad = tmp_path / "reference.toml"
    bad.write_text("tolerance = 0.15\n[rules\n")
    with pytest.raises(ConfigError) as info:
        load_reference(bad)
    assert str(info.value.problems[0]).startswith("line 2")


# --------------------------------------------------------------------------- the output follows


def test_the_table_follows_the_file() -> None:
    doc = copy.deepcopy(_doc())
    doc["figures"][1]["thesis"] = 1.2
    doc["why"]["period"]["higher"] = "A longer step here."
    doc["table_6_7"]["rows"][0]["current_a"] = 9.99
    doc["rules"]["min_progress_fraction"] = 0.5
    ref = parse_reference(doc)
    tripod = Row(
        "0000",
        "tripod",
        {
            "label": "tripod",
            SLOPE_KEY: 0,
            TROCHANTER_KEY: False,
            "commands": [{"t": 3.0, "gait": "tripod", "vx_m_s": 0.12}],
        },
        {
            "uphill_speed_mps": 0.05,  # 42 % of the commanded 0.12 m/s
            "fell": False,
            "max_heading_change_deg": 1.0,
            "gait_period_s": 1.6,
            "total_current_a": 6.0,
        },
        "h",
        "ok",
    )
    shipped = {f.name: f for f in figures([tripod])}
    changed = {f.name: f for f in figures([tripod], ref)}
    period = "tripod gait on the flat: period"
    assert (shipped[period].thesis, shipped[period].note) == (1.6, "")
    assert (changed[period].thesis, changed[period].note) == (1.2, "A longer step here.")
    current = "Table 6.7 tripod 0°, without trochanter: total current"
    assert (shipped[current].thesis, changed[current].thesis) == (5.22, 9.99)
    # The rules: 42 % of the commanded speed is climbing at a quarter, not at a half.
    speed = "tripod gait on the flat: speed"
    assert shipped[speed].note == ""
    assert changed[speed].note == "Did not climb: +0.050 m/s up the plane."
