"""The thesis's figures beside the simulation's: from the campaign's rows and the reference.

Theory of operation
-------------------
The campaign's runs carry labels (``stance-1``, ``tripod``, ``circle`` …) and,
where they vary them, the keys :data:`SLOPE_KEY` and :data:`TROCHANTER_KEY`;
the reference file (:mod:`~whexar.campaign.experiments.reference`) names the
runs each of its figures reads by them, and :func:`figures` finds those rows.

*Figures.* :func:`figures` turns the rows into :class:`Figure` s: a name, a
unit, the thesis's figure (a number, a range as text, or ``None`` where the
thesis gives none), the simulation's (a number, ``"not simulated"``, or
``None`` when the run failed or the value is undefined) and a note. Where the
two differ by more than the figure's tolerance, the note gives the reason we
believe in, chosen by the direction of the difference; every number in the
note comes from the rows.

*Seeds.* When the rows carry more than one :data:`SEED_KEY` (the campaign repeats
its runs over seeds of the spread of real parts, :mod:`whexar.sim.spread`), the
figures are worked out for each seed's rows alone and then merged: a figure's
``sim`` is the median of the seeds' numbers, ``spread`` their minimum and maximum,
and its note the note of the seed at the median (the lower one of an even count).

*Outcomes of the sweep.* A tripod or riding run *made it* when the robot did
not fall, kept its heading within the reference's ``max_heading_change_deg``
and went up the plane at no less than its ``min_progress_fraction`` of the
commanded speed (the thesis counts 0.07 m/s of 0.12 m/s at 32° as walking,
Table 6.7); a static stance *held* when the robot did not fall and slid less
than ``max_slide_m`` over its window. The steepest slope is the highest tested
slope with every tested slope up to it made.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, Final, TypeAlias

from whexar.actors.locomotion.intent import POSE_LIMIT_RAD
from whexar.campaign.experiments.metrics import TILT_SPAN_S
from whexar.campaign.experiments.reference import (
    Reference,
    Rules,
    Single,
    SteepestSlope,
    Why,
    reference,
)
from whexar.config.motion import LocomotionSpec
from whexar.sim.scenario import TiltSpec

if TYPE_CHECKING:
    from whexar.campaign.rows import Row

SLOPE_KEY: Final = "terrain.slope_deg"
"""The variation key of the plane's slope (absent: the flat)."""
TROCHANTER_KEY: Final = "config.locomotion.trochanter_follows_pitch"
"""The variation key of "with/without the trochanter" (eq. 4.18; absent: the default, on)."""
SEED_KEY: Final = "seed"
"""The variation key of the scenario's seed: the spread of real parts (absent: one world)."""

# The simulation's limits, not the thesis's: they decide what cannot be expressed.
MAX_BODY_PITCH_DEG: Final = math.degrees(POSE_LIMIT_RAD)
"""The coordinator's limit on a commanded body pitch: stance No. 2 levels the body by
pitching it, so it cannot be expressed on steeper slopes."""
MAX_TROCHANTER_DEG: Final = float(LocomotionSpec.model_fields["max_trochanter_deg"].default)
"""The coordinator's default limit on the trochanter's follow of the pitch."""

NOT_SIMULATED: Final = "not simulated"
NO_VALUE: Final = "no value: the run failed or the figure is undefined for it"
VERBS: Final = {"walk": "walked", "ride": "ridden", "stand": "stood on"}
"""How the steepest slopes' names say each mode."""

Number = float | int
ThesisValue = Number | str | None
SimValue = float | str | None


@dataclass(frozen=True)
class Figure:
    """One figure of the thesis beside the simulation's: one row of the report's table."""

    name: str
    unit: str
    thesis: ThesisValue
    """The thesis's figure: a number, a range as text, or ``None`` where it gives none."""
    sim: SimValue
    """The simulation's: a number, ``"not simulated"``, or ``None`` (no value)."""
    source: str = ""
    """Where in the thesis (section, table, equation)."""
    note: str = ""
    seeds: int = 1
    """How many seeds the figure is the median of (1: one world)."""
    spread: tuple[float, float] | None = None
    """The smallest and largest of the seeds' numbers (``None``: one seed, or no number)."""
    counted: bool = True
    """Whether the agreement counts the row (:mod:`~whexar.campaign.experiments.agreement`):
    ``False`` for a figure measured a second way beside a row that is counted, so that no
    figure of the thesis counts twice (the steepest slopes on Table 6.6's inclinations)."""

    def to_json(self) -> dict[str, Any]:
        """``{"name", "unit", "thesis", "sim"}``, over seeds ``"seeds"`` and ``"spread"``
        ([min, max]), and ``"counted": false`` for a row the agreement does not count: the
        row of ``whexar sim --experiments --json``."""
        out: dict[str, Any] = {
            "name": self.name,
            "unit": self.unit,
            "thesis": self.thesis,
            "sim": self.sim,
        }
        if self.seeds > 1:
            out["seeds"] = self.seeds
            out["spread"] = None if self.spread is None else list(self.spread)
        if not self.counted:
            out["counted"] = False
        return out


# --------------------------------------------------------------------------- rows


def slope_of(row: Row) -> float:
    """The row's slope (°): its :data:`SLOPE_KEY`, 0 on the flat."""
    value = row.variation.get(SLOPE_KEY, 0.0)
    return float(value) if isinstance(value, int | float) else 0.0


def seed_of(row: Row) -> int | None:
    """The row's seed (:data:`SEED_KEY`); ``None`` when the campaign does not vary it."""
    value = row.variation.get(SEED_KEY)
    return value if isinstance(value, int) and not isinstance(value, bool) else None


def trochanter_of(row: Row) -> bool:
    """Whether the row's trochanters followed the pitch (:data:`TROCHANTER_KEY`)."""
    return bool(row.variation.get(TROCHANTER_KEY, True))


def find(
    rows: Iterable[Row], label: str, slope: float = 0.0, trochanter: bool | None = None
) -> Row | None:
    """The first row of ``label`` on ``slope`` (and with or without the trochanter)."""
    for row in rows:
        if (
            row.label == label
            and abs(slope_of(row) - slope) < 1e-9
            and (trochanter is None or trochanter_of(row) == trochanter)
        ):
            return row
    return None


def number(row: Row | None, key: str) -> float | None:
    """The row's metric ``key`` as a finite float; ``None`` when failed, missing or no number."""
    if row is None or row.outcome != "ok":
        return None
    value = row.metrics.get(key)
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value) if math.isfinite(value) else None


def commanded_speed(row: Row) -> float | None:
    """The fastest speed the row's commands ask for (m/s), from its variation."""
    commands = row.variation.get("commands")
    speeds = [
        math.hypot(float(c.get("vx_m_s", 0.0)), float(c.get("vy_m_s", 0.0)))
        for c in (commands if isinstance(commands, list) else [])
        if isinstance(c, Mapping)
    ]
    return max(speeds) if speeds and max(speeds) > 0 else None


# --------------------------------------------------------------------------- outcomes


def made_it(row: Row, rules: Rules | None = None) -> bool | None:
    """Whether a movement went up the plane (see the module docstring); ``None``: unknown.
    ``rules``: the shipped reference's by default."""
    rules = reference().rules if rules is None else rules
    speed, wanted = number(row, "uphill_speed_mps"), commanded_speed(row)
    turned = number(row, "max_heading_change_deg")
    if speed is None or wanted is None or turned is None:
        return None
    return (
        row.metrics.get("fell") is False
        and speed >= rules.min_progress_fraction * wanted
        and turned <= rules.max_heading_change_deg
    )


def held(row: Row, rules: Rules | None = None) -> bool | None:
    """Whether a static stance held (see the module docstring); ``None``: unknown.
    ``rules``: the shipped reference's by default."""
    rules = reference().rules if rules is None else rules
    slid = number(row, "displacement_m")
    if slid is None:
        return None
    return row.metrics.get("fell") is False and slid <= rules.max_slide_m


Judge: TypeAlias = "Callable[[Row, Rules | None], bool | None]"
"""A judge of a run's outcome: :func:`made_it` or :func:`held`."""


def judge_of(label: str) -> Judge:
    """How a run of ``label`` is judged: a stance's by :func:`held`, others' by :func:`made_it`."""
    return held if label.startswith("stance") else made_it


def steepest(
    rows: Iterable[Row], label: str, trochanter: bool, rules: Rules | None = None
) -> float | None:
    """The highest tested slope (°) with every tested slope up to it passed; ``None`` when
    the lowest failed or nothing was tested."""
    return _sweep(rows, label, trochanter, rules)[1]


def _sweep(
    rows: Iterable[Row], label: str, trochanter: bool, rules: Rules | None
) -> tuple[list[Row], float | None, Row | None]:
    """The runs of ``label`` by slope, :func:`steepest`'s answer and the first run that
    did not pass (``None``: every one passed)."""
    judge = judge_of(label)
    tested = sorted(
        (r for r in rows if r.label == label and trochanter_of(r) == trochanter), key=slope_of
    )
    best: float | None = None
    for row in tested:
        if judge(row, rules) is not True:
            return tested, best, row
        best = slope_of(row)
    return tested, best, None


# --------------------------------------------------------------------------- notes


def _differs(thesis: ThesisValue, sim: SimValue, tolerance: float) -> int:
    """+1 / −1 when the sim's figure is above / below the thesis's beyond ``tolerance``
    (relative), 0 when within it or when either is not a number."""
    if not isinstance(thesis, int | float) or not isinstance(sim, float | int):
        return 0
    if abs(sim - thesis) <= tolerance * abs(thesis):
        return 0
    return 1 if sim > thesis else -1


def _figure(
    name: str,
    unit: str,
    thesis: ThesisValue,
    sim: SimValue,
    *,
    source: str,
    why: Why | None = None,
    tolerance: float = 0.0,
    note: str = "",
) -> Figure:
    """A figure; its note is ``note``, then ``why``'s reason if the two differ beyond
    ``tolerance``, or says there is no value."""
    notes = [note] if note else []
    direction = _differs(thesis, sim, tolerance)
    if why is not None and direction:
        reason = why.higher if direction > 0 else why.lower
        if reason:
            notes.append(reason)
    if sim is None and not note:
        notes.append(NO_VALUE)
    return Figure(name, unit, thesis, sim, source, " ".join(notes))


def _outcome_note(row: Row | None, judge: Judge, rules: Rules) -> str:
    """Why the run did not make it or hold, if it did not; ``""`` if it did."""
    if row is None:
        return "no such run in the campaign"
    if row.outcome != "ok":
        return f"run failed: {row.error}"
    ok = judge(row, rules)
    if ok is True:
        return ""
    fell_at, doing = number(row, "fell_at_s"), row.metrics.get("fell_while")
    if row.metrics.get("fell") is True:
        when = f" at {fell_at:.1f} s" if fell_at is not None else ""
        how = f" ({doing})" if isinstance(doing, str) and doing else ""
        return f"The robot fell (tilted past 60°){when}{how}."
    if judge is made_it:
        speed, turned = number(row, "uphill_speed_mps"), number(row, "max_heading_change_deg")
        if turned is not None and turned > rules.max_heading_change_deg:
            return f"Did not climb: it turned {turned:.0f}° away."
        return f"Did not climb: {speed:+.3f} m/s up the plane." if speed is not None else ""
    slid = number(row, "displacement_m")
    return f"Slid {slid:.3f} m in its 3 s window." if slid is not None else ""


def _joined(*notes: str) -> str:
    return " ".join(n for n in notes if n)


# --------------------------------------------------------------------------- the figures


def _single(ref: Reference, f: Single, rows: Sequence[Row]) -> Figure:
    """One figure of the reference's ``[[figures]]``."""
    row = find(rows, f.run.label, f.run.slope_deg, f.run.trochanter)
    notes = [f.note]
    if f.outcome:
        notes.append(_outcome_note(row, judge_of(f.run.label), ref.rules))
    if f.compare is not None:
        other_run = f.compare.run
        other = find(rows, other_run.label, other_run.slope_deg, other_run.trochanter)
        this, that = number(row, f.compare.metric), number(other, f.compare.metric)
        if this is not None and that is not None:
            notes.append(f.compare.note.format(this=this, other=that))
    tolerance = ref.tolerance if f.tolerance is None else f.tolerance
    return _figure(
        f.name,
        f.unit,
        f.thesis,
        number(row, f.metric),
        source=f.source,
        why=ref.explain(f.why),
        tolerance=tolerance,
        note=_joined(*notes),
    )


def _table_6_7(ref: Reference, rows: Sequence[Row]) -> list[Figure]:
    """6.8.1, Table 6.7: the movements on slopes, without and with the trochanter."""
    table, out = ref.table_6_7, []
    for t in table.rows:
        for trochanter in (False, True):
            row = find(rows, t.movement, float(t.slope_deg), trochanter)
            with_ = "with" if trochanter else "without"
            current, cot = t.current(trochanter), t.cost(trochanter)
            measured = current is not None
            note = _joined(
                "" if measured else table.missing, _outcome_note(row, made_it, ref.rules)
            )
            head = f"Table 6.7 {t.movement} {t.slope_deg}°, {with_} trochanter"
            # A robot that slid back or fell has a current but no cost of transport.
            climbed = row is not None and made_it(row, ref.rules) is True
            out += [
                _figure(
                    f"{head}: speed",
                    "m/s",
                    t.speed_m_s if measured else None,
                    number(row, "uphill_speed_mps"),
                    source=table.speed_source,
                    why=ref.explain(table.speed_why[t.movement]),
                    tolerance=ref.tolerance,
                    note=note,
                ),
                _figure(
                    f"{head}: total current",
                    "A",
                    current,
                    number(row, "total_current_a"),
                    source=table.current_source,
                    why=ref.explain(table.current_why) if climbed else None,
                    tolerance=ref.tolerance,
                    note=note,
                ),
                _figure(
                    f"{head}: cost of transport",
                    "",
                    cot,
                    number(row, "thesis_cost_of_transport") if climbed else None,
                    source=table.cot_source,
                    why=ref.explain(table.cot_why),
                    tolerance=ref.tolerance,
                    note=note,
                ),
            ]
    return out


def _table_6_6(ref: Reference, rows: Sequence[Row]) -> list[Figure]:
    """6.8, Table 6.6, Fig. 6.7a: the static stances, and the current No. 3 saves."""
    table, out = ref.table_6_6, []
    for slope in table.slopes_deg:
        for stance in (1, 2, 3):
            if slope == 0 and stance != 1:
                continue  # Table 6.6: on the flat the three stances are one
            name = f"Table 6.6 stance No. {stance} on {slope}°: total current"
            if stance == 2 and slope > MAX_BODY_PITCH_DEG:
                note = table.not_simulated.format(slope=slope, limit=MAX_BODY_PITCH_DEG)
                out.append(Figure(name, "A", None, NOT_SIMULATED, table.source, note))
                continue
            row = find(rows, table.label(stance), float(slope))
            limit = ""
            if stance == 3 and slope > MAX_TROCHANTER_DEG:
                limit = table.trochanter_limit.format(limit=MAX_TROCHANTER_DEG)
            note = _joined(table.note, limit, _outcome_note(row, held, ref.rules))
            sim = number(row, "total_current_a")
            out.append(_figure(name, "A", None, sim, source=table.source, note=note))
    saving = table.saving
    one_row = find(rows, table.label(1), saving.slope_deg)
    three_row = find(rows, table.label(3), saving.slope_deg)
    one, three = number(one_row, "total_current_a"), number(three_row, "total_current_a")
    saved = 100 * (1 - three / one) if one and three is not None else None
    note = ""
    if saved is not None and saved < saving.thesis_pct:
        # Why less is saved, from the coxa servos' current (the thesis saw the trochanter
        # relieve them, 6.8.2, Fig. 6.8).
        coxa = number(one_row, "coxa_current_a"), number(three_row, "coxa_current_a")
        if coxa[0] is not None and coxa[1] is not None:
            note = saving.lower.format(one=coxa[0], three=coxa[1])
    name = f"stance No. 3 against No. 1 on {saving.slope_deg:g}°: current saved"
    thesis = f">{saving.thesis_pct:g}"
    out.append(_figure(name, "%", thesis, saved, source=saving.source, note=note))
    return out


def _board_runs(rows: Iterable[Row], label: str, trochanter: bool) -> list[Row]:
    """The tilting-board runs (runs with a ``tilt``) of ``label``, with or without trochanter."""
    return [
        r
        for r in rows
        if r.label == label and trochanter_of(r) == trochanter and "tilt" in r.variation
    ]


def tilted(rows: Iterable[Row], label: str, trochanter: bool) -> list[float] | None:
    """The board angles (°) where the tilting-board runs of ``label`` (runs with a ``tilt``)
    failed (``tilt_limit_deg``), one per run that has one; ``None`` when ``label`` names no
    such runs."""
    board = _board_runs(rows, label, trochanter)
    if not board:
        return None
    found = (number(r, "tilt_limit_deg") for r in board)  # a failed run has none
    return [v for v in found if v is not None]


def held_to_the_end(rows: Iterable[Row], label: str, trochanter: bool) -> float | None:
    """The board's last measured angle (°) when a tilting-board run of ``label`` never
    failed (its ``tilt_limit_deg`` is that angle, so the limit lies above), else ``None``."""
    for r in _board_runs(rows, label, trochanter):
        limit, to_s = number(r, "tilt_limit_deg"), r.variation.get("measure.to_s")
        if limit is None or not isinstance(to_s, int | float):
            continue
        board = TiltSpec.model_validate(r.variation["tilt"]).board()  # as the run read it
        # A failure is dated by the start of its span, at most the window's end less a
        # span: a later angle is the one the metric gives when nothing failed. A board
        # held at its top is never steeper: there any limit means "at least the top".
        latest = board.angle_deg(float(to_s) - TILT_SPAN_S)
        if limit > latest + 1e-6 or limit >= board.max_deg - 1e-6:
            return board.angle_deg(float(to_s))
    return None


def _steepest(ref: Reference, rows: Sequence[Row]) -> list[Figure]:
    """6.7.6, 6.8.1: the steepest slopes, from the tilting board (or a sweep)."""
    spec, out = ref.steepest, []
    tolerance = ref.tolerance if spec.tolerance is None else spec.tolerance
    for s in spec.slopes:
        board = tilted(rows, s.label, s.trochanter)
        note = ""
        found: float | None
        if board is not None:
            found = statistics.median(board) if board else None
            if len(board) > 1:
                note = f"Median of {len(board)} runs: {min(board):.3g}–{max(board):.3g}°."
            last = held_to_the_end(rows, s.label, s.trochanter)
            if last is not None:
                note = (
                    f"A run held to the board's last angle ({last:.3g}°): the limit lies "
                    "at or above it; the run should be longer or the board steeper."
                )
        else:
            runs, found, _ = _sweep(rows, s.label, s.trochanter, ref.rules)
            tested = [slope_of(r) for r in runs]
            if tested and found == tested[-1]:
                note = f"Every slope tested passed: the limit lies above {tested[-1]:g}°."
            elif found is None and tested:
                note = f"The lowest slope tested ({tested[0]:g}°) already failed."
        with_ = "with" if s.trochanter else "without"
        name = f"steepest slope {VERBS[s.mode]}, {with_} trochanter"
        why = ref.explain(s.why or spec.why)
        out.append(
            _figure(
                name,
                "°",
                s.thesis_deg,
                found,
                source=spec.source,
                why=why,
                tolerance=tolerance,
                note=note,
            )
        )
        out.append(
            _bracket(
                name,
                s.thesis_deg,
                s.failed_deg,
                found,
                source=spec.source,
                tried=ref.table_6_6.slopes_deg,
            )
        )
        if s.sweep is not None:
            out.append(_on_planes(ref, rows, s, s.sweep, name, tolerance))
    return out


def _on_planes(
    ref: Reference,
    rows: Sequence[Row],
    s: SteepestSlope,
    sweep: str,
    name: str,
    tolerance: float,
) -> Figure:
    """The steepest slope as the thesis's protocol gives it: the last of the fixed
    inclinations (``sweep``'s runs) managed with every one below it; its note says what
    the next one did. Not counted in the agreement: the board's row measures the figure."""
    spec, rules = ref.steepest, ref.rules
    tested, found, failed = _sweep(rows, sweep, s.trochanter, rules)
    if failed is not None:
        why_not = (
            _outcome_note(failed, judge_of(sweep), rules) or "not judged, a metric is missing."
        )
        next_one = f"On {slope_of(failed):g}°: {why_not}"
    elif tested:
        next_one = f"Every slope tested passed: the limit lies above {slope_of(tested[-1]):g}°."
    else:
        next_one = "The campaign has no such runs."
    figure = _figure(
        f"{name}: Table 6.6's planes",
        "°",
        s.thesis_deg,
        found,
        source=spec.source,
        why=ref.explain(s.sweep_why),
        tolerance=tolerance,
        note=_joined(spec.sweep_note.format(runs=sweep), next_one),
    )
    return replace(figure, counted=False)


def _bracket(
    name: str,
    managed: float,
    failed: float | None,
    found: float | None,
    *,
    source: str,
    tried: Sequence[float],
) -> Figure:
    """The steepest slope against Table 6.6's bracket: of the inclinations ``tried``, the
    thesis's robot managed ``managed`` and not ``failed`` (``None``: the steepest
    tried)."""
    thesis = f"{managed:g}–{failed:g}" if failed is not None else f"≥ {managed:g}"
    listed = ", ".join(f"{t:g}" for t in tried)
    said = f"The thesis tried only {listed}° (Table 6.6): its robot managed {managed:g}° and " + (
        f"not {failed:g}°, so its limit lies in between."
        if failed is not None
        else "that was the steepest tried, so its limit lies above."
    )
    if found is None:
        where = ""
    elif found < managed:
        where = f" The simulation's is {100 * (managed - found) / managed:.0f} % below it."
    elif failed is not None and found >= failed:
        where = (
            f" The simulation's reaches {failed:g}°, which the thesis's robot did not: "
            f"{100 * (found - failed) / failed:.0f} % above it."
        )
    else:
        where = " The simulation's lies inside it."
    return Figure(f"{name}: Table 6.6's bracket", "°", thesis, found, source, said + where)


def figures(rows: Sequence[Row], ref: Reference | None = None) -> list[Figure]:
    """The thesis's figures beside the simulation's, from the campaign's rows (see the
    module docstring); one :class:`Figure` per figure, in the report's order: the
    reference's single figures (6.4, 6.5, 6.8.1), Table 6.7, Table 6.6 and the saving of
    6.8.1, the steepest slopes (6.7.6). ``ref``: the shipped reference by default.

    Rows of several seeds give each figure's median over them (the module docstring)."""
    ref = reference() if ref is None else ref
    seeds = sorted({seed_of(r) for r in rows}, key=lambda s: -1 if s is None else s)
    if len(seeds) <= 1:
        return _one_world(rows, ref)
    per_seed = [_one_world([r for r in rows if seed_of(r) == s], ref) for s in seeds]
    return [_over_seeds(same) for same in zip(*per_seed, strict=True)]


def _one_world(rows: Sequence[Row], ref: Reference) -> list[Figure]:
    out = [_single(ref, f, rows) for f in ref.figures]
    out += _table_6_7(ref, rows)
    out += _table_6_6(ref, rows)
    out += _steepest(ref, rows)
    return out


def _sim_number(f: Figure) -> float | None:
    value = f.sim
    return float(value) if isinstance(value, int | float) and not isinstance(value, bool) else None


def _over_seeds(same: Sequence[Figure]) -> Figure:
    """One figure from each seed's: the median, the min–max and the median seed's note."""
    numbers = sorted(
        ((v, f) for f in same if (v := _sim_number(f)) is not None), key=lambda p: p[0]
    )
    if not numbers:
        return replace(same[0], seeds=len(same))
    values = [v for v, _ in numbers]
    middle = numbers[(len(numbers) - 1) // 2][1]
    note = middle.note
    if len(numbers) < len(same):
        missing = f"{len(same) - len(numbers)} of {len(same)} seeds gave no value."
        note = _joined(note, missing)
    return replace(
        middle,
        sim=statistics.median(values),
        note=note,
        seeds=len(same),
        spread=(values[0], values[-1]),
    )


__all__ = [
    "SEED_KEY",
    "SLOPE_KEY",
    "TROCHANTER_KEY",
    "Figure",
    "commanded_speed",
    "figures",
    "find",
    "held",
    "judge_of",
    "made_it",
    "number",
    "seed_of",
    "slope_of",
    "steepest",
    "tilted",
    "trochanter_of",
]
