"""The thesis's experiments (6.4–6.8) as a campaign: their metrics and their report.

Theory of operation
-------------------
The campaign ``config/campaigns/experiments.toml`` repeats in simulation what
Žák 2023 measured on WHexaR: the tripod gait on the flat (6.4, 6.8.1), riding
straight, sideways, spinning in place and along a circle (6.5), the static
stances of Table 6.6 and the movements of Table 6.7 on slopes, with and
without the trochanter (6.8), and the steepest slope walked, ridden and stood
on (6.7.6). Its runs carry labels (``stance-1``, ``tripod``, ``circle`` …)
and, where they vary them, the keys :data:`SLOPE_KEY` and
:data:`TROCHANTER_KEY`; :func:`figures` finds the rows it needs by them.

*Metrics.* This module registers the experiments' own metrics
(:func:`~whexar.campaign.metrics.metric`): the total servo current of
eq. 6.1–6.3 over all 42 servos, the speed up the plane, the cost of transport
as the thesis computes it (eq. 6.4–6.5), the gait period, the time to cover
the 2 m track, the direction of travel, the spin rate and the circle's return
error. Each reads only the run (its samples and its message log), so the
campaign's rows stay deterministic.

*The total current.* The thesis sums each servo's mean |Present Current|
(eq. 6.1) over the servos of a leg (eq. 6.2) and over the legs (eq. 6.3).
The simulation's default read plan reads the current of only 24 servos
(coxa, femur, tibia, tarsus): the generic ``mean_current_a`` sums those. The
world knows every motor's current (its Present Current is τ/kₜ, the same
number): the sampled electric power Σ V·|I| over the supply voltage is that
sum over all 42 servos, so :func:`total_current_a` is the one compared with
the thesis.

*Figures.* :func:`figures` turns the rows into :class:`Figure` s: a name, a
unit, the thesis's figure (a number, a range as text, or ``None`` where the
thesis gives none), the simulation's (a number, ``"not simulated"``, or
``None`` when the run failed or the value is undefined) and a note. Where the
two differ by more than the figure's tolerance, the note gives the reason we
believe in, chosen by the direction of the difference; every number in the
note comes from the rows.

*Outcomes of the sweep.* A tripod or riding run *made it* when the robot did
not fall, kept its heading within :data:`MAX_HEADING_CHANGE_DEG` and went up
the plane at no less than :data:`MIN_PROGRESS_FRACTION` of the commanded
speed (the thesis counts 0.07 m/s of 0.12 m/s at 32° as walking, Table 6.7);
a static stance *held* when the robot did not fall and slid less than
:data:`MAX_SLIDE_M` over its window. The steepest slope is the highest tested
slope with every tested slope up to it made.

:func:`write_report` writes ``experiments.md`` (the table) and the plots in
``img/experiments/`` under the report folder, so the folder's Markdown and
images can be copied into ``docs/`` as they are.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from whexar.actors.messages import LegState
from whexar.campaign.metrics import G, Value, Window, mean_power, metric, servo_currents
from whexar.record.plots import new_figure, save_figure
from whexar.robot import JOINT_NAMES
from whexar.sim.run import FALLEN_TILT_RAD

if TYPE_CHECKING:
    from whexar.campaign.rows import Row
    from whexar.sim.run import Sample, SimResult

# --------------------------------------------------------------------------- the campaign's keys

SLOPE_KEY: Final = "terrain.slope_deg"
"""The variation key of the plane's slope (absent: the flat)."""
TROCHANTER_KEY: Final = "config.locomotion.trochanter_follows_pitch"
"""The variation key of "with/without the trochanter" (eq. 4.18; absent: the default, on)."""
STANCE_LABELS: Final = {1: "stance-1", 2: "stance-2", 3: "stance-3"}
"""Table 6.6's stances No. 1–3, by the labels of their runs."""
TRIPOD: Final = "tripod"
WHEELS: Final = "wheels"
STRAIGHT: Final = "straight"
SIDEWAYS: Final = {45: "sideways+45", -45: "sideways-45"}
SPIN: Final = "spin"
CIRCLE: Final = "circle"

TABLE_6_6_SLOPES_DEG: Final = (0, 14, 23, 32, 40, 50)
"""The slopes of Table 6.6."""
MAX_BODY_PITCH_DEG: Final = 20.0
"""The coordinator's limit on a commanded body pitch (``_limit`` of ``pitch_rad``): stance
No. 2 levels the body by pitching it, so it cannot be expressed on steeper slopes."""
MAX_TROCHANTER_DEG: Final = 45.0
"""The coordinator's limit on the trochanter's follow of the pitch (``MAX_TROCHANTER``)."""

# --------------------------------------------------------------------------- outcome thresholds

MIN_PROGRESS_FRACTION: Final = 0.25
"""A movement made it up the plane at ≥ this share of its commanded speed. The thesis
counts 0.07 m/s of the commanded 0.12 m/s at 32° as walking (Table 6.7): 58 %."""
MAX_HEADING_CHANGE_DEG: Final = 30.0
"""… and turned less than this: a robot swung round by slipping feet did not climb."""
MAX_SLIDE_M: Final = 0.02
"""A static stance held when the body moved less than this over its window (3 s)."""
TRACK_M: Final = 2.0
"""The track of 6.5.1 and 6.5.2: 2 m."""
CIRCLE_LAPS: Final = 2
"""The circle of 6.5.2 was driven twice round."""
MOVING_M: Final = 0.01
"""The track's clock starts when the body has moved this far from where it stood."""
TOP_SPEED_SPAN_S: Final = 1.0
"""Top speed: the largest displacement over this span, over the span."""

# --------------------------------------------------------------------------- metrics


def _supply_voltage(result: SimResult) -> float:
    return float(result.world.cfg.robot.supply_voltage_v)


@metric(
    "total_current_a",
    "A",
    "total servo current, thesis eq. 6.1–6.3, over all 42 servos: the motors' mean Σ|I| "
    "(electric power Σ V·|I| over the supply voltage)",
)
def total_current_a(result: SimResult, window: Window) -> Value:
    """Σ over every servo of its mean |current| in the window (eq. 6.1–6.3), A."""
    power = mean_power(window.samples(result))
    return None if power is None else power / _supply_voltage(result)


def _unwrapped_yaw(samples: Sequence[Sample]) -> list[float]:
    out: list[float] = []
    for s in samples:
        if not out:
            out.append(s.yaw)
            continue
        step = (s.yaw - out[-1] + math.pi) % (2 * math.pi) - math.pi
        out.append(out[-1] + step)
    return out


def _along_plane(a: Sample, b: Sample) -> float:
    """Signed distance from ``a`` to ``b`` along ``a``'s heading, up the plane: the
    horizontal displacement along the heading, lifted onto the plane by the height gained."""
    forward = (b.x - a.x) * math.cos(a.yaw) + (b.y - a.y) * math.sin(a.yaw)
    return math.copysign(math.hypot(forward, b.z - a.z), forward)


@metric(
    "uphill_speed_mps",
    "m/s",
    "speed along the starting heading, up the plane (negative: sliding back), over the window",
)
def uphill_speed_mps(result: SimResult, window: Window) -> Value:
    """The body's mean velocity along its starting heading, measured on the plane, m/s."""
    s = window.samples(result)
    if len(s) < 2 or s[-1].t <= s[0].t:
        return None
    return _along_plane(s[0], s[-1]) / (s[-1].t - s[0].t)


@metric(
    "thesis_cost_of_transport",
    "",
    "cost of transport as in thesis eq. 6.4–6.5: U·I / (m g v), I the total servo current, "
    "v the speed up the plane; none below 0.01 m/s",
)
def thesis_cost_of_transport(result: SimResult, window: Window) -> Value:
    """e = U·I / (m·g·v) (eq. 6.4, P = U·I eq. 6.5), as Table 6.7 computes it."""
    current, speed = total_current_a(result, window), uphill_speed_mps(result, window)
    if not isinstance(current, float) or not isinstance(speed, float) or speed < 0.01:
        return None
    return _supply_voltage(result) * current / (result.mass_kg * G * speed)


@metric("max_heading_change_deg", "°", "largest |yaw − yaw at the window's start| in the window")
def max_heading_change_deg(result: SimResult, window: Window) -> Value:
    """How far the body turned away from its first heading in the window, degrees."""
    yaw = _unwrapped_yaw(window.samples(result))
    return math.degrees(max(abs(y - yaw[0]) for y in yaw)) if yaw else None


@metric(
    "gait_period_s",
    "s",
    "gait cycle time: mean time between a leg's successive lift-offs (LegState swings)",
)
def gait_period_s(result: SimResult, window: Window) -> Value:
    """The mean, over the legs, of the time from one swing's start to the next, s."""
    starts: dict[int, list[float]] = {}
    before: dict[int, str] = {}
    for m in result.run.log.messages(of=LegState):
        if m.phase == "swing" and before.get(m.leg) != "swing" and window.contains(m.t):
            starts.setdefault(m.leg, []).append(m.t)
        before[m.leg] = m.phase
    periods = [(t[-1] - t[0]) / (len(t) - 1) for t in starts.values() if len(t) > 1]
    return sum(periods) / len(periods) if periods else None


def _moving_from(samples: Sequence[Sample]) -> int | None:
    """Index of the last sample before the body left where it stood at the window's start."""
    first = samples[0]
    for k, s in enumerate(samples):
        if math.hypot(s.x - first.x, s.y - first.y) > MOVING_M:
            return max(0, k - 1)
    return None


MOVING_ACTIVITIES: Final = ("riding", "walking", "hybrid")
"""The coordinator's activities that move the body (:class:`LocomotionState`)."""


@metric(
    "time_to_2m_s",
    "s",
    "time from the coordinator starting to ride or walk in the window (else the body's first "
    "movement) until the body is 2 m from where it was then (6.5.1: the 2 m track)",
)
def time_to_2m_s(result: SimResult, window: Window) -> Value:
    """Seconds the robot takes to cover the 2 m track from a standstill. The clock starts
    when the coordinator starts to move the body, not at the command: the walk → ride
    change before it (legs squared, wheels aligned) shifts the body by a few cm."""
    s = window.samples(result)
    if not s:
        return None
    start = next(
        (k for k, x in enumerate(s) if x.activity.split(" ")[0] in MOVING_ACTIVITIES), None
    )
    if start is None:
        start = _moving_from(s)
    if start is None:
        return None
    a = s[start]
    for b in s[start:]:
        if math.hypot(b.x - a.x, b.y - a.y) >= TRACK_M:
            return b.t - a.t
    return None


@metric("top_speed_mps", "m/s", "largest displacement over 1 s in the window, per second")
def top_speed_mps(result: SimResult, window: Window) -> Value:
    """The highest speed over any :data:`TOP_SPEED_SPAN_S` of the window, m/s."""
    s = window.samples(result)
    best: float | None = None
    j = 0
    for i, a in enumerate(s):
        j = max(j, i)
        while j < len(s) and s[j].t - a.t < TOP_SPEED_SPAN_S - 1e-9:
            j += 1
        if j == len(s):
            break
        b = s[j]
        v = math.hypot(b.x - a.x, b.y - a.y) / (b.t - a.t)
        best = v if best is None else max(best, v)
    return best


@metric(
    "travel_direction_deg",
    "°",
    "direction of the window's displacement relative to the starting heading (+: left)",
)
def travel_direction_deg(result: SimResult, window: Window) -> Value:
    """Where the body went, relative to where it faced at the window's start, degrees."""
    s = window.samples(result)
    if len(s) < 2:
        return None
    dx, dy = s[-1].x - s[0].x, s[-1].y - s[0].y
    if math.hypot(dx, dy) < MOVING_M:
        return None
    heading = math.atan2(dy, dx) - s[0].yaw
    return math.degrees((heading + math.pi) % (2 * math.pi) - math.pi)


@metric("spin_rpm", "rpm", "mean turning rate of the body over the window, revolutions/min")
def spin_rpm(result: SimResult, window: Window) -> Value:
    """|Δyaw| / Δt over the window, in revolutions per minute (6.5.2: about 4 rpm)."""
    s = window.samples(result)
    if len(s) < 2 or s[-1].t <= s[0].t:
        return None
    yaw = _unwrapped_yaw(s)
    return abs(yaw[-1] - yaw[0]) / (s[-1].t - s[0].t) * 60 / (2 * math.pi)


@metric(
    "circle_return_m",
    "m",
    "distance from the window's first position when the heading has turned two full laps "
    "(6.5.2: 1.5 cm)",
)
def circle_return_m(result: SimResult, window: Window) -> Value:
    """How far from its starting point the robot is after :data:`CIRCLE_LAPS` laps, m."""
    s = window.samples(result)
    yaw = _unwrapped_yaw(s)
    goal = CIRCLE_LAPS * 2 * math.pi
    for k in range(1, len(s)):
        turned, before = abs(yaw[k] - yaw[0]), abs(yaw[k - 1] - yaw[0])
        if turned >= goal > before:
            f = (goal - before) / (turned - before)
            x = s[k - 1].x + f * (s[k].x - s[k - 1].x)
            y = s[k - 1].y + f * (s[k].y - s[k - 1].y)
            return math.hypot(x - s[0].x, y - s[0].y)
    return None


def _first_fall(result: SimResult) -> Sample | None:
    for s in result.samples:
        if s.tilt > FALLEN_TILT_RAD:
            return s
    return None


@metric("fell_at_s", "s", "when the body first tilted past 60°, in the whole run (none: never)")
def fell_at_s(result: SimResult, window: Window) -> Value:
    """The time of the first fall, whether or not inside the window (a fall before the
    window explains the window's figures)."""
    fall = _first_fall(result)
    return None if fall is None else fall.t


@metric("fell_while", "", "what the coordinator was doing when the body first tilted past 60°")
def fell_while(result: SimResult, window: Window) -> Value:
    """The coordinator's activity at the first fall (``walking walk/tripod``…), if any."""
    fall = _first_fall(result)
    return None if fall is None else fall.activity


def _joint_current(joint: int) -> Callable[[SimResult, Window], Value]:
    def fn(result: SimResult, window: Window) -> Value:
        currents = servo_currents(result, window, joint)
        return sum(currents.values()) if currents else None

    return fn


PER_JOINT: Final = ("coxa", "femur", "tibia", "tarsus")
"""The joints whose current the sim's read plan reports (the others are not read)."""
for _name in PER_JOINT:
    metric(
        f"{_name}_current_a",
        "A",
        f"current of the six {_name} servos (eq. 6.1, summed), as the bus reads it",
    )(_joint_current(JOINT_NAMES.index(_name)))

# --------------------------------------------------------------------------- the thesis's figures

Number = float | int
ThesisValue = Number | str | None
SimValue = float | str | None


@dataclass(frozen=True)
class TableRow:
    """One row of Table 6.7: speed (m/s), current (A) and CoT, without/with trochanter."""

    movement: str
    slope_deg: int
    speed_m_s: float
    current_a: float | None
    current_t_a: float | None
    cot: float | None
    cot_t: float | None


TABLE_6_7: Final = (
    # Žák 2023, Table 6.7; "-" (not measured, or the robot could not) is None.
    TableRow(TRIPOD, 0, 0.12, 5.22, None, 6.05, None),
    TableRow(TRIPOD, 14, 0.12, 7.87, 6.30, 9.12, 7.30),
    TableRow(TRIPOD, 23, 0.10, 7.83, 7.16, 10.88, 9.95),
    TableRow(TRIPOD, 32, 0.07, None, 8.04, None, 15.97),
    TableRow(WHEELS, 0, 0.20, 3.47, None, 2.41, None),
    TableRow(WHEELS, 14, 0.20, 5.37, 4.52, 3.73, 3.14),
    TableRow(WHEELS, 23, 0.20, 6.29, 4.59, 4.37, 3.19),
    TableRow(WHEELS, 32, 0.20, 7.35, 4.80, 5.11, 3.34),
    TableRow(WHEELS, 40, 0.15, None, 4.72, None, 4.37),
)
STEEPEST_DEG: Final = {
    # 6.7.6: walked 32°, rode 40°, stood 50° with the trochanter. Without it: stood up to
    # 32° (6.8.1, Fig. 6.7a: "no longer able to stand stably on slopes greater than 32°"),
    # rode up to 32° (Table 6.7: no 40° row without; 6.8.1 "no longer reliably able to
    # ride on such a slope without using the trochanter"), walked up to 23° (Table 6.7).
    ("walk", True): 32,
    ("ride", True): 40,
    ("stand", True): 50,
    ("walk", False): 23,
    ("ride", False): 32,
    ("stand", False): 32,
}
STATIC_SAVING_32_PCT: Final = 23.0
"""6.8.1: the stance with the trochanter used > 23 % less current than No. 1 at 32°."""


@dataclass(frozen=True)
class Why:
    """Our explanation of a difference, by its direction: the sim's figure higher or lower."""

    higher: str
    lower: str


CURRENT_WHY: Final = Why(
    higher="We think the motor model is the main cause: its friction (BAM model m1, "
    "sim/motors.py) has a fixed size, so a simulated servo holds a static load with its "
    "full current τ/kₜ, while a real geared servo's friction grows with the load and "
    "carries part of it without current. The loaded coxa, femur and tibia servos of the "
    "legs on the ground feel it most.",
    lower="The motor model counts only the current that makes torque (τ/kₜ); a real "
    "servo's Present Current also carries its PID's dithering about the goal.",
)
SPEED_WHY: Final = Why(
    higher="",
    lower="The simulated robot loses ground with every step, and from about 23° it slides "
    "back. On 14° its stance feet neither slide nor roll and the trochanters follow their "
    "goals; the stance legs lag their goals more than on the flat (position control: "
    "the error grows with the load), which shortens each stroke, but whether that is all "
    "of the loss, and what slides it back from 23°, we have not established.",
)
RIDE_SPEED_WHY: Final = Why(
    higher="",
    lower="The model's wheel servo has a Velocity Limit that caps the wheels below the "
    "commanded 0.2 m/s (the coordinator clamps the command and says so).",
)
COT_WHY: Final = Why(
    higher="CoT = U·I/(m g v): a higher current or a lower speed than the thesis's raise it.",
    lower="CoT = U·I/(m g v): a lower current or a higher speed than the thesis's lower it.",
)
STEEPEST_WHY: Final = Why(
    higher="Standing still, the simulated servos hold any torque up to their datasheet's "
    "stall torque on a perfectly even, rigid plane; the thesis's robot slipped on its "
    "board (6.7.7) and its stance No. 1 drew ever more current there (6.8.1).",
    lower="The simulated walks slip back (see the speeds of Table 6.7), and the walk → "
    "ride change re-places the feet one group at a time on the slope, where the robot "
    "can tip; the ground's friction (µ 0.9) holds a sliding body only up to "
    "atan 0.9 = 42°. The thesis's tyres on its wooden board gripped better than that.",
)
CIRCLE_WHY: Final = Why(
    higher="The wheels fight each other through the legs on the circle (see the current "
    "beside), and the centre of the circle wanders. Part of it is mended: the wheels were "
    "driven for the commanded feet, centimetres outward of where the sagging legs put them "
    "(the return error fell to a third when they were driven for the measured feet). The "
    "rest we have not found: the current still grows lap after lap, while the legs' feet "
    "drift sideways by centimetres.",
    lower="The simulated wheels roll without slip on an even floor; the real ones slipped "
    "and the inner legs strained (6.5.2).",
)
SPIN_WHY: Final = Why(
    higher="The coordinator spins as fast as the outermost wheel's speed limit allows; "
    "the thesis did not say what rate it commanded.",
    lower="The coordinator spins as fast as the outermost wheel's speed limit allows, "
    "which is below the thesis's rate in this model.",
)
TRACK_WHY: Final = Why(
    higher="The model's wheel servos are capped below the thesis's 0.2 m/s (see the top "
    "speed), and the body ramps its speed up at 0.25 m/s² (locomotion.max_accel_m_s2).",
    lower="The robot does not slow down at the track's end here; the thesis's run did.",
)
PERIOD_WHY: Final = Why(
    higher="The cycle follows the commanded speed, T = L/(β v) with L = 100 mm: the "
    "thesis's 1.6 s at 0.12 m/s needs a shorter step.",
    lower="The cycle follows the commanded speed, T = L/(β v) with L = 100 mm: at "
    "0.12 m/s that is 1.67 s less the velocity ramp.",
)
DIRECTION_WHY: Final = Why(
    higher="The wheels' headings drift with the coxa's tracking error while riding.",
    lower="The wheels' headings drift with the coxa's tracking error while riding.",
)


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

    def to_json(self) -> dict[str, Any]:
        """``{"name", "unit", "thesis", "sim"}``: the row of ``whexar sim --experiments --json``."""
        return {"name": self.name, "unit": self.unit, "thesis": self.thesis, "sim": self.sim}


def _slope(row: Row) -> float:
    value = row.variation.get(SLOPE_KEY, 0.0)
    return float(value) if isinstance(value, int | float) else 0.0


def _trochanter(row: Row) -> bool:
    return bool(row.variation.get(TROCHANTER_KEY, True))


def _find(
    rows: Iterable[Row], label: str, slope: float = 0.0, trochanter: bool | None = None
) -> Row | None:
    for row in rows:
        if (
            row.label == label
            and abs(_slope(row) - slope) < 1e-9
            and (trochanter is None or _trochanter(row) == trochanter)
        ):
            return row
    return None


def _number(row: Row | None, key: str) -> float | None:
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


def made_it(row: Row) -> bool | None:
    """Whether a movement went up the plane (see the module docstring); ``None``: unknown."""
    speed, wanted = _number(row, "uphill_speed_mps"), commanded_speed(row)
    turned = _number(row, "max_heading_change_deg")
    if speed is None or wanted is None or turned is None:
        return None
    return (
        row.metrics.get("fell") is False
        and speed >= MIN_PROGRESS_FRACTION * wanted
        and turned <= MAX_HEADING_CHANGE_DEG
    )


def held(row: Row) -> bool | None:
    """Whether a static stance held (see the module docstring); ``None``: unknown."""
    slid = _number(row, "displacement_m")
    if slid is None:
        return None
    return row.metrics.get("fell") is False and slid <= MAX_SLIDE_M


def steepest(rows: Iterable[Row], label: str, trochanter: bool) -> float | None:
    """The highest tested slope (°) with every tested slope up to it passed; ``None`` when
    the lowest failed or nothing was tested."""
    judge = held if label.startswith("stance") else made_it
    tested = sorted(
        (r for r in rows if r.label == label and _trochanter(r) == trochanter), key=_slope
    )
    best: float | None = None
    for row in tested:
        if judge(row) is not True:
            break
        best = _slope(row)
    return best


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
    source: str,
    why: Why | None = None,
    *,
    tolerance: float = 0.15,
    note: str = "",
) -> Figure:
    notes = [note] if note else []
    direction = _differs(thesis, sim, tolerance)
    if why is not None and direction:
        reason = why.higher if direction > 0 else why.lower
        if reason:
            notes.append(reason)
    if sim is None and not note:
        notes.append("no value: the run failed or the figure is undefined for it")
    return Figure(name, unit, thesis, sim, source, " ".join(notes))


def _outcome_note(row: Row | None, judge: Callable[[Row], bool | None]) -> str:
    if row is None:
        return "no such run in the campaign"
    if row.outcome != "ok":
        return f"run failed: {row.error}"
    ok = judge(row)
    if ok is True:
        return ""
    fell_at, doing = _number(row, "fell_at_s"), row.metrics.get("fell_while")
    if row.metrics.get("fell") is True:
        when = f" at {fell_at:.1f} s" if fell_at is not None else ""
        how = f" ({doing})" if isinstance(doing, str) and doing else ""
        return f"The robot fell (tilted past 60°){when}{how}."
    if judge is made_it:
        speed, turned = _number(row, "uphill_speed_mps"), _number(row, "max_heading_change_deg")
        if turned is not None and turned > MAX_HEADING_CHANGE_DEG:
            return f"Did not climb: it turned {turned:.0f}° away."
        return f"Did not climb: {speed:+.3f} m/s up the plane." if speed is not None else ""
    slid = _number(row, "displacement_m")
    return f"Slid {slid:.3f} m in its 3 s window." if slid is not None else ""


def _saving_note(rows: Sequence[Row], saving: float | None) -> str:
    """Why stance No. 3 saves less than the thesis's 23 % at 32°, from the coxa servos'
    current (the thesis saw the trochanter relieve them, 6.8.2, Fig. 6.8)."""
    if saving is None or saving >= STATIC_SAVING_32_PCT:
        return ""
    one = _number(_find(rows, STANCE_LABELS[1], 32.0), "coxa_current_a")
    three = _number(_find(rows, STANCE_LABELS[3], 32.0), "coxa_current_a")
    if one is None or three is None:
        return ""
    return (
        f"The six coxa servos draw {one:.2f} A in No. 1 and {three:.2f} A in No. 3 here; "
        "the thesis saw the trochanter relieve them markedly (6.8.2, Fig. 6.8). We suspect "
        "the six stiff, position-held legs push against each other through the ground, "
        "which loads the coxas whatever the trochanter does."
    )


def figures(rows: Sequence[Row]) -> list[Figure]:
    """The thesis's figures beside the simulation's, from the campaign's rows (see the
    module docstring); one :class:`Figure` per figure, in the report's order."""
    out: list[Figure] = []
    # 6.4, 6.8.1: the tripod gait on the flat.
    flat = _find(rows, TRIPOD, 0.0, False)
    out.append(
        _figure(
            "tripod gait on the flat: speed",
            "m/s",
            "0.07–0.12",
            _number(flat, "uphill_speed_mps"),
            "6.8.1",
            note=_outcome_note(flat, made_it),
        )
    )
    out.append(
        _figure(
            "tripod gait on the flat: period",
            "s",
            1.6,
            _number(flat, "gait_period_s"),
            "6.8.1, Fig. 6.9a",
            PERIOD_WHY,
            tolerance=0.05,
        )
    )
    # 6.5.1, 6.5.2: riding on the flat.
    straight = _find(rows, STRAIGHT)
    out += [
        _figure(
            "riding straight: time for the 2 m track",
            "s",
            10.0,
            _number(straight, "time_to_2m_s"),
            "6.5.1",
            TRACK_WHY,
        ),
        _figure(
            "riding straight: top speed",
            "m/s",
            0.2,
            _number(straight, "top_speed_mps"),
            "6.5.1",
            RIDE_SPEED_WHY,
            tolerance=0.05,
        ),
        _figure(
            "riding straight: direction of travel",
            "°",
            0.0,
            _number(straight, "travel_direction_deg"),
            "6.5.1 (kept its direction)",
            note="The thesis gives no number: it kept its direction.",
        ),
    ]
    for angle, label in SIDEWAYS.items():
        side = _find(rows, label)
        out += [
            _figure(
                f"riding sideways at {angle:+d}°: direction of travel",
                "°",
                float(angle),
                _number(side, "travel_direction_deg"),
                "6.5.2",
                DIRECTION_WHY,
                tolerance=0.05,
            ),
            _figure(
                f"riding sideways at {angle:+d}°: time for the 2 m track",
                "s",
                10.0,
                _number(side, "time_to_2m_s"),
                "6.5.2",
                TRACK_WHY,
            ),
            _figure(
                f"riding sideways at {angle:+d}°: top speed",
                "m/s",
                0.2,
                _number(side, "top_speed_mps"),
                "6.5.2",
                RIDE_SPEED_WHY,
                tolerance=0.05,
            ),
        ]
    out.append(
        _figure(
            "spinning in place: rate",
            "rpm",
            4.0,
            _number(_find(rows, SPIN), "spin_rpm"),
            "6.5.2",
            SPIN_WHY,
        )
    )
    circle = _find(rows, CIRCLE)
    circle_note = "Radius 0.6 m here (the thesis gives none)."
    on_circle, on_line = _number(circle, "total_current_a"), _number(straight, "total_current_a")
    if on_circle is not None and on_line is not None:
        circle_note += (
            f" It draws {on_circle:.1f} A on the circle against {on_line:.1f} A riding straight."
        )
    out.append(
        _figure(
            f"circle ({CIRCLE_LAPS} laps): distance from the start",
            "m",
            0.015,
            _number(circle, "circle_return_m"),
            "6.5.2",
            CIRCLE_WHY,
            tolerance=0.5,
            note=circle_note,
        )
    )
    # 6.8.1, Table 6.7: the movements on slopes.
    for t in TABLE_6_7:
        for trochanter in (False, True):
            row = _find(rows, t.movement, float(t.slope_deg), trochanter)
            with_ = "with" if trochanter else "without"
            current = t.current_t_a if trochanter else t.current_a
            cot = t.cot_t if trochanter else t.cot
            measured = current is not None
            missing = "" if measured else "The thesis has no value here."
            outcome = _outcome_note(row, made_it)
            head = f"Table 6.7 {t.movement} {t.slope_deg}°, {with_} trochanter"
            speed_why = RIDE_SPEED_WHY if t.movement == WHEELS else SPEED_WHY
            # A robot that slid back or fell has a current but no cost of transport.
            climbed = row is not None and made_it(row) is True
            note = " ".join(x for x in (missing, outcome) if x)
            out += [
                _figure(
                    f"{head}: speed",
                    "m/s",
                    t.speed_m_s if measured else None,
                    _number(row, "uphill_speed_mps"),
                    "Table 6.7",
                    speed_why,
                    note=note,
                ),
                _figure(
                    f"{head}: total current",
                    "A",
                    current,
                    _number(row, "total_current_a"),
                    "Table 6.7, eq. 6.1–6.3",
                    CURRENT_WHY if climbed else None,
                    note=note,
                ),
                _figure(
                    f"{head}: cost of transport",
                    "",
                    cot,
                    _number(row, "thesis_cost_of_transport") if climbed else None,
                    "Table 6.7, eq. 6.4–6.5",
                    COT_WHY,
                    note=note,
                ),
            ]
    # 6.8, Table 6.6, Fig. 6.7a: the static stances.
    for slope in TABLE_6_6_SLOPES_DEG:
        for number in (1, 2, 3):
            if slope == 0 and number != 1:
                continue  # Table 6.6: on the flat the three stances are one
            name = f"Table 6.6 stance No. {number} on {slope}°: total current"
            if number == 2 and slope > MAX_BODY_PITCH_DEG:
                out.append(
                    Figure(
                        name,
                        "A",
                        None,
                        "not simulated",
                        "Table 6.6, Fig. 6.7a",
                        f"Levelling the body takes a body pitch of {slope}°; the coordinator "
                        f"allows ±{MAX_BODY_PITCH_DEG:g}°.",
                    )
                )
                continue
            row = _find(rows, STANCE_LABELS[number], float(slope))
            notes = ["Fig. 6.7a gives it as a chart only."]
            if number == 3 and slope > MAX_TROCHANTER_DEG:
                notes.append(
                    f"The trochanters follow the pitch up to {MAX_TROCHANTER_DEG:g}° only."
                )
            held_note = _outcome_note(row, held)
            if held_note:
                notes.append(held_note)
            out.append(
                _figure(
                    name,
                    "A",
                    None,
                    _number(row, "total_current_a"),
                    "Table 6.6, Fig. 6.7a",
                    note=" ".join(notes),
                )
            )
    one = _number(_find(rows, STANCE_LABELS[1], 32.0), "total_current_a")
    three = _number(_find(rows, STANCE_LABELS[3], 32.0), "total_current_a")
    saving = 100 * (1 - three / one) if one and three is not None else None
    out.append(
        _figure(
            "stance No. 3 against No. 1 on 32°: current saved",
            "%",
            f">{STATIC_SAVING_32_PCT:g}",
            saving,
            "6.8.1",
            note=_saving_note(rows, saving),
        )
    )
    # 6.7.6, 6.8.1: the steepest slopes, from the sweep.
    for (mode, trochanter), thesis in STEEPEST_DEG.items():
        label = {"walk": TRIPOD, "ride": WHEELS, "stand": STANCE_LABELS[3]}[mode]
        if mode == "stand" and not trochanter:
            label = STANCE_LABELS[1]
        tested = sorted(
            {_slope(r) for r in rows if r.label == label and _trochanter(r) == trochanter}
        )
        found = steepest(rows, label, trochanter)
        verb = {"walk": "walked", "ride": "ridden", "stand": "stood on"}[mode]
        note = ""
        if tested and found == tested[-1]:
            note = f"Every slope tested passed: the limit lies above {tested[-1]:g}°."
        elif found is None and tested:
            note = f"The lowest slope tested ({tested[0]:g}°) already failed."
        out.append(
            _figure(
                f"steepest slope {verb}, {'with' if trochanter else 'without'} trochanter",
                "°",
                thesis,
                found,
                "6.7.6, 6.8.1",
                STEEPEST_WHY,
                tolerance=0.1,
                note=note,
            )
        )
    return out


# --------------------------------------------------------------------------- the report

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


def table_markdown(found: Sequence[Figure]) -> str:
    """The figures as one Markdown table."""
    lines = ["| figure | unit | thesis | sim | source | note |", "|---|---|---|---|---|---|"]
    for f in found:
        note = f.note.replace("|", "\\|")
        lines.append(
            f"| {f.name} | {f.unit} | {format_value(f.thesis)} | {format_value(f.sim)} "
            f"| {f.source} | {note} |"
        )
    return "\n".join(lines)


def table_text(found: Sequence[Figure]) -> str:
    """The figures for the terminal: name, thesis, sim and unit, one a line."""
    width = max((len(f.name) for f in found), default=10)
    lines = [f"{'figure':<{width}}  {'thesis':>10}  {'sim':>13}  unit"]
    for f in found:
        lines.append(
            f"{f.name:<{width}}  {format_value(f.thesis):>10}  {format_value(f.sim):>13}  {f.unit}"
        )
    return "\n".join(lines)


def _series(
    rows: Sequence[Row], label: str, trochanter: bool | None, key: str
) -> tuple[list[float], list[float]]:
    """``key`` against the slope for the runs that made it or held: a fallen robot's
    current says nothing of the stance or the movement."""
    judge = held if label.startswith("stance") else made_it
    points = sorted(
        (_slope(r), v)
        for r in rows
        if r.label == label
        and (trochanter is None or _trochanter(r) == trochanter)
        and judge(r) is True
        for v in [_number(r, key)]
        if v is not None
    )
    return [p[0] for p in points], [p[1] for p in points]


def _plot_static(rows: Sequence[Row], path: Path) -> Path:
    fig, ax = new_figure(8.0, 4.5)
    for number, style in ((1, "o-"), (2, "s-"), (3, "^-")):
        label = STANCE_LABELS[number]
        xs, ys = _series(rows, label, None, "total_current_a")
        ax.plot(xs, ys, style, label=f"No. {number}")
    ax.set_xlabel("slope (°)")
    ax.set_ylabel("total servo current (A), eq. 6.1–6.3")
    ax.set_title("Static stances of Table 6.6 (cf. Fig. 6.7a); only the stances that held")
    ax.grid(True, alpha=0.3)
    ax.legend()
    return save_figure(fig, path)


def _plot_motion(rows: Sequence[Row], path: Path) -> Path:
    fig, ax = new_figure(8.0, 4.5)
    for movement, color in ((TRIPOD, "tab:blue"), (WHEELS, "tab:orange")):
        for trochanter, style in ((False, "--"), (True, "-")):
            xs, ys = _series(rows, movement, trochanter, "total_current_a")
            w = "w" if trochanter else "w/o"
            ax.plot(xs, ys, style + ".", color=color, label=f"{movement} {w} trochanter (sim)")
            thesis = [
                (t.slope_deg, t.current_t_a if trochanter else t.current_a)
                for t in TABLE_6_7
                if t.movement == movement
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


def _plot_cot(rows: Sequence[Row], path: Path) -> Path:
    fig, ax = new_figure(10.0, 4.5)
    names: list[str] = []
    thesis: list[float] = []
    sim: list[float] = []
    for t in TABLE_6_7:
        for trochanter in (False, True):
            value = t.cot_t if trochanter else t.cot
            row = _find(rows, t.movement, float(t.slope_deg), trochanter)
            names.append(f"{t.movement} {t.slope_deg}°{' T' if trochanter else ''}")
            thesis.append(value if value is not None else math.nan)
            s = _number(row, "thesis_cost_of_transport")
            climbed = row is not None and made_it(row) is True
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


def _plot_sweep(rows: Sequence[Row], path: Path) -> Path:
    fig, ax = new_figure(9.0, 4.0)
    lines = [
        ("walk", False, TRIPOD),
        ("walk", True, TRIPOD),
        ("ride", False, WHEELS),
        ("ride", True, WHEELS),
        ("stand", False, STANCE_LABELS[1]),
        ("stand", True, STANCE_LABELS[3]),
    ]
    for k, (mode, trochanter, label) in enumerate(lines):
        judge = held if mode == "stand" else made_it
        for r in rows:
            if r.label != label or _trochanter(r) != trochanter:
                continue
            ok = judge(r)
            color = "tab:green" if ok else "tab:red" if ok is False else "tab:gray"
            ax.plot(_slope(r), k, "s", color=color, markersize=11)
        ax.plot(STEEPEST_DEG[(mode, trochanter)], k, "k|", markersize=22, markeredgewidth=2)
    ax.set_yticks(range(len(lines)))
    ax.set_yticklabels([f"{m} {'w' if t else 'w/o'} trochanter" for m, t, _ in lines])
    ax.set_xlabel("slope (°)")
    ax.plot([], [], "s", color="tab:green", label="made it / held")
    ax.plot([], [], "s", color="tab:red", label="failed")
    ax.plot([], [], "k|", markersize=12, label="thesis's steepest")
    ax.legend(fontsize=7, loc="lower left")
    ax.set_title("Slope sweep (6.7.6): the outcome of every run")
    ax.grid(True, axis="x", alpha=0.3)
    return save_figure(fig, path)


def _plot_joints(rows: Sequence[Row], path: Path) -> Path:
    fig, ax = new_figure(8.0, 4.0)
    groups = [
        (f"No. {n} {slope}°", _find(rows, STANCE_LABELS[n], float(slope)))
        for slope in (0, 32)
        for n in (1, 3)
    ]
    xs = list(range(len(groups)))
    width = 0.8 / len(PER_JOINT)
    for k, joint in enumerate(PER_JOINT):
        values = [_number(row, f"{joint}_current_a") for _, row in groups]
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


PLOTS: Final[tuple[tuple[str, Callable[[Sequence[Row], Path], Path], str], ...]] = (
    (
        "static-current.png",
        _plot_static,
        "Total current of the static stances that held (Fig. 6.7a)",
    ),
    (
        "motion-current.png",
        _plot_motion,
        "Total current of the movements that climbed, thesis's points beside (Fig. 6.7b)",
    ),
    ("cost-of-transport.png", _plot_cot, "Cost of transport per row of Table 6.7"),
    ("slope-sweep.png", _plot_sweep, "Outcome of every run of the slope sweep (6.7.6)"),
    ("joint-current.png", _plot_joints, "Current per joint of the static stances (Fig. 6.8)"),
)


def report_markdown(found: Sequence[Figure], rows: Sequence[Row]) -> str:
    """``experiments.md``: what was run, the table, the plots."""
    failed = [r for r in rows if r.outcome != "ok"]
    lines = [
        "# The thesis's experiments in simulation",
        "",
        "Generated by `whexar sim --experiments` (campaign `config/campaigns/experiments.toml`,"
        " metrics and report in `whexar/campaign/experiments.py`). The thesis is Žák 2023,"
        " sections 6.4–6.8; every thesis figure is cited by section, table or equation.",
        "",
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
        f" {MAX_HEADING_CHANGE_DEG:g}° and climbed at ≥ {MIN_PROGRESS_FRACTION:.0%} of its"
        f" commanded speed; a stance *held* when it slid less than {MAX_SLIDE_M * 100:g} cm"
        " in 3 s. The model's physical parameters come from the sources the simulation"
        " cites; nothing was tuned to these figures. The notes give the reason we believe"
        " for a difference larger than the figure's tolerance (15 % for most).",
        "",
        table_markdown(found),
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


def write_report(rows: Sequence[Row], out_dir: str | Path) -> list[Path]:
    """Write ``experiments.md`` and its plots (under ``img/experiments/``) into ``out_dir``;
    the paths written."""
    out = Path(out_dir)
    images = out / IMG_DIR
    images.mkdir(parents=True, exist_ok=True)
    found = figures(rows)
    written = [draw(rows, images / name) for name, draw, _ in PLOTS]
    md = out / "experiments.md"
    md.write_text(report_markdown(found, rows))
    return [md, *written]


__all__ = [
    "SLOPE_KEY",
    "TABLE_6_7",
    "TROCHANTER_KEY",
    "Figure",
    "commanded_speed",
    "figures",
    "held",
    "made_it",
    "steepest",
    "table_markdown",
    "table_text",
    "write_report",
]
