"""The plots of the experiments' report: the simulation's runs, the thesis's points beside.

Each plot takes the campaign's rows and the reference
(:mod:`~whexar.campaign.experiments.reference`): the labels and slopes it reads
and the thesis's points it draws come from the reference file, so a figure
corrected there is corrected in the plots too. A fallen robot's current says
nothing of the stance or the movement: the current plots show only the runs that
made it or held. Over seeds (the spread of real parts), the current plots draw each
slope's median over the seeds' runs that made it or held, the slope sweep every
run's outcome on one another, and the bar plots the first seed's runs.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Final

from whexar.campaign.experiments.figures import (
    find,
    judge_of,
    made_it,
    number,
    slope_of,
    tilted,
    trochanter_of,
)
from whexar.campaign.experiments.metrics import PER_JOINT
from whexar.record.plots import new_figure, save_figure

if TYPE_CHECKING:
    from whexar.campaign.experiments.reference import Reference
    from whexar.campaign.rows import Row

Plot = Callable[["Sequence[Row]", "Reference", Path], Path]
"""A plot: the rows and the reference in, the PNG written to the path (returned)."""


def _series(
    rows: Sequence[Row], ref: Reference, label: str, trochanter: bool | None, key: str
) -> tuple[list[float], list[float]]:
    """``key`` against the slope for the runs of ``label`` that made it or held (over
    seeds: each slope's median)."""
    judge = judge_of(label)
    by_slope: dict[float, list[float]] = {}
    for r in rows:
        if (
            r.label == label
            and (trochanter is None or trochanter_of(r) == trochanter)
            and judge(r, ref.rules) is True
        ):
            v = number(r, key)
            if v is not None:
                by_slope.setdefault(slope_of(r), []).append(v)
    slopes = sorted(by_slope)
    return slopes, [statistics.median(by_slope[x]) for x in slopes]


def plot_static(rows: Sequence[Row], ref: Reference, path: Path) -> Path:
    """Fig. 6.7a: the total current of the static stances that held, against the slope."""
    fig, ax = new_figure(8.0, 4.5)
    for stance, style in ((1, "o-"), (2, "s-"), (3, "^-")):
        xs, ys = _series(rows, ref, ref.table_6_6.label(stance), None, "total_current_a")
        ax.plot(xs, ys, style, label=f"No. {stance}")
    ax.set_xlabel("slope (°)")
    ax.set_ylabel("total servo current (A), eq. 6.1–6.3")
    ax.set_title("Static stances of Table 6.6 (cf. Fig. 6.7a); only the stances that held")
    ax.grid(True, alpha=0.3)
    ax.legend()
    return save_figure(fig, path)


def plot_motion(rows: Sequence[Row], ref: Reference, path: Path) -> Path:
    """Fig. 6.7b: the total current of the movements that climbed, Table 6.7's beside."""
    fig, ax = new_figure(8.0, 4.5)
    table = ref.table_6_7
    colors = ("tab:blue", "tab:orange", "tab:green", "tab:purple")
    for movement, color in zip(table.movements, colors, strict=False):
        for trochanter, style in ((False, "--"), (True, "-")):
            xs, ys = _series(rows, ref, movement, trochanter, "total_current_a")
            w = "w" if trochanter else "w/o"
            ax.plot(xs, ys, style + ".", color=color, label=f"{movement} {w} trochanter (sim)")
            thesis = [
                (t.slope_deg, t.current(trochanter)) for t in table.rows if t.movement == movement
            ]
            tx = [x for x, y in thesis if y is not None]
            ty = [y for _, y in thesis if y is not None]
            marker = "o" if trochanter else "s"
            ax.plot(tx, ty, marker, color=color, mfc="none", label=f"{movement} {w} (thesis)")
    ax.set_xlabel("slope (°)")
    ax.set_ylabel("total servo current (A)")
    ax.set_title("Tripod gait and riding on slopes (cf. Fig. 6.7b); sim: the runs that climbed")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    return save_figure(fig, path)


def plot_cot(rows: Sequence[Row], ref: Reference, path: Path) -> Path:
    """Table 6.7: the cost of transport of each row, the thesis's and the sim's."""
    fig, ax = new_figure(10.0, 4.5)
    names: list[str] = []
    thesis: list[float] = []
    sim: list[float] = []
    for t in ref.table_6_7.rows:
        for trochanter in (False, True):
            value = t.cost(trochanter)
            row = find(rows, t.movement, float(t.slope_deg), trochanter)
            names.append(f"{t.movement} {t.slope_deg}°{' T' if trochanter else ''}")
            thesis.append(value if value is not None else math.nan)
            s = number(row, "thesis_cost_of_transport")
            climbed = row is not None and made_it(row, ref.rules) is True
            sim.append(s if s is not None and climbed else math.nan)
    xs = list(range(len(names)))
    ax.bar([x - 0.2 for x in xs], thesis, width=0.4, label="thesis (Table 6.7)")
    ax.bar([x + 0.2 for x in xs], sim, width=0.4, label="sim")
    ax.set_xticks(xs)
    ax.set_xticklabels(names, rotation=60, ha="right", fontsize=7)
    ax.set_ylabel("cost of transport, eq. 6.4")
    ax.set_title("Cost of transport per row of Table 6.7 (T: with trochanter; no bar: no value)")
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend()
    return save_figure(fig, path)


MODES: Final = ("walk", "ride", "stand")
"""The order of the sweep's lines, each without then with the trochanter."""


SWEEPS: Final = {
    "walk": ("tripod", "tripod"),
    "ride": ("wheels", "wheels"),
    "stand": ("stance-1", "stance-3"),
}
"""The fixed-slope runs of each mode, (without, with) the trochanter."""


def plot_sweep(rows: Sequence[Row], ref: Reference, path: Path) -> Path:
    """6.7.6: the outcome of every fixed-slope run, where the tilting board failed, and the
    thesis's steepest."""
    fig, ax = new_figure(9.0, 4.0)
    lines = sorted(ref.steepest.slopes, key=lambda s: (MODES.index(s.mode), s.trochanter))
    for k, line in enumerate(lines):
        label = SWEEPS[line.mode][int(line.trochanter)]
        judge = judge_of(label)
        for r in rows:
            if r.label != label or trochanter_of(r) != line.trochanter or "tilt" in r.variation:
                continue
            ok = judge(r, ref.rules)
            color = "tab:green" if ok else "tab:red" if ok is False else "tab:gray"
            ax.plot(slope_of(r), k, "s", color=color, markersize=11)
        for angle in tilted(rows, line.label, line.trochanter) or ():
            ax.plot(angle, k, "D", color="tab:blue", markersize=7)
        ax.plot(line.thesis_deg, k, "k|", markersize=22, markeredgewidth=2)
    ax.set_yticks(range(len(lines)))
    ax.set_yticklabels([f"{s.mode} {'w' if s.trochanter else 'w/o'} trochanter" for s in lines])
    ax.set_xlabel("slope (°)")
    ax.plot([], [], "s", color="tab:green", label="made it / held")
    ax.plot([], [], "s", color="tab:red", label="failed")
    ax.plot([], [], "D", color="tab:blue", label="tilting board: failed here")
    ax.plot([], [], "k|", markersize=12, label="thesis's steepest")
    ax.legend(fontsize=7, loc="lower left")
    ax.set_title("Slopes (6.7.6): fixed slopes, and the board raised under the robot")
    ax.grid(True, axis="x", alpha=0.3)
    return save_figure(fig, path)


def plot_joints(rows: Sequence[Row], ref: Reference, path: Path) -> Path:
    """Fig. 6.8: the current per joint of the static stances the reference names."""
    fig, ax = new_figure(8.0, 4.0)
    table = ref.table_6_6
    groups = [
        (f"No. {n} {slope:g}°", find(rows, table.label(n), float(slope)))
        for slope in table.joints.slopes_deg
        for n in table.joints.stances
    ]
    xs = list(range(len(groups)))
    width = 0.8 / len(PER_JOINT)
    for k, joint in enumerate(PER_JOINT):
        values = [number(row, f"{joint}_current_a") for _, row in groups]
        ax.bar(
            [x - 0.4 + (k + 0.5) * width for x in xs],
            [v if v is not None else math.nan for v in values],
            width=width,
            label=joint,
        )
    ax.set_xticks(xs)
    ax.set_xticklabels([g for g, _ in groups])
    ax.set_ylabel("current of the six servos (A)")
    ax.set_title("Current per joint, static stances (cf. Fig. 6.8; the joints the bus reads)")
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend()
    return save_figure(fig, path)


PLOTS: Final[tuple[tuple[str, Plot, str], ...]] = (
    (
        "static-current.png",
        plot_static,
        "Total current of the static stances that held (Fig. 6.7a)",
    ),
    (
        "motion-current.png",
        plot_motion,
        "Total current of the movements that climbed, thesis's points beside (Fig. 6.7b)",
    ),
    ("cost-of-transport.png", plot_cot, "Cost of transport per row of Table 6.7"),
    ("slope-sweep.png", plot_sweep, "Outcome of every run of the slope sweep (6.7.6)"),
    ("joint-current.png", plot_joints, "Current per joint of the static stances (Fig. 6.8)"),
)
"""Each plot of the report: its file name, how it is drawn, its caption."""

__all__ = ["PLOTS", "Plot"]
