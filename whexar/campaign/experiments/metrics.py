"""The metrics of the thesis's experiments (Žák 2023, 6.4–6.8), registered by name.

Theory of operation
-------------------
Each function here is a campaign metric (:func:`~whexar.campaign.metrics.metric`)
that ``config/campaigns/experiments.toml`` keeps: the total servo current of
eq. 6.1–6.3 over all 42 servos, the speed up the plane, the cost of transport as
the thesis computes it (eq. 6.4–6.5), the gait period, the time to cover the 2 m
track, the direction of travel, the spin rate and the circle's return error. Each
reads only the run (its samples and the series of its messages), so the campaign's rows stay
deterministic.

*The total current.* Table 6.7's current, and the I of the cost of
transport (eq. 6.5: "the current drawn from the power supply"), is the
supply's: an ACS712 on the 12 V line (6.8). :func:`total_current_a` is that:
the world's supply current (:mod:`whexar.sim.power`: Σ duty × winding current
of the bridges, the servos' standby currents, the electronics). The winding
currents the servos report as Present Current (eq. 6.1–6.3, Fig. 6.8) keep
their own names: the generic ``mean_current_a`` sums those the default read
plan reads (coxa, femur, tibia, tarsus: 24 servos), :func:`winding_current_a`
all 42 (the sampled Σ V·|I| over the supply voltage).

The constants below define what a metric measures (a change changes the rows,
and so every run's key); the thesis's figures they are set beside are data
(:mod:`whexar.campaign.experiments.reference`).
"""

from __future__ import annotations

import bisect
import itertools
import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Final

from whexar.campaign.metrics import (
    G,
    Value,
    Window,
    mean_power,
    mean_supply,
    metric,
    servo_currents,
)
from whexar.robot import JOINT_NAMES
from whexar.sim.run import FALLEN_TILT_RAD

if TYPE_CHECKING:
    from whexar.sim.run import Sample, SimResult

TRACK_M: Final = 2.0
"""The track of 6.5.1 and 6.5.2: 2 m."""
CIRCLE_LAPS: Final = 2
"""The circle of 6.5.2 was driven twice round."""
MOVING_M: Final = 0.01
"""The track's clock starts when the body has moved this far from where it stood."""
TOP_SPEED_SPAN_S: Final = 1.0
"""Top speed: the largest displacement over this span, over the span."""


def _supply_voltage(result: SimResult) -> float:
    return float(result.world.cfg.robot.supply_voltage_v)


@metric(
    "total_current_a",
    "A",
    "the robot's current as Table 6.7 measured it: the supply's mean current (the servos' "
    "bridges, duty × winding current, their standby currents and the electronics)",
)
def total_current_a(result: SimResult, window: Window) -> Value:
    """The mean current drawn from the supply in the window (6.8, eq. 6.5), A."""
    found = mean_supply(window.samples(result))
    return None if found is None else found[0]


@metric(
    "winding_current_a",
    "A",
    "total servo winding current, thesis eq. 6.1–6.3, over all 42 servos: the motors' mean "
    "Σ|I| as Present Current reports it (electric power Σ V·|I| over the supply voltage)",
)
def winding_current_a(result: SimResult, window: Window) -> Value:
    """Σ over every servo of its mean |winding current| in the window (eq. 6.1–6.3), A."""
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


def cost_of_transport(power_w: float, mass_kg: float, speed_mps: float) -> float:
    """e = P / (m·g·v) (eq. 6.4), P = U·I (eq. 6.5)."""
    return power_w / (mass_kg * G * speed_mps)


@metric(
    "thesis_cost_of_transport",
    "",
    "cost of transport as in thesis eq. 6.4–6.5: U·I / (m g v), U·I the supply's mean "
    "power (I the supply current, as total_current_a), v the speed up the plane; none "
    "below 0.01 m/s",
)
def thesis_cost_of_transport(result: SimResult, window: Window) -> Value:
    """e = U·I / (m·g·v) (eq. 6.4, P = U·I eq. 6.5), as Table 6.7 computes it."""
    found, speed = mean_supply(window.samples(result)), uphill_speed_mps(result, window)
    if found is None or not isinstance(speed, float) or speed < 0.01:
        return None
    return cost_of_transport(found[1], result.mass_kg, speed)


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
    found = result.series.swing_intervals().items()
    inside = [[t0 for t0, _ in swings if window.contains(t0)] for _, swings in found]
    # In the order of the legs' first swings, as the messages came: the mean is summed so.
    starts = sorted((t for t in inside if t), key=lambda t: t[0])
    periods = [(t[-1] - t[0]) / (len(t) - 1) for t in starts if len(t) > 1]
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


@metric(
    "circle_reckoned_return_m",
    "m",
    "distance from the window's first position when the turning the coordinator "
    "commanded (its yaw rate, integrated) has made two full laps: the laps as the robot "
    "reckons them (6.5.2: 1.5 cm, however its laps ended)",
)
def circle_reckoned_return_m(result: SimResult, window: Window) -> Value:
    """How far from its starting point the robot is when it reckons :data:`CIRCLE_LAPS`
    laps done, m: where a robot that stops by its own count stops."""
    s = window.samples(result)
    if len(s) < 2:
        return None
    points = result.series.locomotion.between(s[0].t, s[-1].t)
    goal, turned = CIRCLE_LAPS * 2 * math.pi, 0.0
    for a, b in itertools.pairwise(points):
        turned += abs(a.yaw_rate_rad_s) * (b.t - a.t)
        if turned >= goal:
            x, y = _position_at(s, b.t)
            return math.hypot(x - s[0].x, y - s[0].y)
    return None


def _position_at(samples: Sequence[Sample], t: float) -> tuple[float, float]:
    """The body's (x, y) at ``t``, linear between the samples around it."""
    k = bisect.bisect_left([x.t for x in samples], t)
    if k <= 0 or k >= len(samples):
        last = samples[0 if k <= 0 else -1]
        return last.x, last.y
    a, b = samples[k - 1], samples[k]
    f = (t - a.t) / (b.t - a.t) if b.t > a.t else 0.0
    return a.x + f * (b.x - a.x), a.y + f * (b.y - a.y)


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

TILT_SPAN_S: Final = 2.0
"""The tilting board (6.7.6): the robot must hold or keep climbing over every span this long
(a gait cycle and more; at 1°/s the board rises 2° in it)."""
TILT_SLIDE_M: Final = 0.02
"""A stance failed when the body slid more than this down the board or sideways in a span
(the rules' ``max_slide_m``)."""
TILT_PROGRESS_FRACTION: Final = 0.25
"""A movement failed when it climbed at less than this share of its speed on the level
board (the rules' ``min_progress_fraction``)."""
TILT_TURN_DEG: Final = 30.0
"""… or turned further than this from its heading (the rules' ``max_heading_change_deg``)."""
TILT_SUPPORT_FRACTION: Final = 0.5
"""A stance failed when a leg's force sensor read no contact for more than this share of a
span: a foot left the board, and the robot no longer stood on its six supports (6.8.1:
"no longer able to stand stably"; 4.2.3 counts disappeared supports). Over half a span,
so that a foot's flicker is not a lost support."""
STILL_MPS: Final = 0.01
"""Slower than this on the level board: the run is a stance."""


@metric(
    "tilt_limit_deg",
    "°",
    "the tilting board (6.7.6): the board's angle at the start of the first 2 s span in "
    "which the robot fell, turned > 30°, slid > 2 cm down or across the board or lifted a "
    "foot off it for most of the span (standing) or climbed at < 25 % of its "
    "speed on the level board (moving); when it never failed, the board's last angle",
)
def tilt_limit_deg(result: SimResult, window: Window) -> Value:
    """The steepest board angle (°) the run held, raised under it (:mod:`whexar.sim.tilt`)."""
    tilt = result.world.tilt
    s = window.samples(result)
    if tilt is None or len(s) < 2 or s[0].t >= tilt.start_s:
        return None
    level = [x for x in s if x.t <= tilt.start_s]
    speed = _along_plane(level[0], level[-1]) / max(level[-1].t - level[0].t, 1e-9)
    moving = speed >= STILL_MPS
    yaw = _unwrapped_yaw(s)
    loads_t, contacts = result.series.contacts()
    start = 0
    for k, b in enumerate(s):
        if b.t < tilt.start_s + TILT_SPAN_S:
            continue
        while s[start].t < b.t - TILT_SPAN_S - 1e-9:
            start += 1
        a = s[start]
        if moving:
            failed = _along_plane(a, b) / (b.t - a.t) < TILT_PROGRESS_FRACTION * speed
        else:
            # Down the board (it rises along +x) or sideways: as the trochanters turn with
            # the board, their arcs carry the body uphill over its feet, which is no slide.
            failed = max(a.x - b.x, abs(b.y - a.y)) > TILT_SLIDE_M
            inside = (loads_t > a.t) & (loads_t <= b.t)
            if inside.any():  # a foot off the board for most of the span
                off = 1.0 - contacts[inside].mean(axis=0)
                failed = failed or bool((off > TILT_SUPPORT_FRACTION).any())
        failed = (
            failed or b.tilt > FALLEN_TILT_RAD or math.degrees(abs(yaw[k] - yaw[0])) > TILT_TURN_DEG
        )
        if failed:
            return tilt.angle_deg(a.t)
    return tilt.angle_deg(s[-1].t)


__all__ = [
    "CIRCLE_LAPS",
    "PER_JOINT",
    "TRACK_M",
    "circle_reckoned_return_m",
    "circle_return_m",
    "cost_of_transport",
    "fell_at_s",
    "fell_while",
    "gait_period_s",
    "max_heading_change_deg",
    "spin_rpm",
    "thesis_cost_of_transport",
    "tilt_limit_deg",
    "time_to_2m_s",
    "top_speed_mps",
    "total_current_a",
    "travel_direction_deg",
    "uphill_speed_mps",
    "winding_current_a",
]
