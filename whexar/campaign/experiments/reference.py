"""The thesis's reference figures and our explanations, read from their data file.

Theory of operation
-------------------
``config/campaigns/reference/experiments.toml`` holds what the thesis measured
(Žák 2023, 6.4–6.8) and what we believe explains each difference; this module
validates it into frozen models (:class:`Reference`), the way every other file
of the project is validated (:mod:`whexar.runtime.schema`): strict keys and
types, then the relations (an explanation named by a figure exists, every
movement of Table 6.7 has its speed's explanation, a note quotes only the
numbers it is given), every problem listed at once with its key path, the
value found and what is allowed (:class:`~whexar.errors.ConfigError`).

Nothing here computes: :mod:`whexar.campaign.experiments.figures` sets these
figures beside the campaign's rows, :mod:`~whexar.campaign.experiments.report`
and :mod:`~whexar.campaign.experiments.plots` show them.

A thesis figure keeps the type it is written with (``10.0`` a float, ``32`` an
int): the JSON of ``whexar sim --experiments --json`` shows it as written.
"""

from __future__ import annotations

import functools
import math
import string
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, Final, Literal

from pydantic import AfterValidator, Field, PlainValidator, ValidationError

from whexar.errors import ConfigError, Problem
from whexar.runtime.schema import CheckedSection, Section, problem_from_error, read_toml

REFERENCE_PATH: Final = (
    Path(__file__).resolve().parents[3] / "config" / "campaigns" / "reference" / "experiments.toml"
)
"""The shipped data file, beside the campaign ``config/campaigns/experiments.toml``."""


def _thesis_value(value: object) -> int | float | str:
    """A thesis figure: a finite number (int or float, kept as written) or non-empty text."""
    if isinstance(value, bool) or not isinstance(value, int | float | str):
        raise ValueError("a number, or text where the thesis gives no single number")
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError("a finite number")
    if isinstance(value, str) and not value.strip():
        raise ValueError("a non-empty text")
    return value


def _number(value: object) -> int | float:
    """A thesis figure that must be a number (int or float, kept as written)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError("a number")
    if not math.isfinite(value):
        raise ValueError("a finite number")
    return value


ThesisValue = Annotated[int | float | str, PlainValidator(_thesis_value)]
"""A figure as the thesis gives it: a number, or text such as a range (``"0.07–0.12"``)."""
ThesisNumber = Annotated[int | float, PlainValidator(_number)]
# Strict: a number written as text ("7.87") or a bool is a mistake in a file of figures, not
# something to convert (an int is taken as a float where a float is wanted).
Finite = Annotated[float, Field(strict=True, allow_inf_nan=False)]
Positive = Annotated[float, Field(strict=True, gt=0, allow_inf_nan=False)]
Tolerance = Annotated[float, Field(strict=True, ge=0, allow_inf_nan=False)]
Slope = Annotated[int, Field(strict=True, ge=0, le=90)]
Flag = Annotated[bool, Field(strict=True)]
Label = Annotated[str, Field(min_length=1)]


def _template(*names: str) -> Callable[[str], str]:
    """A check that a note quotes only ``names`` (``{one:.2f}``), each with a valid format."""

    def check(text: str) -> str:
        fields = [f for _, f, _, _ in string.Formatter().parse(text) if f is not None]
        unknown = [f for f in fields if f not in names]
        if unknown:
            allowed = ", ".join(f"{{{n}}}" for n in names)
            raise ValueError(f"a note quoting only {allowed} (found {{{unknown[0]}}})")
        try:
            text.format(**dict.fromkeys(names, 1.0))
        except (ValueError, IndexError) as exc:
            raise ValueError(f"a note whose {{…}} format numbers: {exc}") from None
        return text

    return check


CompareNote = Annotated[str, AfterValidator(_template("this", "other"))]
SavingNote = Annotated[str, AfterValidator(_template("one", "three"))]
PitchNote = Annotated[str, AfterValidator(_template("slope", "limit"))]
LimitNote = Annotated[str, AfterValidator(_template("limit"))]
SweepNote = Annotated[str, AfterValidator(_template("runs"))]


class Why(Section):
    """Our explanation of a difference, by its direction: the sim's figure higher or lower."""

    higher: str = ""
    lower: str = ""


class Rules(Section):
    """When a run made it up the plane or held its stance (see :mod:`.figures`)."""

    min_progress_fraction: Annotated[float, Field(strict=True, gt=0, le=1, allow_inf_nan=False)]
    """A movement made it at no less than this share of its commanded speed …"""
    max_heading_change_deg: Positive
    """… and turned no more than this (degrees) in its window."""
    max_slide_m: Positive
    """A static stance held when its body slid no more than this (m) in its window."""


class RunRef(Section):
    """Which of the campaign's runs a figure reads: by label, slope and trochanter."""

    label: Label
    slope_deg: Finite = 0.0
    trochanter: Flag | None = None
    """``None``: whichever (the first run of the label and slope)."""


class Compare(Section):
    """A sentence setting a metric of the figure's run beside that of another run."""

    run: RunRef
    metric: Label
    note: CompareNote


class Single(Section):
    """One figure of the thesis: a metric of one run of the campaign beside it."""

    name: Label
    unit: str = ""
    thesis: ThesisValue | None = None
    source: Label
    run: RunRef
    metric: Label
    why: str | None = None
    """The name of an explanation of ``[why]`` (none: no explanation needed)."""
    tolerance: Tolerance | None = None
    """Relative; none: the file's ``tolerance``."""
    note: str = ""
    outcome: Flag = False
    """Add why the run did not make it (fell, slid back, turned away), if it did not."""
    compare: Compare | None = None


class TableRow(Section):
    """One row of Table 6.7: speed (m/s), current (A) and CoT, without/with trochanter."""

    movement: Label
    slope_deg: Slope
    speed_m_s: Positive
    current_a: Finite | None = None
    current_t_a: Finite | None = None
    cot: Finite | None = None
    cot_t: Finite | None = None

    def current(self, trochanter: bool) -> float | None:
        """The total current, without or with the trochanter (``None``: the thesis's "-")."""
        return self.current_t_a if trochanter else self.current_a

    def cost(self, trochanter: bool) -> float | None:
        """The cost of transport, without or with the trochanter."""
        return self.cot_t if trochanter else self.cot


class Table67(Section):
    """Table 6.7: the movements on slopes, three figures each, without and with trochanter."""

    speed_source: Label
    current_source: Label
    cot_source: Label
    speed_why: dict[str, str]
    """The explanation of each movement's speed, by movement."""
    current_why: str
    cot_why: str
    missing: str = ""
    """The note of a figure the thesis gives no value for."""
    rows: tuple[TableRow, ...] = Field(min_length=1)

    @property
    def movements(self) -> tuple[str, ...]:
        """The movements of the table, in its order."""
        return tuple(dict.fromkeys(r.movement for r in self.rows))


class Saving(Section):
    """6.8.1: stance No. 3 saves more than ``thesis_pct`` % of No. 1's current on a slope."""

    slope_deg: Finite
    thesis_pct: Finite
    source: Label
    lower: SavingNote = ""
    """When less is saved: quoting the six coxa servos' current in No. 1 and No. 3."""


class Joints(Section):
    """Fig. 6.8: the current per joint of some stances on some slopes."""

    slopes_deg: tuple[Finite, ...] = Field(min_length=1)
    stances: tuple[Literal[1, 2, 3], ...] = Field(min_length=1)


class Table66(Section):
    """Table 6.6 and Fig. 6.7a: the static stances No. 1–3 on the slopes."""

    source: Label
    slopes_deg: tuple[Slope, ...] = Field(min_length=1)
    labels: tuple[Label, Label, Label]
    """The labels of the runs of stances No. 1, 2 and 3."""
    note: str = ""
    not_simulated: PitchNote
    """Why stance No. 2 is not simulated beyond the coordinator's body pitch ``limit``."""
    trochanter_limit: LimitNote
    """That the trochanters follow the pitch only up to ``limit`` degrees."""
    saving: Saving
    joints: Joints

    def label(self, number: int) -> str:
        """The label of stance No. ``number`` (1–3)."""
        return self.labels[number - 1]


class SteepestSlope(Section):
    """One of 6.7.6's steepest slopes: walked, ridden or stood on, with or without trochanter."""

    mode: Literal["walk", "ride", "stand"]
    trochanter: Flag
    label: Label
    """The campaign's runs for it: a tilting board's (their ``tilt_limit_deg``, the board's
    angle where the run failed, as the thesis found it), or a sweep of fixed slopes."""
    thesis_deg: ThesisNumber
    failed_deg: ThesisNumber | None = None
    """The next inclination of Table 6.6 (0, 14, 23, 32, 40, 50°) that the thesis's robot
    did not manage, ``None`` when it managed the steepest tested: the thesis's limit lies
    from ``thesis_deg`` up to this."""
    why: str | None = None
    """The explanation of [why] for this slope; ``None``: the section's."""
    sweep: Label | None = None
    """The campaign's runs on Table 6.6's fixed inclinations for the same mode (``tripod``,
    ``wheels``, a stance's): the last inclination they managed, with every one below it,
    is the figure the thesis's protocol gives (6.7.6: "different inclinations of the board
    were sequentially set"). A second measurement beside ``label``'s, which the agreement
    does not count; ``None``: none."""
    sweep_why: str | None = None
    """The explanation of [why] for the row from :attr:`sweep`; ``None``: none."""


class Steepest(Section):
    """6.7.6, 6.8.1: the steepest slopes, against those the simulated sweep passed."""

    source: Label
    tolerance: Tolerance | None = None
    why: str | None = None
    sweep_note: SweepNote = ""
    """The note of every row from the fixed inclinations (:attr:`SteepestSlope.sweep`),
    quoting ``{runs}``, their runs' label."""
    slopes: tuple[SteepestSlope, ...] = Field(min_length=1)

    def thesis(self, mode: str, trochanter: bool) -> int | float | None:
        """The thesis's steepest slope for ``mode`` with or without the trochanter."""
        for s in self.slopes:
            if s.mode == mode and s.trochanter == trochanter:
                return s.thesis_deg
        return None


class Reference(CheckedSection):
    """The whole data file (see the module docstring and the file's own comments)."""

    tolerance: Tolerance
    """The default relative tolerance of a figure."""
    rules: Rules
    why: dict[str, Why] = Field(default_factory=dict)
    figures: tuple[Single, ...] = ()
    table_6_7: Table67
    table_6_6: Table66
    steepest: Steepest

    def explain(self, name: str | None) -> Why | None:
        """The explanation named ``name``; ``None`` for none."""
        return None if name is None else self.why[name]

    def problems(self, at: str) -> list[Problem]:
        """The names that point nowhere, the repeated figures and slopes."""
        known = ", ".join(self.why) or "(none)"
        found: list[Problem] = []

        def why(path: str, name: str | None) -> None:
            if name is not None and name not in self.why:
                found.append(Problem(path, name, f"the name of an explanation of [why]: {known}"))

        for i, f in enumerate(self.figures):
            why(f"figures[{i}].why", f.why)
        names = [f.name for f in self.figures]
        for i, name in enumerate(names):
            if name in names[:i]:
                found.append(Problem(f"figures[{i}].name", name, "a name no other figure has"))
        table = self.table_6_7
        why("table_6_7.current_why", table.current_why)
        why("table_6_7.cot_why", table.cot_why)
        for movement, name in table.speed_why.items():
            why(f"table_6_7.speed_why.{movement}", name)
        for i, row in enumerate(table.rows):
            if row.movement not in table.speed_why:
                allowed = f"a movement of table_6_7.speed_why: {', '.join(table.speed_why)}"
                found.append(Problem(f"table_6_7.rows[{i}].movement", row.movement, allowed))
        cells = [(r.movement, r.slope_deg) for r in table.rows]
        for i, cell in enumerate(cells):
            if cell in cells[:i]:
                allowed = f"a slope no other row of {cell[0]} has"
                found.append(Problem(f"table_6_7.rows[{i}].slope_deg", cell[1], allowed))
        why("steepest.why", self.steepest.why)
        pairs = [(s.mode, s.trochanter) for s in self.steepest.slopes]
        for i, pair in enumerate(pairs):
            if pair in pairs[:i]:
                allowed = "a mode and trochanter no other slope has"
                found.append(Problem(f"steepest.slopes[{i}].mode", pair[0], allowed))
        for i, slope in enumerate(self.steepest.slopes):
            why(f"steepest.slopes[{i}].why", slope.why)
            why(f"steepest.slopes[{i}].sweep_why", slope.sweep_why)
            if slope.failed_deg is not None and slope.failed_deg <= slope.thesis_deg:
                above = f"above thesis_deg ({slope.thesis_deg:g})"
                found.append(Problem(f"steepest.slopes[{i}].failed_deg", slope.failed_deg, above))
        return found


def parse_reference(data: dict[str, Any], source: str = "<reference>") -> Reference:
    """Check a reference document (as parsed from TOML); every problem at once.

    Raises :class:`~whexar.errors.ConfigError` naming ``source`` and listing each
    problem: the key path, the value found and what is allowed.
    """
    try:
        doc = Reference.model_validate(data, context={"defer_relations": True})
    except ValidationError as exc:
        raise ConfigError(
            source, [problem_from_error(e, Reference) for e in exc.errors(include_url=False)]
        ) from None
    problems = doc.problems("")
    if problems:
        raise ConfigError(source, problems)
    return doc


def load_reference(path: str | Path = REFERENCE_PATH) -> Reference:
    """Read and check a reference file (:func:`parse_reference`)."""
    return parse_reference(read_toml(path), str(path))


@functools.cache
def reference() -> Reference:
    """The shipped reference (:data:`REFERENCE_PATH`), read once."""
    return load_reference()


__all__ = [
    "REFERENCE_PATH",
    "Reference",
    "Single",
    "TableRow",
    "Why",
    "load_reference",
    "parse_reference",
    "reference",
]
