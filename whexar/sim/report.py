"""The report of a simulated run: PNG plots, ``summary.json`` and ``summary.md``.

Theory of operation
-------------------
:func:`write_report` turns a :class:`~whexar.sim.run.SimResult` into a folder:

* ``path.png`` — the body's path seen from above, coloured by time, over the
  footprints of the terrain's obstacles (read from the MuJoCo model: every
  box and ball that is not the robot's);
* ``gait.png`` — the gait diagram (thesis Fig. 3.3): a bar for every leg
  while :class:`~whexar.actors.messages.LegState` says ``swing``, over a band
  of the coordinator's activity (:class:`~whexar.actors.messages.LocomotionState`);
* ``joints.png`` — goal against present angle of leg 0's (RF) coxa, femur,
  tibia and tarsus (Fig. 6.2): goals from the :class:`JointGoals` that leg
  sends, present angles from the bus's :class:`ServoStates`;
* ``current.png`` — current per leg: the sum of |Present Current| of the
  leg's servos in each bus cycle (the ``default`` read plan reads the current
  of the five positioning joints only, so the wheel and its direction servo
  are missing from it);
* ``cot.png`` — cost of transport per segment, CoT = E / (m g d), and mean
  electric power, the segments split at the scenario's command times (one
  segment per command; :func:`segments`).

Everything is plotted from the run's series (:mod:`whexar.sim.series`, kept as the
messages passed) and the samples; nothing is run again. The gait diagram, the joint
angles and the currents are drawn by :mod:`whexar.record.plots` (which ``whexar plot``
draws a recording with); matplotlib draws with its Agg backend (no display).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

import numpy as np

from whexar import _json
from whexar.actors.messages import GaitSelected, JointBack, JointLost, MotionCommand
from whexar.kinematics.stability import convex_hull
from whexar.record import plots
from whexar.record.plots import new_figure, save_figure
from whexar.robot import JOINT_NAMES, LEG_NAMES
from whexar.sim.run import progress, travelled

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from whexar.sim.run import Sample, SimResult

G: Final = 9.81
PLOTTED_JOINTS: Final = plots.FIG_6_2_JOINTS
"""Leg 0's joints in the goal/present plot: coxa, femur, tibia, tarsus (Fig. 6.2)."""
MIN_SEGMENT_DISTANCE_M: Final = 0.1
MIN_SEGMENT_SPEED_M_S: Final = 0.02
"""A segment shorter than this, or slower on average, has no cost of transport: it stands
(sways, sits down) rather than travels, and E/(m g d) of a few centimetres is noise."""
_ROBOT_GEOM_GROUP: Final = 3
"""The geom group :class:`~whexar.sim.world.SimWorld` moves the robot's geoms to."""
TIME_LABEL: Final = "simulated time (s)"


@dataclass(frozen=True)
class Segment:
    """One stretch of the run: from ``t0`` to ``t1`` s, doing ``label``."""

    t0: float
    t1: float
    label: str
    distance_m: float
    """Length of the body's path over the segment, sway included."""
    energy_j: float
    cost_of_transport: float | None
    """E / (m g d), d the net progress; ``None`` when it hardly got anywhere
    (:data:`MIN_SEGMENT_SPEED_M_S`)."""
    progress_m: float = 0.0
    """Net displacement of the body from the segment's start to its end."""

    @property
    def mean_power_w(self) -> float:
        """Mean electric power over the segment."""
        return self.energy_j / (self.t1 - self.t0) if self.t1 > self.t0 else 0.0


def _travel(samples: Sequence[Sample], t0: float, t1: float) -> tuple[float, float, float]:
    """Path length (m), energy (J) and net progress (m) over the samples in [t0, t1]."""
    inside = [s for s in samples if t0 - 1e-9 <= s.t <= t1 + 1e-9]
    distance = travelled(inside)
    energy = sum(0.5 * (a.power_w + b.power_w) * (b.t - a.t) for a, b in itertools.pairwise(inside))
    return distance, energy, progress(inside)


def segments(
    samples: Sequence[Sample],
    commands: Sequence[tuple[float, MotionCommand]],
    mass_kg: float,
    *,
    every_s: float = 10.0,
) -> list[Segment]:
    """The run split at the command times (commands at one time make one segment).

    Without commands it is split every ``every_s`` seconds. The stretch before
    the first command is labelled ``"start"`` (the robot stands up there).
    """
    from whexar.sim.scenario import describe_command

    if not samples:
        return []
    end = samples[-1].t
    cuts: list[tuple[float, str]] = []
    if commands:
        by_time: dict[float, list[str]] = {}
        for t, cmd in commands:
            if t < end:
                by_time.setdefault(t, []).append(describe_command(cmd))
        cuts = [(t, ", ".join(labels)) for t, labels in sorted(by_time.items())]
        if not cuts or cuts[0][0] > samples[0].t:
            cuts.insert(0, (samples[0].t, "start"))
    else:
        n = max(1, math.ceil(end / every_s))
        cuts = [
            (k * every_s, f"{k * every_s:g}–{min(end, (k + 1) * every_s):g} s") for k in range(n)
        ]
    out: list[Segment] = []
    for (t0, label), nxt in itertools.zip_longest(cuts, cuts[1:]):
        t1 = end if nxt is None else nxt[0]
        if t1 <= t0:
            continue
        distance, energy, net = _travel(samples, t0, t1)
        travels = net >= max(MIN_SEGMENT_DISTANCE_M, MIN_SEGMENT_SPEED_M_S * (t1 - t0))
        cot = energy / (mass_kg * G * net) if travels else None
        out.append(Segment(t0, t1, label, distance, energy, cot, net))
    return out


# --------------------------------------------------------------------------- data from the series
# The run keeps its messages as compact series (whexar.sim.series), built as the messages
# passed with the same rules as whexar.record.plots, which `whexar plot` draws a recording with.


def swing_intervals(result: SimResult) -> dict[int, list[tuple[float, float]]]:
    """Per leg, the (start, end) times it was in swing, from its LegState messages."""
    return result.series.swing_intervals()


def activity_intervals(result: SimResult) -> list[tuple[float, float, str]]:
    """(start, end, activity) of the coordinator, from its LocomotionState messages."""
    return result.series.activity_intervals()


def joint_traces(
    result: SimResult, leg: int = 0
) -> dict[int, tuple[list[tuple[float, float]], list[tuple[float, float]]]]:
    """For each of :data:`PLOTTED_JOINTS`: (goals, present) as (t, rad) lists; goals are
    those the leg's own actor sent. A run keeps leg 0's only
    (:data:`~whexar.sim.series.TRACED_LEG`)."""
    return result.series.joint_traces(leg)


def leg_currents(result: SimResult) -> tuple[list[float], np.ndarray]:
    """Bus cycle times and, per cycle and leg, Σ |Present Current| of the leg's servos (A)."""
    return result.series.leg_currents()


# --------------------------------------------------------------------------- plots


@dataclass(frozen=True)
class _Shape:
    """The footprint of one terrain geom: a polygon, or a circle (centre and radius)."""

    label: str
    colour: str
    points: tuple[tuple[float, float], ...]
    radius: float = 0.0


def _terrain_shapes(result: SimResult) -> list[_Shape]:
    """Footprints of the terrain's boxes and balls (not the robot's, not the ground's slabs)."""
    import mujoco

    model, data = result.world.model, result.world.data
    colours = {"ramp": "#9ecae1", "step": "#c6dbef", "rock": "#969696", "block": "#a6761d"}
    out: list[_Shape] = []
    for g in range(model.ngeom):
        if int(model.geom_group[g]) == _ROBOT_GEOM_GROUP:
            continue
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
        kind = name.rsplit("_", 1)[0]
        free = int(model.geom_bodyid[g]) != 0  # a free block has a body of its own
        label = "free block" if free else kind
        colour = "#ff7f00" if free else colours.get(kind, "#bdbdbd")
        gtype = int(model.geom_type[g])
        size = model.geom_size[g]
        centre = data.geom_xpos[g]
        if gtype == mujoco.mjtGeom.mjGEOM_BOX and max(size[:2]) <= 10.0:  # not ground slabs
            rot = data.geom_xmat[g].reshape(3, 3)
            corners = [
                (float(p[0]), float(p[1]))
                for signs in itertools.product((-1, 1), repeat=3)
                for p in [centre + rot @ (np.array(signs) * size)]
            ]
            out.append(_Shape(label, colour, tuple(convex_hull(corners))))
        elif gtype == mujoco.mjtGeom.mjGEOM_SPHERE:
            point = (float(centre[0]), float(centre[1]))
            out.append(_Shape(label, colour, (point,), float(size[0])))
    return out


def _bounds(shapes: Sequence[_Shape]) -> tuple[float, float, float, float] | None:
    """(x0, x1, y0, y1) around every shape, or None."""
    if not shapes:
        return None
    xs = [x + d for s in shapes for x, _ in s.points for d in (-s.radius, s.radius)]
    ys = [y + d for s in shapes for _, y in s.points for d in (-s.radius, s.radius)]
    return min(xs), max(xs), min(ys), max(ys)


def _draw_terrain(ax: Axes, shapes: Sequence[_Shape]) -> None:
    from matplotlib.patches import Circle, Polygon

    labelled: set[str] = set()
    for shape in shapes:
        shown = shape.label if shape.label not in labelled else None
        labelled.add(shape.label)
        style = {"fc": shape.colour, "ec": "#444444", "lw": 0.5, "label": shown}
        if shape.radius > 0:
            ax.add_patch(Circle(shape.points[0], shape.radius, **style))
        else:
            ax.add_patch(Polygon(shape.points, closed=True, **style))


def plot_path(result: SimResult, path: Path, *, title: str = "") -> Path:
    """The path of the body centre seen from above, over the terrain's obstacles."""
    s = result.samples
    xs = np.array([p.x for p in s])
    ys = np.array([p.y for p in s])
    ts = np.array([p.t for p in s])
    # The whole course is shown, where the robot went and where it did not get to.
    margin = 0.4
    box = [0.0, 0.0, 0.0, 0.0]
    if len(s):
        box = [float(xs.min()), float(xs.max()), float(ys.min()), float(ys.max())]
    shapes = _terrain_shapes(result)
    terrain = _bounds(shapes)
    if terrain is not None:
        lo_x, hi_x, lo_y, hi_y = terrain
        box = [min(box[0], lo_x), max(box[1], hi_x), min(box[2], lo_y), max(box[3], hi_y)]
    x0, x1, y0, y1 = box[0] - margin, box[1] + margin, box[2] - margin, box[3] + margin
    # The figure takes the course's shape (long and narrow), within reason.
    fig, ax = new_figure(11.0, min(8.0, max(3.5, 9.0 * (y1 - y0) / (x1 - x0) + 1.2)))
    _draw_terrain(ax, shapes)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    if len(s):
        ax.plot(xs, ys, color="#555555", lw=0.8, zorder=2)
        points = ax.scatter(xs, ys, c=ts, cmap="viridis", s=6, zorder=3)
        fig.colorbar(points, ax=ax, label="simulated time (s)", fraction=0.04, pad=0.02)
        ax.plot(xs[0], ys[0], "o", color="#1a9850", ms=8, label="start", zorder=4)
        ax.plot(xs[-1], ys[-1], "s", color="#d73027", ms=8, label="end", zorder=4)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x (m, along the course)")
    ax.set_ylabel("y (m, to the left)")
    ax.set_title(title or "Path of the body centre, seen from above")
    ax.grid(True, lw=0.3)
    ax.legend(loc="upper left", fontsize=8, framealpha=0.8)
    return save_figure(fig, path)


def plot_gait(result: SimResult, path: Path, *, window: tuple[float, float] | None = None) -> Path:
    """The gait diagram: each leg's swings as bars (Fig. 3.3), the activity as a band, the
    gait walked in a row above them and each reflex's active spells above that."""
    end = result.samples[-1].t if result.samples else result.duration_s
    return plots.draw_gait(
        swing_intervals(result),
        activity_intervals(result),
        path,
        window=window if window is not None else (0.0, end),
        time_label=TIME_LABEL,
        gaits=result.series.gait_intervals(),
        reflexes=result.series.reflex_intervals(),
    )


def plot_joints(result: SimResult, path: Path, *, leg: int = 0) -> Path:
    """Goal against present angle of one leg's coxa, femur, tibia and tarsus (Fig. 6.2)."""
    return plots.draw_joints(joint_traces(result, leg), path, leg=leg, time_label=TIME_LABEL)


def plot_currents(result: SimResult, path: Path) -> Path:
    """Σ |Present Current| of each leg's servos per bus cycle, one row per leg."""
    times, amps = leg_currents(result)
    return plots.draw_leg_currents(times, amps, path, time_label=TIME_LABEL)


def plot_cot(found: Sequence[Segment], path: Path) -> Path:
    """Cost of transport and mean electric power per segment."""
    fig, (top, bottom) = new_figure(11.0, 6.5, rows=2, sharex=True)
    x = np.arange(len(found))
    cots = [s.cost_of_transport if s.cost_of_transport is not None else 0.0 for s in found]
    bars = top.bar(x, cots, color="#3182bd")
    for bar, s in zip(bars, found, strict=True):
        text = f"{s.cost_of_transport:.1f}" if s.cost_of_transport is not None else "—"
        top.annotate(
            text,
            (bar.get_x() + bar.get_width() / 2, bar.get_height()),
            ha="center",
            va="bottom",
            fontsize=8,
        )
    top.set_ylabel("cost of transport E/(m g d)")
    top.set_title(
        "Per segment of the run (—: stood rather than travelled, "
        f"under {100 * MIN_SEGMENT_DISTANCE_M:g} cm or {100 * MIN_SEGMENT_SPEED_M_S:g} cm/s)"
    )
    top.grid(True, axis="y", lw=0.3)
    bottom.bar(x, [s.mean_power_w for s in found], color="#e6550d")
    bottom.set_ylabel("mean electric power (W)")
    bottom.grid(True, axis="y", lw=0.3)
    bottom.set_xticks(x)
    bottom.set_xticklabels(
        [f"{s.t0:.1f}–{s.t1:.1f} s\n{s.label}" for s in found], rotation=30, ha="right", fontsize=8
    )
    return save_figure(fig, path)


# --------------------------------------------------------------------------- the folder


FIGURES: Final = {
    "progress_m": ("progress (start to end)", "m", "{:.3f}"),
    "progress_along_m": ("progress along the course", "m", "{:.3f}"),
    "distance_m": ("path length (sway included)", "m", "{:.3f}"),
    "mean_speed_mps": ("mean speed while moving (progress)", "m/s", "{:.3f}"),
    "energy_j": ("electric energy", "J", "{:.0f}"),
    "cost_of_transport": ("cost of transport (over the progress)", "", "{:.2f}"),
    "min_stability_margin_m": ("minimum stability margin", "m", "{:.3f}"),
    "gait_changes": ("gait changes", "", "{}"),
    "gait_selections": ("gait selector's choices", "", "{}"),
    "reflex_activations": ("reflex activations", "", "{}"),
    "falls": ("falls", "", "{}"),
    "sim_seconds": ("simulated time", "s", "{:.1f}"),
    "stopped_by": ("stopped early by", "", "{}"),
    "wall_seconds": ("wall time", "s", "{:.1f}"),
    "realtime_factor": ("real-time factor", "×", "{:.2f}"),
    "state_hash": ("state hash", "", "`{:.16}…`"),
}
"""The summary's figures: key → (label, unit, format), in the order they are shown."""


def format_figure(key: str, value: object) -> str:
    """One summary figure as text with its unit (``0.512 m``); ``—`` when there is none."""
    _, unit, fmt = FIGURES.get(key, (key, "", "{}"))
    if value is None:
        return "—"
    return f"{fmt.format(value)} {unit}".strip()


def reactive_timeline(result: SimResult) -> list[tuple[float, str]]:
    """What the reactive layer did, in time order: each gait the selector chose and why,
    each reflex's active spells, each servo lost and what the coordinator did about it."""
    out = [
        (e.t, f"gait selector: {e.before} → {e.after} ({e.reason})")
        for e in result.events
        if isinstance(e, GaitSelected)
    ]
    for name, spells in result.series.reflex_intervals().items():
        out += [(t0, f"reflex {name}: active for {t1 - t0:.1f} s") for t0, t1 in spells]
    for e in result.events:  # what the coordinator did about a lost servo
        if isinstance(e, JointLost):
            out.append((e.t, f"{_joint(e.leg, e.joint)} lost: {e.action}"))
        elif isinstance(e, JointBack):
            out.append((e.t, f"{_joint(e.leg, e.joint)} back"))
    return sorted(out)


def _joint(leg: int, joint: int) -> str:
    return f"{LEG_NAMES[leg]} {JOINT_NAMES[joint]}"


def summary_markdown(
    summary: dict[str, Any],
    found: Sequence[Segment],
    *,
    title: str = "Simulated run",
    timeline: Sequence[tuple[float, str]] = (),
) -> str:
    """``summary.md``: the figures and the segments as Markdown tables, then the reactive
    layer's ``timeline`` (:func:`reactive_timeline`)."""
    lines = [f"# {title}", "", "| figure | value |", "|---|---|"]
    for key, value in summary.items():
        if key == "stopped_by" and value is None:
            continue
        if key in FIGURES:
            lines.append(f"| {FIGURES[key][0]} | {format_figure(key, value)} |")
    lines += [
        "",
        "## Segments",
        "",
        "| from (s) | to (s) | command | progress (m) | path (m) | energy (J) "
        "| mean power (W) | CoT |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for s in found:
        cot = f"{s.cost_of_transport:.2f}" if s.cost_of_transport is not None else "—"
        lines.append(
            f"| {s.t0:.1f} | {s.t1:.1f} | {s.label} | {s.progress_m:.3f} | {s.distance_m:.3f} "
            f"| {s.energy_j:.0f} | {s.mean_power_w:.1f} | {cot} |"
        )
    lines += ["", "## The reactive layer", ""]
    if timeline:
        lines += ["| t (s) | what |", "|---|---|"]
        lines += [f"| {t:.1f} | {what} |" for t, what in timeline]
    else:
        lines.append("No gait chosen by the selector, no reflex active.")
    lines += [
        "",
        "Plots: `path.png`, `gait.png` (with the gait walked and the reflexes' spells), "
        "`joints.png`, `current.png`, `cot.png`.",
        "",
    ]
    return "\n".join(lines)


def write_report(
    result: SimResult,
    folder: str | Path,
    *,
    commands: Sequence[tuple[float, MotionCommand]] = (),
    name: str = "run",
    description: str = "",
) -> list[Path]:
    """Write the plots, ``summary.json`` and ``summary.md`` into ``folder``; their paths.

    ``commands`` (the scenario's timeline) splits the run into segments for the
    cost of transport; ``name`` and ``description`` title the report.
    """
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    summary = result.summary()
    found = segments(result.samples, commands, result.mass_kg)
    title = f"whexar sim: {name}"
    written = [
        plot_path(result, out / "path.png", title=f"{title}: path of the body centre, from above"),
        plot_gait(result, out / "gait.png"),
        plot_joints(result, out / "joints.png"),
        plot_currents(result, out / "current.png"),
        plot_cot(found, out / "cot.png"),
    ]
    doc = {
        "scenario": name,
        "description": description,
        **summary,
        "segments": [{**asdict(s), "mean_power_w": s.mean_power_w} for s in found],
    }
    json_path = out / "summary.json"
    # Strict JSON: a figure with no finite value (a margin of −∞) is null.
    json_path.write_text(_json.dumps(doc, indent=2) + "\n", encoding="utf-8")
    md_path = out / "summary.md"
    heading = title if not description else f"{title}\n\n{description}"
    md_path.write_text(
        summary_markdown(summary, found, title=heading, timeline=reactive_timeline(result)),
        encoding="utf-8",
    )
    return [*written, json_path, md_path]


__all__ = [
    "FIGURES",
    "PLOTTED_JOINTS",
    "Segment",
    "activity_intervals",
    "format_figure",
    "joint_traces",
    "leg_currents",
    "plot_cot",
    "plot_currents",
    "plot_gait",
    "plot_joints",
    "plot_path",
    "reactive_timeline",
    "segments",
    "summary_markdown",
    "swing_intervals",
    "write_report",
]
