"""What the plots of a recording draw: the messages they need, read once, and their series.

:func:`read_log` reads a recording once (:class:`~whexar.record.reader.Recording`),
keeps the messages the plots need, picked by type rather than by channel name (a
wiring may name its channels otherwise), within an optional time window, and notes
where a file that was cut short ends: a :class:`LogData`. The functions below turn
it into plain series (:func:`joint_series`, :func:`currents`, :func:`power`,
:func:`cost_of_transport`, :func:`tilt`, the gait's :func:`swing_intervals`),
which :mod:`whexar.record.plots` draws; nothing here draws.
"""

from __future__ import annotations

import itertools
import math
import os
import tomllib
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

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
from whexar.robot import N_JOINTS, N_LEGS, joint_index, leg_index

SMOOTH_S: Final = 0.25
"""The moving mean of the current and power plots: the cycle-to-cycle ripple hides the trend."""
TRAVEL_STEP_S: Final = 1.0
"""The path is measured between points this far apart (a gait sways the body sideways and
back once a cycle, and that sway is not distance travelled)."""
MIN_COT_DISTANCE_M: Final = 0.1
"""The cost of transport is drawn only once the body has travelled this far: E/(m g d) of a
few centimetres is noise."""
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


def moving_mean(values: np.ndarray, t: np.ndarray, width_s: float = SMOOTH_S) -> np.ndarray:
    """A centred moving mean over about ``width_s`` (NaN counted as 0): the plots' smoothing."""
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


__all__ = [
    "MIN_COT_DISTANCE_M",
    "CurrentSeries",
    "JointSeries",
    "LogData",
    "Pose",
    "PowerSeries",
    "TiltSeries",
    "Trace",
    "activity_intervals",
    "cost_of_transport",
    "currents",
    "joint_series",
    "joint_traces",
    "leg_currents",
    "moving_mean",
    "parse_joints",
    "parse_legs",
    "plotted_joints",
    "power",
    "read_log",
    "swing_intervals",
    "tilt",
]
