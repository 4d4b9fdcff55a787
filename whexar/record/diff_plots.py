"""Two runs drawn over each other: the pictures of a ``--report`` (``whexar replay
--check --report DIR``, ``whexar log diff A B --report DIR``).

For each leg, one figure of its positioning joints (coxa … tarsus): the present
angle the servos reported and the goal the leg sent, of the first run (the
recording: solid) and the second (the replay or the other log: dashed), with a
mark where the time-aligned check first found the joint beyond tolerance; and one
figure of the events, each kind on a row, the first run's above the second's.
Both runs are read from their recordings (:func:`whexar.record.series.read_log`).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any, Final

from whexar.record.diff import LIFECYCLE, DiffReport, recorded_messages
from whexar.record.plots import figure_height, new_figure, save_figure
from whexar.record.series import joint_series, read_log
from whexar.robot import JOINT_NAMES, LEG_NAMES, POSITIONING_JOINTS
from whexar.runtime.messages import Event

__all__ = ["write_diff_plots"]

FIRST: Final = "C0"
SECOND: Final = "C3"


def write_diff_plots(
    first: str | os.PathLike[str],
    second: str | os.PathLike[str],
    folder: str | os.PathLike[str],
    report: DiffReport | None = None,
    *,
    labels: tuple[str, str] = ("recorded", "replayed"),
) -> list[Path]:
    """Write the comparison's PNGs into ``folder`` (made if need be); their paths."""
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    a, b = read_log(first), read_log(second)
    marks = _first_beyond(report)
    written = []
    for leg in range(len(LEG_NAMES)):
        written.append(_leg(a, b, leg, out, labels, marks))
    written.append(_events(first, second, out, labels))
    return written


def _first_beyond(report: DiffReport | None) -> dict[tuple[str, str], float]:
    """(leg name, joint name) → the first time a field of that joint was beyond tolerance."""
    marks: dict[tuple[str, str], float] = {}
    if report is None:
        return marks
    for row in report.fields:
        key, t = row.first_beyond_key, row.first_beyond_t
        if key is None or t is None or "joint " not in key or "leg " not in key:
            continue
        parts = key.split()
        leg, joint = parts[parts.index("leg") + 1], parts[parts.index("joint") + 1]
        if (leg, joint) not in marks or t < marks[(leg, joint)]:
            marks[(leg, joint)] = t
    return marks


def _leg(
    a: Any,
    b: Any,
    leg: int,
    out: Path,
    labels: tuple[str, str],
    marks: dict[tuple[str, str], float],
) -> Path:
    joints = list(range(len(POSITIONING_JOINTS)))
    fig, axes = new_figure(
        10.0, figure_height(len(joints), 1.6, 0.8), rows=len(joints), sharex=True
    )
    for ax, joint in zip(axes, joints, strict=True):
        for data, colour, label, style in (
            (a, FIRST, labels[0], "-"),
            (b, SECOND, labels[1], "--"),
        ):
            s = joint_series(data, leg, joint)
            if len(s.present_t):
                ax.plot(
                    s.present_t,
                    s.present_rad,
                    style,
                    color=colour,
                    lw=1.0,
                    label=f"{label} present",
                )
            if len(s.goal_t):
                ax.step(
                    s.goal_t,
                    s.goal_rad,
                    style,
                    where="post",
                    color=colour,
                    lw=0.6,
                    alpha=0.6,
                    label=f"{label} goal",
                )
        mark = marks.get((LEG_NAMES[leg], JOINT_NAMES[joint]))
        if mark is not None:
            ax.axvline(mark, color="k", lw=0.8, ls=":")
        ax.set_ylabel(f"{JOINT_NAMES[joint]} (rad)")
        ax.grid(alpha=0.3)
    axes[0].set_title(f"Leg {LEG_NAMES[leg]}: {labels[0]} (solid) against {labels[1]} (dashed)")
    axes[0].legend(loc="upper right", fontsize=7, ncol=4)
    axes[-1].set_xlabel("t (s)")
    return save_figure(fig, out / f"joints-{LEG_NAMES[leg]}.png")


def _events(
    first: str | os.PathLike[str],
    second: str | os.PathLike[str],
    out: Path,
    labels: tuple[str, str],
) -> Path:
    runs = [
        _event_times(recorded_messages(first, ["events"])),
        _event_times(recorded_messages(second, ["events"])),
    ]
    kinds = sorted(set(runs[0]) | set(runs[1]))
    fig, ax = new_figure(10.0, figure_height(max(1, len(kinds)), 0.35, 1.2))
    for row, kind in enumerate(kinds):
        for k, (times, colour) in enumerate(((runs[0], FIRST), (runs[1], SECOND))):
            ts = times.get(kind, [])
            ax.plot(ts, [row + 0.15 - 0.3 * k] * len(ts), "|", color=colour, ms=8)
    ax.set_yticks(range(len(kinds)))
    ax.set_yticklabels(kinds, fontsize=7)
    ax.set_xlabel("t (s)")
    ax.set_title(f"Events: {labels[0]} (upper, blue) against {labels[1]} (lower, red)")
    ax.grid(alpha=0.3, axis="x")
    return save_figure(fig, out / "events.png")


def _event_times(messages: Iterable[tuple[str, Any]]) -> dict[str, list[float]]:
    times: dict[str, list[float]] = {}
    for _, msg in messages:
        if isinstance(msg, Event) and not isinstance(msg, LIFECYCLE):
            times.setdefault(type(msg).__name__, []).append(msg.t)
    return times
