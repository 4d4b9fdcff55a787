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

A plot whose data is missing is skipped, and the caller is told why. The drawing
functions (:func:`draw_gait`, :func:`draw_joints`, :func:`draw_leg_currents`) take
plain lists, so :mod:`whexar.sim.report` draws its report with them. matplotlib
draws with its Agg backend (no display); every figure is :data:`WIDTH_IN` wide at
:data:`DPI` dots per inch.
"""

from __future__ import annotations

import itertools
import math
import os
import tomllib
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

import numpy as np

from whexar.actors.messages import (
    BodyTilt,
    JointGoals,
    LegState,
    LocomotionState,
    ServoHealth,
    ServoStates,
)
from whexar.config import RobotConfig, parse_config
from whexar.errors import ConfigError, UsageError
from whexar.kinematics.body import quat_rpy
from whexar.record.reader import Recording
from whexar.robot import JOINT_NAMES, LEG_NAMES, N_JOINTS, N_LEGS, joint_index, leg_index

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
SMOOTH_S: Final = 0.25
"""The moving mean of the current and power plots: the cycle-to-cycle ripple hides the trend."""
TRAVEL_STEP_S: Final = 1.0
"""The path is measured between points this far apart (a gait sways the body sideways and
back once a cycle, and that sway is not distance travelled)."""
MIN_COT_DISTANCE_M: Final = 0.1
"""The cost of transport is drawn only once the body has travelled this far: E/(m g d) of a
few centimetres is noise."""
GOAL_COLOUR: Final = "#d95f02"
PRESENT_COLOUR: Final = "#1b9e77"
SWING_COLOUR: Final = "#1f3b73"
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
_FRAME_TRANSFORMS: Final = "foxglove.FrameTransforms"

Trace = list[tuple[float, float]]
"""(t, value) pairs."""


# --------------------------------------------------------------------------- data from messages


def swing_intervals(states: Iterable[LegState]) -> dict[int, list[tuple[float, float]]]:
    """Per leg, the (start, end) times it was in swing, from its LegState messages.

    A swing still going at the last message ends there."""
    out: dict[int, list[tuple[float, float]]] = {leg: [] for leg in range(N_LEGS)}
    started: dict[int, float] = {}
    last_t = 0.0
    for m in states:
        last_t = m.t
        if m.phase == "swing":
            started.setdefault(m.leg, m.t)
        elif m.leg in started:
            out[m.leg].append((started.pop(m.leg), m.t))
    for leg, t0 in started.items():
        out[leg].append((t0, last_t))
    return out


def activity_intervals(states: Iterable[LocomotionState]) -> list[tuple[float, float, str]]:
    """(start, end, activity) of the coordinator, from its LocomotionState messages."""
    out: list[tuple[float, float, str]] = []
    for m in states:
        if out and out[-1][2] == m.activity:
            out[-1] = (out[-1][0], m.t, m.activity)
        else:
            if out:
                out[-1] = (out[-1][0], m.t, out[-1][2])
            out.append((m.t, m.t, m.activity))
    return out


def joint_traces(
    goals: Iterable[JointGoals],
    states: Iterable[ServoStates],
    leg: int,
    joints: Sequence[int],
    *,
    source: str | None = None,
) -> dict[int, tuple[Trace, Trace]]:
    """For each of ``joints`` of ``leg``: (goals, present angles) as (t, rad) lists.

    Goals are position goals only (a wheel's speed goal has none); with ``source``,
    only the goals that actor sent."""
    goal: dict[int, Trace] = {j: [] for j in joints}
    present: dict[int, Trace] = {j: [] for j in joints}
    for msg in goals:
        if source is not None and msg.source != source:
            continue
        for g in msg.goals:
            if g.leg == leg and g.joint in goal and g.position_rad is not None:
                goal[g.joint].append((msg.t, g.position_rad))
    for s in states:
        for js in s.joints:
            if js.leg == leg and js.joint in present and js.position_rad is not None:
                present[js.joint].append((s.t, js.position_rad))
    return {j: (goal[j], present[j]) for j in joints}


def leg_currents(states: Iterable[ServoStates]) -> tuple[list[float], np.ndarray]:
    """Bus cycle times and, per cycle and leg, Σ |Present Current| of the leg's servos (A)."""
    times: list[float] = []
    rows: list[list[float]] = []
    for s in states:
        row = [0.0] * N_LEGS
        for js in s.joints:
            if js.current_a is not None:
                row[js.leg] += abs(js.current_a)
        times.append(s.t)
        rows.append(row)
    return times, np.array(rows, dtype=float).reshape(-1, N_LEGS)


def _servo_amps(states: Sequence[ServoStates]) -> tuple[np.ndarray, np.ndarray]:
    """Cycle times and |Present Current| per cycle, leg and joint (A; NaN: not read)."""
    t = np.array([s.t for s in states], dtype=float)
    amps = np.full((len(states), N_LEGS, N_JOINTS), np.nan)
    for k, s in enumerate(states):
        for js in s.joints:
            if js.current_a is not None:
                amps[k, js.leg, js.joint] = abs(js.current_a)
    return t, amps


def _moving_mean(values: np.ndarray, t: np.ndarray, width_s: float = SMOOTH_S) -> np.ndarray:
    """A centred moving mean over about ``width_s`` (NaN counted as 0)."""
    width = 1
    if len(t) > 1:
        width = max(1, round(width_s / float(np.median(np.diff(t)))))
    kernel = np.ones(width) / width
    return np.convolve(np.nan_to_num(values), kernel, mode="same")


# --------------------------------------------------------------------------- a recording


@dataclass(frozen=True)
class Pose:
    """The body's pose in the world (``/tf``, world → base): position (m), roll, pitch (rad)."""

    t: float
    x: float
    y: float
    z: float
    roll: float
    pitch: float


@dataclass
class LogData:
    """What the plots need from one recording, within the window ``t0`` … ``t1`` (s)."""

    path: Path
    t0: float
    t1: float
    goals: list[JointGoals] = field(default_factory=list)
    servo_states: list[ServoStates] = field(default_factory=list)
    legs: list[LegState] = field(default_factory=list)
    locomotion: list[LocomotionState] = field(default_factory=list)
    tilts: list[BodyTilt] = field(default_factory=list)
    health: list[ServoHealth] = field(default_factory=list)
    poses: list[Pose] = field(default_factory=list)
    ended: str | None = None
    """Where a recording that was cut short ends (:meth:`Recording.describe_end`)."""
    last_t: float | None = None
    """Time of the last message read: the last readable one of a recording cut short, the
    first after the window if the recording goes on."""
    supply_voltage_v: float = 12.0
    mass_kg: float = 1.0
    gravity_m_s2: float = 9.81
    config_source: str = "the built-in configuration"
    """Where the supply voltage and the mass come from."""


def _config(recording: Recording) -> tuple[RobotConfig, str]:
    """The robot configuration the recording carries (``config.toml``), else the built-in."""
    attached = recording.attachments.get("config.toml")
    if attached is not None:
        try:
            return (
                parse_config(tomllib.loads(attached.text), "config.toml"),
                "the recording's config.toml",
            )
        except (tomllib.TOMLDecodeError, ConfigError):
            pass  # a configuration this whexar does not read: the defaults will do
    return RobotConfig(), "the built-in configuration"


def _pose(t: float, value: Any) -> Pose | None:
    """The world → base transform of a ``foxglove.FrameTransforms`` message, if it has one."""
    if not isinstance(value, Mapping):
        return None
    for tf in value.get("transforms", ()):
        if tf.get("parent_frame_id") == "world" and tf.get("child_frame_id") == "base":
            p, q = tf["translation"], tf["rotation"]
            roll, pitch, _ = quat_rpy(q["w"], q["x"], q["y"], q["z"])
            return Pose(t, float(p["x"]), float(p["y"]), float(p["z"]), roll, pitch)
    return None


def read_log(
    recording: Recording | str | os.PathLike[str],
    *,
    t_from: float | None = None,
    t_to: float | None = None,
) -> LogData:
    """Read what the plots need from ``recording``, the messages in ``t_from`` … ``t_to`` (s).

    Raises :class:`~whexar.record.encoding.RecordingError` (a
    :class:`~whexar.errors.UsageError`) for a file that is not a whexar recording of this
    version, and :class:`~whexar.errors.UsageError` for a window that is empty or holds
    no message. A recording cut short is read up to where it ends (:attr:`LogData.ended`).
    """
    if t_from is not None and t_to is not None and t_to <= t_from:
        raise UsageError(f"--to {t_to:g} s is not after --from {t_from:g} s")
    rec = recording if isinstance(recording, Recording) else Recording(recording)
    rec.check_compatible()
    cfg, source = _config(rec)
    lo = -math.inf if t_from is None else t_from
    hi = math.inf if t_to is None else t_to
    kept: dict[type, list[Any]] = {
        JointGoals: [],
        ServoStates: [],
        LegState: [],
        LocomotionState: [],
        BodyTilt: [],
        ServoHealth: [],
    }
    poses: list[Pose] = []
    first: float | None = None
    last: float | None = None
    seen: float | None = None
    for record in rec.records():  # in time order: stop after the window
        t = record.t
        seen = t
        if t > hi:
            break
        if t < lo:
            continue
        first = t if first is None else first
        last = t
        bucket = kept.get(type(record.value))
        if bucket is not None:
            bucket.append(record.value)
        elif record.schema == _FRAME_TRANSFORMS:
            pose = _pose(t, record.value)
            if pose is not None:
                poses.append(pose)
    ended = rec.describe_end() if rec.damage is not None else None
    if rec.damage is not None and rec.damage.last_ns is not None:
        seen = rec.damage.last_ns / 1e9
    if first is None or last is None:
        span = "it has none" if seen is None else f"its last is at t = {seen:.3f} s"
        window = f"{'the start' if t_from is None else f'{t_from:g} s'} … " + (
            "the end" if t_to is None else f"{t_to:g} s"
        )
        raise UsageError(f"{rec.path}: no message between {window} ({span})")
    return LogData(
        path=rec.path,
        t0=first if t_from is None else t_from,
        t1=last if t_to is None else min(t_to, seen if seen is not None else t_to),
        goals=kept[JointGoals],
        servo_states=kept[ServoStates],
        legs=kept[LegState],
        locomotion=kept[LocomotionState],
        tilts=kept[BodyTilt],
        health=kept[ServoHealth],
        poses=poses,
        ended=ended,
        last_t=seen,
        supply_voltage_v=cfg.robot.supply_voltage_v,
        mass_kg=cfg.robot.mass_kg,
        gravity_m_s2=cfg.robot.gravity_m_s2,
        config_source=source,
    )


# --------------------------------------------------------------------------- series for the plots


def _pick(
    values: Iterable[str | int] | None, index: Callable[[int | str], int], n: int
) -> list[int]:
    if values is None:
        return list(range(n))
    out: list[int] = []
    for value in values:
        for part in str(value).split(",") if isinstance(value, str) else [value]:
            if isinstance(part, str):
                part = part.strip()
                if not part:
                    continue
                if part.isdigit():
                    part = int(part)
            i = index(part)
            if i not in out:
                out.append(i)
    return sorted(out)


def parse_legs(values: Iterable[str | int] | None) -> list[int]:
    """Leg indices from numbers 0–5 or names (``RF`` …, commas allowed); ``None``: all six.

    Raises :class:`~whexar.errors.UsageError` naming a bad value and what is allowed."""
    return _pick(values, leg_index, N_LEGS)


def parse_joints(values: Iterable[str | int] | None) -> list[int] | None:
    """Joint indices from names (``coxa`` …, commas allowed) or numbers 0–6; ``None`` stays
    ``None`` (each plot's default). Raises :class:`~whexar.errors.UsageError` naming a bad
    value and what is allowed."""
    return None if values is None else _pick(values, joint_index, N_JOINTS)


@dataclass(frozen=True)
class JointSeries:
    """Goal and present angle of one joint (rad), each with its own times (s)."""

    leg: int
    joint: int
    goal_t: np.ndarray
    goal_rad: np.ndarray
    present_t: np.ndarray
    present_rad: np.ndarray

    @property
    def empty(self) -> bool:
        """Neither a position goal nor a reading."""
        return len(self.goal_t) == 0 and len(self.present_t) == 0


def joint_series(data: LogData, leg: int | str, joint: int | str) -> JointSeries:
    """Goal (from :class:`JointGoals`) and present (from :class:`ServoStates`) angle of one
    joint in the window (Fig. 6.2)."""
    leg_i, joint_i = leg_index(leg), joint_index(joint)
    goals, present = joint_traces(data.goals, data.servo_states, leg_i, [joint_i])[joint_i]
    gt, gq = _columns(goals)
    pt, pq = _columns(present)
    return JointSeries(leg_i, joint_i, gt, gq, pt, pq)


def _columns(trace: Trace) -> tuple[np.ndarray, np.ndarray]:
    if not trace:
        return np.zeros(0), np.zeros(0)
    a = np.array(trace, dtype=float)
    return a[:, 0], a[:, 1]


def plotted_joints(data: LogData, leg: int, joints: Sequence[int] | None = None) -> list[int]:
    """The joints of ``leg`` that ``joints_leg{N}.png`` shows: ``joints`` if given, else
    every joint with a position goal or a present angle in the window."""
    if joints is not None:
        return list(joints)
    found: set[int] = set()
    for msg in data.goals:
        found.update(g.joint for g in msg.goals if g.leg == leg and g.position_rad is not None)
    for s in data.servo_states:
        found.update(js.joint for js in s.joints if js.leg == leg and js.position_rad is not None)
        if len(found) == N_JOINTS:
            break
    return sorted(found)


@dataclass(frozen=True)
class CurrentSeries:
    """|Present Current| (A) at the bus cycles ``t`` (s): per servo, as (leg, joint) → values
    (only servos whose current was read), and per leg, the sum over all its servos read."""

    t: np.ndarray
    per_servo: dict[tuple[int, int], np.ndarray]
    per_leg: dict[int, np.ndarray]

    def mean(self, leg: int, joint: int) -> float:
        """Mean |current| of one servo over the window (A)."""
        return float(np.mean(self.per_servo[leg, joint]))


def currents(
    data: LogData, legs: Sequence[int] | None = None, joints: Sequence[int] | None = None
) -> CurrentSeries:
    """The currents of the selected legs and joints (default: all that were read; Fig. 6.8)."""
    t, amps = _servo_amps(data.servo_states)
    legs = list(range(N_LEGS)) if legs is None else list(legs)
    joints = list(range(N_JOINTS)) if joints is None else list(joints)
    per_servo = {
        (leg, j): amps[:, leg, j]
        for leg in legs
        for j in joints
        if len(t) and not np.all(np.isnan(amps[:, leg, j]))
    }
    per_leg = {leg: np.nansum(amps[:, leg, :], axis=1) for leg in legs if len(t)}
    return CurrentSeries(t, per_servo, per_leg)


@dataclass(frozen=True)
class PowerSeries:
    """Electric power P = Σ V·|I| (W) at the bus cycles ``t`` (s), and where V came from."""

    t: np.ndarray
    watts: np.ndarray
    voltage: str
    """``ServoHealth`` or the configuration's supply voltage, as a phrase for the title."""
    servos: int
    """How many servos' current the bus read (the sum is over these)."""

    @property
    def energy_j(self) -> np.ndarray:
        """Electric energy from the first cycle on (J), at each cycle (trapezoids)."""
        if len(self.t) < 2:
            return np.zeros(len(self.t))
        steps = 0.5 * (self.watts[1:] + self.watts[:-1]) * np.diff(self.t)
        return np.concatenate([[0.0], np.cumsum(steps)])


def power(data: LogData) -> PowerSeries:
    """Σ V·|I| over the servos whose current the bus read, each cycle.

    V is a servo's latest :class:`ServoHealth` input voltage (before it has one: the
    mean of the latest readings of the others) when the recording has any, else the
    configuration's supply voltage."""
    t, amps = _servo_amps(data.servo_states)
    read = ~np.isnan(amps)
    servos = int(np.any(read, axis=0).sum()) if len(t) else 0
    flat = np.nan_to_num(amps)
    readings = [h for h in data.health if h.voltage_v is not None]
    if not readings:
        volts = np.full_like(flat, data.supply_voltage_v)
        phrase = (
            f"V = {data.supply_voltage_v:g} V, the supply voltage of {data.config_source} "
            "(no ServoHealth voltage recorded)"
        )
        return PowerSeries(t, (volts * flat).sum(axis=(1, 2)), phrase, servos)
    ids = {(js.leg, js.joint): js.servo_id for s in data.servo_states[:1] for js in s.joints}
    latest: dict[int, float] = {}
    volts = np.full_like(flat, data.supply_voltage_v)
    k = 0
    for row, ts in enumerate(t):
        while k < len(readings) and readings[k].t <= ts:
            latest[readings[k].servo_id] = float(readings[k].voltage_v or 0.0)
            k += 1
        if latest:
            fallback = sum(latest.values()) / len(latest)
            for (leg, j), sid in ids.items():
                volts[row, leg, j] = latest.get(sid, fallback)
    phrase = "V = each servo's input voltage from ServoHealth"
    return PowerSeries(t, (volts * flat).sum(axis=(1, 2)), phrase, servos)


def cost_of_transport(data: LogData, p: PowerSeries) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, distance m, CoT) from the window's start on: d measured between poses a second
    apart (:data:`TRAVEL_STEP_S`), E the electric energy of ``p`` up to t, CoT = E / (m g d)
    (NaN while d < :data:`MIN_COT_DISTANCE_M`). Empty without poses or power."""
    poses = data.poses
    if len(poses) < 2 or len(p.t) < 2:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    points = [poses[0]]
    for pose in poses[1:]:
        if pose.t - points[-1].t >= TRAVEL_STEP_S - 1e-9:
            points.append(pose)
    if points[-1] is not poses[-1]:
        points.append(poses[-1])
    t = np.array([q.t for q in points])
    steps = [math.hypot(b.x - a.x, b.y - a.y) for a, b in itertools.pairwise(points)]
    distance = np.concatenate([[0.0], np.cumsum(steps)])
    energy = np.interp(t, p.t, p.energy_j) - np.interp(t[0], p.t, p.energy_j)
    with np.errstate(divide="ignore", invalid="ignore"):
        cot = energy / (data.mass_kg * data.gravity_m_s2 * distance)
    cot[distance < MIN_COT_DISTANCE_M] = np.nan
    return t, distance, cot


@dataclass(frozen=True)
class TiltSeries:
    """Body roll and pitch (rad) at times ``t`` (s) from one source: an accelerometer
    (``board``, ``imu``) or the world (``/tf``)."""

    source: str
    t: np.ndarray
    roll: np.ndarray
    pitch: np.ndarray


def tilt(data: LogData) -> list[TiltSeries]:
    """Roll and pitch per accelerometer (:class:`BodyTilt`), and from ``/tf`` if recorded."""
    out: list[TiltSeries] = []
    for sensor in sorted({m.sensor for m in data.tilts}):
        ms = [m for m in data.tilts if m.sensor == sensor]
        out.append(
            TiltSeries(
                sensor,
                np.array([m.t for m in ms]),
                np.array([m.roll_rad for m in ms]),
                np.array([m.pitch_rad for m in ms]),
            )
        )
    if data.poses:
        out.append(
            TiltSeries(
                "world (/tf)",
                np.array([q.t for q in data.poses]),
                np.array([q.roll for q in data.poses]),
                np.array([q.pitch for q in data.poses]),
            )
        )
    return out


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
) -> Path:
    """The gait diagram (thesis Fig. 3.3): each leg's swings as bars, one row per leg (top:
    the first of ``legs``), over bands of the coordinator's activity."""
    from matplotlib.patches import Patch

    rows = list(range(N_LEGS)) if legs is None else list(legs)
    n = len(rows)
    fig, ax = new_figure(WIDTH_IN, max(GAIT_MIN_HEIGHT_IN, figure_height(n, 0.5, 1.0)))
    for row, leg in enumerate(rows):
        bars = [(t0, t1 - t0) for t0, t1 in swings.get(leg, ())]
        ax.broken_barh(bars, (n - 1 - row + 0.15, 0.7), color=SWING_COLOUR, zorder=2)
    for t0, t1, activity in activities:
        ax.axvspan(t0, t1, color=ACTIVITY_COLOURS.get(activity, "#ffffff"), lw=0, zorder=0)
    ax.set_xlim(*window)
    ax.set_ylim(0, n)
    ax.set_yticks([n - 1 - row + 0.5 for row in range(n)])
    ax.set_yticklabels([f"{LEG_NAMES[leg]} ({leg})" for leg in rows])
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
            ax.plot(t, _moving_mean(amps[:, leg], t), color="#08519c", lw=1.0)
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
                    t, _moving_mean(amps, t), color=_JOINT_COLOURS[j], lw=0.9, label=JOINT_NAMES[j]
                )
        if leg in series.per_leg:
            total = _moving_mean(series.per_leg[leg], t)
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
    top.plot(p.t, _moving_mean(p.watts, p.t), color="#e6550d", lw=1.0, label="0.25 s mean")
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
