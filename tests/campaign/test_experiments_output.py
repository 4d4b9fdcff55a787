"""The experiments' table, JSON and report, from fixed rows: the same, byte for byte.

``golden/<set>/rows.jsonl`` holds one made-up row per run of the campaign (one
set mostly failing — falls, slides, turns, failed and missing runs; one mostly
passing; one where every slope passes), so every branch of the notes is taken; and
``seeds``, the mostly passing set over three seeds of the spread of real parts (its
numbers scaled by 0.97, 1 and 1.04, one seed's circle failed), for the medians and
their min–max.
The other files are what ``whexar sim --experiments`` prints for them (the
table, ``--json``) and the report it writes. They were written before the
thesis's figures moved from code into their data file; since, the report's
sentence naming where the code and the data live has changed, and the table's
summary (``agreement``: the median deviation, the rows more than 2× off, the
ranges missed) was added to all three outputs, and ``--json``'s ``config`` (the robot
configuration given with ``--config``; ``null`` here).

When an output is meant to change, rewrite them and review the diff:
``python tests/campaign/test_experiments_output.py``.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from whexar.campaign import Row
from whexar.campaign.experiments import figures, json_document, report_markdown, table_text

GOLDEN = Path(__file__).resolve().parent / "golden"
SETS = ("rough", "good", "perfect", "seeds")


def _rows(name: str) -> list[Row]:
    lines = (GOLDEN / name / "rows.jsonl").read_text().splitlines()
    return [Row.from_json(json.loads(line)) for line in lines]


def _outputs(name: str) -> dict[str, str]:
    """What the command prints and writes for the set's rows, by the golden file's name."""
    rows = _rows(name)
    found = figures(rows)
    doc = json_document(found)
    return {
        # As `--json` prints it, indented to keep the file's diffs readable: the text, not
        # the parsed values, is compared, so 10.0 against 10 would show.
        "figures.json": json.dumps(doc, indent=1) + "\n",
        "table.txt": table_text(found) + "\n",
        "experiments.md": report_markdown(found, rows),
    }


@pytest.mark.parametrize("name", SETS)
def test_the_table_json_and_report_are_unchanged_for_the_same_rows(name: str) -> None:
    for file, text in _outputs(name).items():
        assert text == (GOLDEN / name / file).read_text(), f"golden/{name}/{file} differs"


def test_a_configuration_given_is_named_in_the_json_and_the_report() -> None:
    rows = _rows("good")
    found = figures(rows)
    assert json_document(found, "stiff.toml")["config"] == "stiff.toml"
    report = report_markdown(found, rows, config="stiff.toml")
    assert "Robot configuration: `stiff.toml` (`--config`)" in report
    assert "Robot configuration" not in report_markdown(found, rows)


def test_the_rows_take_every_kind_of_note() -> None:
    notes = " ".join(
        f.note for name in SETS for f in figures(_rows(name)) if f.note
    )  # the branches a change could silently drop
    for phrase in (
        "The robot fell (tilted past 60°) at",
        "Did not climb: it turned",
        "m/s up the plane.",
        "Slid ",
        "run failed: timed out",
        "no such run in the campaign",
        "no value: the run failed",
        "Median of 3 runs:",
        "The six coxa servos draw",
        "It draws",
        "the coordinator allows ±20°",
        "The thesis has no value here.",
        "The current is the supply's",  # a reason: higher
        "The motor model counts only",  # a reason: lower
    ):
        assert phrase in notes, phrase


if __name__ == "__main__":
    for name in SETS:
        for file, text in _outputs(name).items():
            (GOLDEN / name / file).write_text(text)
