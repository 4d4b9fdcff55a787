"""Plots of a recording: joint angles, currents, the gait diagram, tilt, power (``whexar plot``).

Theory of operation
-------------------
:func:`read_log` reads a recording once (:class:`~whexar.record.reader.Recording`),
keeps the messages the plots need, picked by type rather than by channel name (a
wiring may name its channels otherwise), within an optional time window, and notes
where a file that was cut short ends. :func:`write_plots` then draws from that
:class:`LogData`, nothing else:

* ``joints_leg{N}.png`` — per leg, goal against present angle of each joint, one
  subplot per joint, in degrees (thesis Fig. 6.2). Goals are the positions of the
  :class:`~whexar.actors.messages.JointGoals` addressed to (leg, joint), from any
  source (a reflex's goals too: the bus sends whichever is latest), drawn as steps;
  present angles come from the bus's :class:`~whexar.actors.messages.ServoStates`.
  By default the joints that have any position (goal or reading) in the window;
  the wheel has speed goals, no position goals;
* ``currents.png`` — |Present Current| of each servo over time, one subplot per leg
  with its total (the sum over all the leg's servos the bus read), and the mean per
  servo and leg over the window as grouped bars (Fig. 6.8);
* ``gait.png`` — the gait diagram (Fig. 3.3): a bar while the leg's
  :class:`~whexar.actors.messages.LegState` says ``swing``, over a band of the
  coordinator's activity (:class:`~whexar.actors.messages.LocomotionState`);
* ``tilt.png`` — body roll and pitch from :class:`~whexar.actors.messages.BodyTilt`,
  per accelerometer, and the body's true attitude where ``/tf`` holds it (simulation);
* ``power.png`` — electric power P = Σ V·|I| over the servos whose current the bus
  read, V the latest :class:`~whexar.actors.messages.ServoHealth` input voltage of the
  servo when recorded, else the configuration's supply voltage (the title says
  which); with the body's pose (``/tf``, world → base) also the cost of transport
  CoT = E / (m g d) from the window's start on (thesis 6.8.1), d measured between
  points a second apart so that the gait's sway is not counted as travel.

The data comes from :mod:`whexar.record.series` (re-exported here: ``whexar plot``'s
callers and :mod:`whexar.sim.report` import both from this module). A plot whose
data is missing is skipped, and the caller is told why. The drawing
functions (:func:`draw_gait`, :func:`draw_joints`, :func:`draw_leg_currents`) take
plain lists, so :mod:`whexar.sim.report` draws its report with them. matplotlib
draws with its Agg backend (no display); every figure is :data:`WIDTH_IN` wide at
:data:`DPI` dots per inch.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

import numpy as np

from whexar.errors import UsageError
from whexar.record.reader import Recording
from whexar.record.series import (
    MIN_COT_DISTANCE_M,
    CurrentSeries,
    JointSeries,
    LogData,
    Pose,
    PowerSeries,
    TiltSeries,
    Trace,
    activity_intervals,
    cost_of_transport,
    currents,
    joint_series,
    joint_traces,
    leg_currents,
    moving_mean,
    parse_joints,
    parse_legs,
    plotted_joints,
    power,
    read_log,
    swing_intervals,
    tilt,
)
from whexar.robot import JOINT_NAMES, LEG_NAMES, N_LEGS

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "DPI",
    "FIG_6_2_JOINTS",
    "WIDTH_IN",
    "CurrentSeries",
    "JointSeries",
    "LogData",
    "Pose",
    "PowerSeries",
    "TiltSeries",
    "activity_intervals",
    "cost_of_transport",
    "currents",
    "draw_gait",
    "draw_joints",
    "draw_leg_currents",
    "figure_height",
    "joint_series",
    "joint_traces",
    "leg_currents",
    "new_figure",
    "parse_joints",
    "parse_legs",
    "plot_log",
    "plotted_joints",
    "power",
    "read_log",
    "save_figure",
    "swing_intervals",
    "tilt",
    "write_plots",
]

DPI: Final = 110
WIDTH_IN: Final = 11.0
"""Every figure's width (inches): 1210 pixels at :data:`DPI`."""
FIG_6_2_JOINTS: Final = (0, 2, 3, 4)
"""The joints of thesis Fig. 6.2: coxa, femur, tibia, tarsus."""
GAIT_MIN_HEIGHT_IN: Final = 3.2
"""The gait diagram of one or two legs still has room for its legend."""
TIME_LABEL: Final = "time (s)"
GOAL_COLOUR: Final = "#d95f02"
PRESENT_COLOUR: Final = "#1b9e77"
SWING_COLOUR: Final = "#1f3b73"
REFLEX_COLOUR: Final = "#d6604d"
"""A reflex's active spells on the gait diagram."""
GAIT_COLOURS: Final = {
    "wheels": "#9ecae1",
    "tripod": "#a1d99b",
    "tetrapod": "#fdd49e",
    "ripple": "#fdae6b",
    "wave": "#e6550d",
}
"""The gait walked, least to most stable (Table 5.9's ranking), on the gait diagram."""
ACTIVITY_COLOURS: Final = {
    "seated": "#bbbbbb",
    "standing_up": "#d9c9a3",
    "sitting_down": "#d9c9a3",
    "standing": "#e8e8e8",
    "walking": "#a6cee3",
    "riding": "#b2df8a",
    "hybrid": "#cab2d6",
    "transition": "#fdbf6f",
    "flipping": "#fb9a99",
}
_JOINT_COLOURS: Final = (
    "#1b9e77",
    "#7570b3",
    "#d95f02",
    "#e7298a",
    "#66a61e",
    "#a6761d",
    "#666666",
)


# --------------------------------------------------------------------------- drawing


def figure_height(rows: int, per_row: float, extra: float) -> float:
    """A figure's height (inches): ``extra`` plus ``per_row`` for each of ``rows``."""
    return round(extra + per_row * rows, 2)


def new_figure(width: float, height: float, rows: int = 1, **kw: Any) -> tuple[Figure, Any]:
    """A figure of ``width`` × ``height`` inches with ``rows`` axes, one above the other
    (``kw``: :func:`matplotlib.pyplot.subplots`'s), drawn by the Agg backend."""
    import matplotlib

    matplotlib.use("Agg")  # no display: draw into memory, save as PNG
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(rows, 1, figsize=(width, height), **kw)
    return fig, axes


def save_figure(fig: Figure, path: Path) -> Path:
    """Lay ``fig`` out, write it to ``path`` as PNG at :data:`DPI`, close it; ``path``."""
    import matplotlib.pyplot as plt

    if fig.get_layout_engine() is None:
        fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def draw_gait(
    swings: Mapping[int, Sequence[tuple[float, float]]],
    activities: Sequence[tuple[float, float, str]],
    path: Path,
    *,
    window: tuple[float, float],
    legs: Sequence[int] | None = None,
    time_label: str = TIME_LABEL,
    title: str = "Gait diagram: dark bars = leg in swing; background = coordinator's activity",
    gaits: Sequence[tuple[float, float, str]] = (),
    reflexes: Mapping[str, Sequence[tuple[float, float]]] | None = None,
) -> Path:
    """The gait diagram (thesis Fig. 3.3): each leg's swings as bars, one row per leg (top:
    the first of ``legs``), over bands of the coordinator's activity; above them, when
    given, a row of the gait walked (``gaits``: start, end, gait or ``wheels``) and a row
    per reflex with its active spells (``reflexes``: name → (start, end))."""
    from matplotlib.patches import Patch

    rows = list(range(N_LEGS)) if legs is None else list(legs)
    named = sorted(reflexes or {})
    top = [*named, *(["gait"] if gaits else [])]
    n = len(rows)
    total = n + len(top)
    fig, ax = new_figure(WIDTH_IN, max(GAIT_MIN_HEIGHT_IN, figure_height(total, 0.5, 1.0)))
    for row, leg in enumerate(rows):
        bars = [(t0, t1 - t0) for t0, t1 in swings.get(leg, ())]
        ax.broken_barh(bars, (n - 1 - row + 0.15, 0.7), color=SWING_COLOUR, zorder=2)
    for t0, t1, activity in activities:
        ax.axvspan(t0, t1, color=ACTIVITY_COLOURS.get(activity, "#ffffff"), lw=0, zorder=0)
    if gaits:
        y = n + 0.15
        for t0, t1, gait in gaits:
            colour = GAIT_COLOURS.get(gait, "#999999")
            ax.broken_barh([(t0, t1 - t0)], (y, 0.7), color=colour, zorder=2)
            ax.text(t0, y + 0.35, f" {gait}", va="center", fontsize=7, clip_on=True, zorder=3)
    for k, name in enumerate(named):
        spells = [(t0, max(t1 - t0, 0.05)) for t0, t1 in (reflexes or {})[name]]
        y = n + (1 if gaits else 0) + k + 0.15
        ax.broken_barh(spells, (y, 0.7), color=REFLEX_COLOUR, zorder=2)
    if top:
        ax.axhline(n, color="#444444", lw=0.8, zorder=1)
    ax.set_xlim(*window)
    ax.set_ylim(0, total)
    labels = [f"{LEG_NAMES[leg]} ({leg})" for leg in rows]
    ticks = [n - 1 - row + 0.5 for row in range(n)]
    if gaits:
        ticks.append(n + 0.5)
        labels.append("gait")
    for k, name in enumerate(named):
        ticks.append(n + (1 if gaits else 0) + k + 0.5)
        labels.append(name)
    ax.set_yticks(ticks)
    ax.set_yticklabels(labels)
    ax.set_xlabel(time_label)
    ax.set_title(title)
    seen = dict.fromkeys(a for _, _, a in activities)
    handles = [Patch(color=ACTIVITY_COLOURS.get(a, "#ffffff"), label=a) for a in seen]
    handles.append(Patch(color=SWING_COLOUR, label="swing"))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
    ax.grid(True, axis="x", lw=0.3)
    return save_figure(fig, path)


def draw_joints(
    traces: Mapping[int, tuple[Trace, Trace]],
    path: Path,
    *,
    leg: int,
    time_label: str = TIME_LABEL,
    title: str = "",
    window: tuple[float, float] | None = None,
) -> Path:
    """Goal (steps) against present angle (line) of a leg's joints, one subplot per joint, in
    degrees (thesis Fig. 6.2); ``traces`` as :func:`joint_traces` gives them."""
    joints = list(traces)
    fig, axes = new_figure(
        WIDTH_IN, figure_height(len(joints), 1.8, 0.8), rows=len(joints), sharex=True, squeeze=False
    )
    axes = axes[:, 0]
    for ax, joint in zip(axes, joints, strict=True):
        goals, present = traces[joint]
        if goals:
            t, q = zip(*goals, strict=True)
            ax.step(t, np.degrees(q), where="post", color=GOAL_COLOUR, lw=1.0, label="goal")
        if present:
            t, q = zip(*present, strict=True)
            ax.plot(t, np.degrees(q), color=PRESENT_COLOUR, lw=1.0, label="present")
        missing = [
            what for what, got in (("position goal", goals), ("present angle", present)) if not got
        ]
        if missing:
            ax.text(
                0.01,
                0.9,
                f"not recorded: {', '.join(missing)}",
                transform=ax.transAxes,
                fontsize=8,
                va="top",
                color="#555555",
            )
        ax.set_ylabel(f"{JOINT_NAMES[joint]} (°)")
        ax.grid(True, lw=0.3)
        if goals or present:
            ax.legend(loc="upper right", fontsize=8)
    if window is not None:
        axes[0].set_xlim(*window)
    axes[0].set_title(title or f"Leg {leg} ({LEG_NAMES[leg]}): goal and present joint angles")
    axes[-1].set_xlabel(time_label)
    return save_figure(fig, path)


def draw_leg_currents(
    times: Sequence[float] | np.ndarray,
    amps: np.ndarray,
    path: Path,
    *,
    time_label: str = TIME_LABEL,
) -> Path:
    """Σ |Present Current| of each leg's servos per bus cycle, one row per leg (``amps``: one
    column per leg, as :func:`leg_currents` gives), light every cycle, dark a 0.25 s mean."""
    fig, axes = new_figure(WIDTH_IN, 8.0, rows=N_LEGS, sharex=True, sharey=True)
    t = np.asarray(times, dtype=float)
    for leg, ax in enumerate(axes):
        if len(t):
            ax.plot(t, amps[:, leg], color="#c6dbef", lw=0.5)
            ax.plot(t, moving_mean(amps[:, leg], t), color="#08519c", lw=1.0)
        ax.set_ylabel(f"{LEG_NAMES[leg]} (A)")
        ax.grid(True, lw=0.3)
    axes[0].set_title(
        "Current per leg: Σ |Present Current| of the leg's servos the bus reads "
        "(light: every cycle; dark: 0.25 s mean)"
    )
    axes[-1].set_xlabel(time_label)
    return save_figure(fig, path)


def _draw_currents(
    series: CurrentSeries,
    legs: Sequence[int],
    path: Path,
    *,
    window: tuple[float, float],
    note: str,
) -> Path:
    """Per leg: each servo's |current| (0.25 s mean) and the leg's total; then the mean per
    servo and leg as grouped bars (thesis Fig. 6.8)."""
    import matplotlib.pyplot as plt

    n = len(legs)
    plt.switch_backend("Agg")
    fig = plt.figure(figsize=(WIDTH_IN, figure_height(n, 1.6, 3.6)), layout="constrained")
    grid = fig.add_gridspec(n + 1, 1, height_ratios=[1.6] * n + [2.6])
    first = None
    t = series.t
    for row, leg in enumerate(legs):
        ax = fig.add_subplot(grid[row], sharex=first)
        first = first or ax
        for (lg, j), amps in series.per_servo.items():
            if lg == leg:
                ax.plot(
                    t, moving_mean(amps, t), color=_JOINT_COLOURS[j], lw=0.9, label=JOINT_NAMES[j]
                )
        if leg in series.per_leg:
            total = moving_mean(series.per_leg[leg], t)
            ax.plot(t, total, color="#000000", lw=1.2, label="leg total")
        ax.set_ylabel(f"{LEG_NAMES[leg]} (A)")
        ax.set_xlim(*window)
        ax.grid(True, lw=0.3)
        if row == 0:
            ax.set_title(
                "Current per servo and per leg: |Present Current|, 0.25 s mean "
                "(leg total: all its servos the bus read)" + note,
                fontsize=10,
            )
            ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
        if row < n - 1:
            ax.tick_params(labelbottom=False)
        else:
            ax.set_xlabel(TIME_LABEL)
    bars = fig.add_subplot(grid[n])
    joints = sorted({j for _, j in series.per_servo})
    width = 0.8 / max(1, len(joints))
    x = np.arange(n)
    for k, j in enumerate(joints):
        means = [series.mean(leg, j) if (leg, j) in series.per_servo else 0.0 for leg in legs]
        bars.bar(
            x + (k - (len(joints) - 1) / 2) * width,
            means,
            width,
            color=_JOINT_COLOURS[j],
            label=JOINT_NAMES[j],
        )
    bars.set_xticks(x)
    bars.set_xticklabels([f"{LEG_NAMES[leg]} ({leg})" for leg in legs])
    bars.set_ylabel("mean |current| (A)")
    bars.set_title(
        f"Mean current per servo, {window[0]:.1f}–{window[1]:.1f} s (thesis Fig. 6.8)", fontsize=10
    )
    bars.grid(True, axis="y", lw=0.3)
    if joints:
        bars.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
    return save_figure(fig, path)


def _draw_tilt(
    series: Sequence[TiltSeries], path: Path, *, window: tuple[float, float], note: str
) -> Path:
    fig, (top, bottom) = new_figure(WIDTH_IN, 5.5, rows=2, sharex=True)
    colours = {"imu": "#1b9e77", "board": "#d95f02", "world (/tf)": "#444444"}
    for s in series:
        style = {"color": colours.get(s.source, "#7570b3"), "lw": 0.9, "label": s.source}
        if s.source.startswith("world"):
            style["ls"] = "--"
        top.plot(s.t, np.degrees(s.roll), **style)
        bottom.plot(s.t, np.degrees(s.pitch), **style)
    top.set_ylabel("roll (°)")
    bottom.set_ylabel("pitch (°)")
    bottom.set_xlabel(TIME_LABEL)
    bottom.set_xlim(*window)
    for ax in (top, bottom):
        ax.grid(True, lw=0.3)
        ax.legend(loc="upper right", fontsize=8)
    top.set_title(
        "Body tilt: roll and pitch per accelerometer (BodyTilt); dashed: the world's" + note
    )
    return save_figure(fig, path)


def _draw_power(
    p: PowerSeries,
    cot: tuple[np.ndarray, np.ndarray, np.ndarray],
    path: Path,
    *,
    mass_kg: float,
    window: tuple[float, float],
    note: str,
) -> Path:
    t_cot, distance, values = cot
    rows = 2 if len(t_cot) else 1
    fig, axes = new_figure(
        WIDTH_IN, figure_height(rows, 3.0, 0.5), rows=rows, sharex=True, squeeze=False
    )
    top = axes[0, 0]
    top.plot(p.t, p.watts, color="#fdd0a2", lw=0.5, label="every bus cycle")
    top.plot(p.t, moving_mean(p.watts, p.t), color="#e6550d", lw=1.0, label="0.25 s mean")
    energy = float(p.energy_j[-1]) if len(p.t) else 0.0
    top.set_ylabel("electric power (W)")
    top.set_title(
        f"Electric power Σ V·|I| over the {p.servos} servos whose current was read, "
        f"E = {energy:.0f} J\n{p.voltage}" + note,
        fontsize=9,
    )
    top.grid(True, lw=0.3)
    top.legend(loc="upper right", fontsize=8)
    bottom = axes[-1, 0]
    if rows == 2:
        bottom.plot(t_cot, values, color="#3182bd", marker=".", lw=1.0, label="CoT since the start")
        bottom.set_ylabel("cost of transport E/(m g d)")
        twin = bottom.twinx()
        twin.plot(t_cot, distance, color="#999999", lw=0.8, ls="--", label="distance")
        twin.set_ylabel("distance travelled (m)")
        final = values[-1] if len(values) and math.isfinite(values[-1]) else None
        final_text = f"{final:.2f}" if final is not None else f"— (under {MIN_COT_DISTANCE_M:g} m)"
        bottom.set_title(
            f"Cost of transport from the window's start on (m = {mass_kg:g} kg): "
            f"{final_text} over {distance[-1]:.2f} m",
            fontsize=9,
        )
        lines = bottom.get_legend_handles_labels()
        more = twin.get_legend_handles_labels()
        bottom.legend(lines[0] + more[0], lines[1] + more[1], loc="upper right", fontsize=8)
        bottom.grid(True, lw=0.3)
    bottom.set_xlim(*window)
    bottom.set_xlabel(TIME_LABEL)
    return save_figure(fig, path)


# --------------------------------------------------------------------------- the folder


def write_plots(
    recording_path: str | os.PathLike[str] | Recording,
    out_dir: str | os.PathLike[str],
    *,
    legs: Iterable[str | int] | None = None,
    joints: Iterable[str | int] | None = None,
    t_from: float | None = None,
    t_to: float | None = None,
    say: Callable[[str], object] | None = None,
) -> list[Path]:
    """Write the PNGs of a recording into ``out_dir`` (made if missing); their paths.

    ``legs`` (numbers 0–5 or names), ``joints`` (names or numbers 0–6) and the window
    ``t_from`` … ``t_to`` (s) select what is drawn (see the module docstring for the
    plots). ``say`` is told every plot skipped for want of data, and where a recording
    cut short ends. Raises :class:`~whexar.errors.UsageError` for a bad leg, joint or
    window, or a file that is not a readable whexar recording.
    """
    leg_list = parse_legs(legs)
    joint_list = parse_joints(joints)
    data = read_log(recording_path, t_from=t_from, t_to=t_to)
    return plot_log(data, out_dir, legs=leg_list, joints=joint_list, say=say)


def plot_log(
    data: LogData,
    out_dir: str | os.PathLike[str],
    *,
    legs: Sequence[int] | None = None,
    joints: Sequence[int] | None = None,
    say: Callable[[str], object] | None = None,
) -> list[Path]:
    """:func:`write_plots` for a recording already read (:func:`read_log`)."""
    tell: Callable[[str], object] = say or (lambda _: None)
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"cannot make {out}/: {exc.strerror or exc}") from None
    legs = list(range(N_LEGS)) if legs is None else list(legs)
    window = (data.t0, data.t1)
    note = ""
    if data.ended is not None:
        end = f"t = {data.last_t:.2f} s" if data.last_t is not None else "its start"
        note = f"\n(the recording ends early, at {end}: cut short)"
        tell(data.ended)
    written: list[Path] = []

    def skip(name: str, why: str) -> None:
        tell(f"skipped {name}: {why}")

    # joints_leg{N}.png (Fig. 6.2)
    for leg in legs:
        name = f"joints_leg{leg}.png"
        traces = joint_traces(data.goals, data.servo_states, leg, plotted_joints(data, leg, joints))
        if not any(g or p for g, p in traces.values()):
            skip(name, f"no position goal or reading of leg {leg} ({LEG_NAMES[leg]})")
            continue
        title = (
            f"Leg {leg} ({LEG_NAMES[leg]}): goal (JointGoals) and present (ServoStates) joint "
            f"angles (thesis Fig. 6.2){note}"
        )
        written.append(draw_joints(traces, out / name, leg=leg, title=title, window=window))
    # currents.png (Fig. 6.8)
    found = currents(data, legs, joints)
    if found.per_servo:
        written.append(_draw_currents(found, legs, out / "currents.png", window=window, note=note))
    else:
        skip("currents.png", "no servo current recorded for the selected legs and joints")
    # gait.png (Fig. 3.3)
    if data.legs:
        title = (
            "Gait diagram (thesis Fig. 3.3): dark bars = leg in swing (LegState); "
            "background = coordinator's activity (LocomotionState)" + note
        )
        written.append(
            draw_gait(
                swing_intervals(data.legs),
                activity_intervals(data.locomotion),
                out / "gait.png",
                window=window,
                legs=legs,
                title=title,
            )
        )
    else:
        skip("gait.png", "no LegState recorded")
    # tilt.png
    if data.tilts:
        written.append(_draw_tilt(tilt(data), out / "tilt.png", window=window, note=note))
    else:
        skip("tilt.png", "no BodyTilt recorded")
    # power.png
    p = power(data)
    if p.servos:
        cot = cost_of_transport(data, p)
        if not len(cot[0]):
            skip("the cost of transport in power.png", "no body pose (/tf, world → base)")
        written.append(
            _draw_power(p, cot, out / "power.png", mass_kg=data.mass_kg, window=window, note=note)
        )
    else:
        skip("power.png", "no servo current recorded")
    return written
