"""The experiments' report: the table of figures, ``experiments.md`` and its plots.

:func:`write_report` writes ``experiments.md`` (the table) and the plots in
``img/experiments/`` under the report folder, so the folder's Markdown and
images can be copied into ``docs/`` as they are. :func:`table_text` is the
table ``whexar sim --experiments`` prints.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from whexar.campaign.experiments.agreement import FAR_RATIO, Agreement, Compared, agreement
from whexar.campaign.experiments.figures import (
    Figure,
    SimValue,
    ThesisValue,
    figures,
    seed_of,
)
from whexar.campaign.experiments.plots import PLOTS
from whexar.campaign.experiments.reference import Reference, reference
from whexar.campaign.spec import config_note

if TYPE_CHECKING:
    from whexar.campaign.rows import Row

IMG_DIR: Final = Path("img") / "experiments"
"""Where the plots go, under the report folder (as in ``docs/``)."""


def format_value(value: ThesisValue | SimValue, unit: str = "") -> str:
    """A figure as the table shows it: 3 significant digits; ``—`` for none."""
    if value is None:
        return "—"
    if isinstance(value, str):
        return value
    if isinstance(value, bool):
        return str(value)
    if value == 0:
        return "0"
    if abs(value) >= 100:
        return f"{value:.0f}"
    return f"{value:.3g}"


def seeds_of(found: Sequence[Figure]) -> int:
    """How many seeds the figures are medians of (1: one world, no spread column)."""
    return max((f.seeds for f in found), default=1)


def format_spread(f: Figure) -> str:
    """A figure's min–max over seeds (``0.113…0.121``: a dash would read as a minus);
    ``—`` for none."""
    if f.spread is None:
        return "—"
    low, high = f.spread
    return f"{format_value(low)}…{format_value(high)}"


def table_markdown(found: Sequence[Figure]) -> str:
    """The figures as one Markdown table; over seeds, the sim's median and its min–max."""
    if seeds_of(found) == 1:
        lines = ["| figure | unit | thesis | sim | source | note |", "|---|---|---|---|---|---|"]
    else:
        lines = [
            "| figure | unit | thesis | sim (median) | min–max | source | note |",
            "|---|---|---|---|---|---|---|",
        ]
    for f in found:
        note = f.note.replace("|", "\\|")
        spread = "" if seeds_of(found) == 1 else f" | {format_spread(f)}"
        lines.append(
            f"| {f.name} | {f.unit} | {format_value(f.thesis)} | {format_value(f.sim)}{spread} "
            f"| {f.source} | {note} |"
        )
    return "\n".join(lines)


def _compared(c: Compared, ratio: bool = False) -> str:
    """``name: sim against thesis unit (how far)``: as sim / thesis (×0.27) or as the
    relative deviation (8 % off)."""
    f = c.figure
    unit = f.unit if f.unit in ("°", "%", "") else f" {f.unit}"
    how = f"×{c.ratio:.2g}" if ratio else f"{c.deviation * 100:.0f} % off"
    return f"{f.name}: {format_value(f.sim)} against {format_value(f.thesis)}{unit} ({how})"


def agreement_lines(a: Agreement, bullet: str = "") -> list[str]:
    """The table summed up (:mod:`~whexar.campaign.experiments.agreement`), a sentence a
    line, each after ``bullet``; the rows it names indented under theirs."""
    sub = "  " + bullet if bullet else "  "
    median = a.median_deviation
    lines = [
        f"{bullet}{len(a.numbers)} figures with one thesis number (not 0) to compare with:"
        + (" none." if median is None else f" median deviation {median * 100:.1f} %."),
        f"{bullet}{len(a.far_off)} more than {FAR_RATIO:g}× off" + (":" if a.far_off else "."),
        *(sub + _compared(c, ratio=True) for c in a.far_off),
        f"{bullet}{len(a.ranges)} ranges and bounds, {a.inside} inside"
        + ("; outside:" if a.outside else "."),
        *(sub + _compared(c) for c in a.outside),
    ]
    if a.without_value:
        lines.append(f"{bullet}{len(a.without_value)} with no number from the simulation:")
        lines += [sub + f.name for f in a.without_value]
    if a.second:
        same = sum(c.deviation == 0 for c in a.second)
        lines.append(
            f"{bullet}{len(a.second)} measured a second way, not counted above: "
            f"{same} equal to the thesis's" + ("; the others:" if same < len(a.second) else ".")
        )
        lines += [sub + _compared(c) for c in a.second if c.deviation != 0]
    return lines


def json_document(found: Sequence[Figure], config: str | None = None) -> dict[str, Any]:
    """What ``whexar sim --experiments --json`` prints: ``{"experiments": [row, …],
    "agreement": {…}, "config": …}`` (:meth:`Figure.to_json`, :meth:`Agreement.to_json`;
    ``config``: the robot configuration given with ``--config``, else ``null``)."""
    return {
        "experiments": [f.to_json() for f in found],
        "agreement": agreement(found).to_json(),
        "config": config,
    }


def table_text(found: Sequence[Figure]) -> str:
    """The figures for the terminal: name, thesis, sim and unit, one a line; over seeds,
    the sim's median and its min–max."""
    width = max((len(f.name) for f in found), default=10)
    seeds = seeds_of(found)
    head = "sim" if seeds == 1 else "sim (median)"
    spread = "" if seeds == 1 else f"  {'min–max':>15}"
    lines = [f"{'figure':<{width}}  {'thesis':>10}  {head:>13}{spread}  unit"]
    for f in found:
        spread = "" if seeds == 1 else f"  {format_spread(f):>15}"
        lines.append(
            f"{f.name:<{width}}  {format_value(f.thesis):>10}  {format_value(f.sim):>13}"
            f"{spread}  {f.unit}"
        )
    return "\n".join([*lines, "", *agreement_lines(agreement(found))])


def report_markdown(
    found: Sequence[Figure],
    rows: Sequence[Row],
    ref: Reference | None = None,
    config: str | None = None,
) -> str:
    """``experiments.md``: what was run (on the robot configuration ``config`` when one
    was given), the table, the plots."""
    ref = reference() if ref is None else ref
    rules = ref.rules
    failed = [r for r in rows if r.outcome != "ok"]
    lines = [
        "# The thesis's experiments in simulation",
        "",
        "Generated by `whexar sim --experiments` (campaign `config/campaigns/experiments.toml`,"
        " the thesis's figures and our explanations in"
        " `config/campaigns/reference/experiments.toml`, metrics and report in"
        " `whexar/campaign/experiments/`). The thesis is Žák 2023, sections 6.4–6.8; every"
        " thesis figure is cited by section, table or equation.",
        "",
        *config_note(config),
        f"{len(rows)} runs, {len(failed)} failed. The robot starts seated on the flat or on an"
        " endless plane rising ahead of it, stands up in its first ~2.4 s and then stands,"
        " walks the tripod gait at 0.12 m/s or rides at 0.2 m/s (6.8); the metrics measure a"
        ' window after it has settled. "With the trochanter" is'
        " `locomotion.trochanter_follows_pitch` (eq. 4.18). The total current is eq. 6.1–6.3"
        " over all 42 servos, from the motor model (the electric power over the supply"
        " voltage); the cost of transport is eq. 6.4–6.5 with it, the robot's 8.8 kg and the"
        " speed up the plane.",
        "",
        "A movement *made it* up a slope when it did not fall, turned less than"
        f" {rules.max_heading_change_deg:g}° and climbed at ≥"
        f" {rules.min_progress_fraction:.0%} of its commanded speed; a stance *held* when it"
        f" slid less than {rules.max_slide_m * 100:g} cm in 3 s. The model's physical"
        " parameters come from the sources the simulation cites; nothing was tuned to these"
        " figures. The notes give the reason we believe for a difference larger than the"
        f" figure's tolerance ({ref.tolerance * 100:g} % for most).",
        "",
        *_seeds_paragraph(found, rows),
        table_markdown(found),
        "",
        "## Agreement with the thesis",
        "",
        "The table summed up: the deviation is |sim − thesis| / |thesis|; for a range or a"
        " bound, 0 inside it and otherwise the distance to the end it misses, relative to"
        " that end. A figure of 0 (a direction) has no relative deviation and is left out.",
        "",
        *agreement_lines(agreement(found), bullet="- "),
        "",
    ]
    if failed:
        lines += ["## Failed runs", ""]
        lines += [f"- {r.label} {r.variation}: {r.error}" for r in failed]
        lines.append("")
    lines += ["## Plots", ""]
    for name, _, caption in PLOTS:
        lines += [f"![{caption}]({(IMG_DIR / name).as_posix()})", "", f"*{caption}.*", ""]
    return "\n".join(lines)


def _seeds_paragraph(found: Sequence[Figure], rows: Sequence[Row]) -> list[str]:
    """What the seeds are, and how many runs each has, when there are several."""
    seeds = seeds_of(found)
    if seeds == 1:
        return []
    runs = Counter(seed_of(r) for r in rows)
    counts = ", ".join(
        f"seed {s}: {n} runs"
        for s, n in sorted(runs.items(), key=lambda e: -1 if e[0] is None else e[0])
    )
    uneven = len(set(runs.values())) > 1
    return [
        f"The runs are {seeds} robots, each drawn from its seed within the spread of real parts"
        " (sensor gains and offsets, wheel friction, masses, gear backlash, the USB adapter's"
        ' delays, each within its datasheet\'s band: docs/sim.md, "Spread of real parts");'
        f" {counts}. *sim* is the median over the seeds, *min–max* the smallest and largest,"
        " and the note that of the seed at the median."
        + (
            " A seed that ran fewer slopes of a sweep finds its steepest slope on those."
            if uneven
            else ""
        ),
        "",
    ]


def write_report(
    rows: Sequence[Row], out_dir: str | Path, *, config: str | None = None
) -> list[Path]:
    """Write ``experiments.md`` and its plots (under ``img/experiments/``) into ``out_dir``,
    naming the robot configuration ``config`` if one was given; the paths written."""
    out = Path(out_dir)
    images = out / IMG_DIR
    images.mkdir(parents=True, exist_ok=True)
    ref = reference()
    found = figures(rows, ref)
    written = [draw(rows, ref, images / name) for name, draw, _ in PLOTS]
    md = out / "experiments.md"
    md.write_text(report_markdown(found, rows, ref, config))
    return [md, *written]


__all__ = [
    "IMG_DIR",
    "agreement_lines",
    "format_spread",
    "format_value",
    "json_document",
    "report_markdown",
    "seeds_of",
    "table_markdown",
    "table_text",
    "write_report",
]
