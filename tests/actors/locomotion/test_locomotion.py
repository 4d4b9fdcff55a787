"""The locomotion actors (coordinator and six legs) on the servo emulator, on virtual time.

Each scenario runs once (cached) and several tests look at its log: the gaits'
phase tables and duty factors, the static stability margin of the commanded
feet, the wheels' directions and speeds against eq. 5.8–5.18, stance and mode
transitions, the kinematic body displacement of a straight walk and the feet
the servos report, the leg flip, bad commands, a reflex override and
determinism.

Conventions of the analysis: every actor stamps what it says in a control
cycle with the time of that cycle's :class:`ServoStates`, so messages of one
cycle share their ``t``. A foot supports the body unless it is in the air: a
swing before its touchdown (a swing's last cycle, progress 1, puts the foot
down at its target, which is how the coordinator hands over between groups),
or a lifted move (a :class:`StepCommand` of kind ``move`` with a height) in
progress.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections import Counter, defaultdict
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest

from whexar.actors.locomotion.leg_controller import FLIPPED_TROCHANTER
from whexar.actors.locomotion.planner import CONTACT_GRID_M
from whexar.actors.locomotion.wire_goals import HALF_TICK_RAD
from whexar.actors.messages import (
    BodyMotion,
    CommandClamped,
    CommandRefused,
    GoalClamped,
    GoalRefused,
    IkFailed,
    JointGoal,
    JointGoals,
    LegState,
    LocomotionChanged,
    LocomotionState,
    MotionCommand,
    ServoStates,
    StepCommand,
)
from whexar.config import RobotConfig
from whexar.kinematics.body import body_to_leg
from whexar.kinematics.gait import GAITS
from whexar.kinematics.leg import ik
from whexar.kinematics.stability import static_stability_margin
from whexar.kinematics.wheels import (
    WheelCommand,
    wheel_sideways,
    wheel_spin,
    wheel_straight,
    wheel_turn,
    wheel_twist,
)
from whexar.robot import LEG_NAMES, N_LEGS
from whexar.runtime.messages import ActorFailed, Event
from whexar.testing import Harness, RunResult, run_actors
from whexar.testing.walk import command, run_walk, walk_graph

# Whole walks on the emulators, seconds each: the policy itself is tested in milliseconds
# by test_planner.py and test_leg_controller.py.
pytestmark = pytest.mark.slow

CFG = RobotConfig()
LOCO = CFG.locomotion
GEOMETRY = CFG.leg_geometry()
WHEEL_RADIUS = GEOMETRY.wheel_radius
MIN_MARGIN = LOCO.min_stability_margin_mm / 1000
FULL_FEEDBACK = {"plan": "full_feedback"}
"""Read every servo's position, velocity and current: the direction and trochanter joints too
(the default plan reads the coxa, femur, tibia and tarsus only)."""
FAULTS: tuple[type[Event], ...] = (GoalClamped, GoalRefused, IkFailed, ActorFailed)
COXA, TROCHANTER, FEMUR, DIRECTION, WHEEL = 0, 1, 2, 5, 6
WALK_START = 3.0
"""Commands start here: standing up takes about 2.4 s."""
GAIT_SPEEDS = {"tripod": 0.08, "tetrapod": 0.08, "ripple": 0.08, "wave": 0.05}


# --------------------------------------------------------------------------- analysis helpers


def faults(r: RunResult) -> list[Event]:
    """Goals clamped or refused by the bus, IK failures, actor failures."""
    return [e for e in r.log.events() if isinstance(e, FAULTS)]


def changes(r: RunResult, what: str) -> list[tuple[str, str]]:
    """(before, after) of every LocomotionChanged of kind ``what``, in order."""
    return [(e.before, e.after) for e in r.log.events(of=LocomotionChanged) if e.what == what]


def leg_of(source: str) -> int:
    """Leg index of an actor called ``leg-XX``."""
    return LEG_NAMES.index(source.removeprefix("leg-"))


def leg_goals(r: RunResult) -> dict[float, dict[int, JointGoals]]:
    """The (non-reflex) goals in force for each leg, by cycle time and leg.

    A leg sends only the goals that changed (the bus keeps the others): each cycle's
    entry holds, per joint, the latest goal the leg sent up to that cycle.
    """
    latest: dict[int, dict[int, JointGoal]] = defaultdict(dict)
    sent: dict[float, list[JointGoals]] = defaultdict(list)
    for m in r.log.messages("goals", of=JointGoals):
        if m.source.startswith("leg-") and not m.reflex:
            sent[m.t].append(m)
    out: dict[float, dict[int, JointGoals]] = {}
    for t in sorted({s.t for s in r.log.messages("legs", of=LegState)} | set(sent)):
        for m in sent.get(t, ()):
            for g in m.goals:
                latest[leg_of(m.source)][g.joint] = g
        out[t] = {
            leg: JointGoals(
                t=t, source=f"leg-{LEG_NAMES[leg]}", goals=tuple(v for _, v in sorted(j.items()))
            )
            for leg, j in latest.items()
        }
    return out


def goal(msg: JointGoals, joint: int) -> JointGoal:
    """The goal for ``joint`` in a leg's JointGoals."""
    (found,) = [g for g in msg.goals if g.joint == joint]
    return found


def leg_states(r: RunResult) -> dict[float, dict[int, LegState]]:
    """Every LegState, by cycle time and leg."""
    out: dict[float, dict[int, LegState]] = defaultdict(dict)
    for s in r.log.messages("legs", of=LegState):
        out[s.t][s.leg] = s
    return dict(out)


def servo_states(r: RunResult) -> dict[float, dict[tuple[int, int], Any]]:
    """Present (position, velocity) of every joint read, by cycle time and (leg, joint)."""
    return {
        s.t: {(j.leg, j.joint): (j.position_rad, j.velocity_rad_s) for j in s.joints}
        for s in r.log.messages("servo-state", of=ServoStates)
    }


def airborne(state: LegState, step: StepCommand | None) -> bool:
    """The foot is off the ground: a swing before touchdown, or a lifted move under way."""
    if state.phase == "swing":
        return state.progress < 1.0
    if state.phase == "move":
        return step is not None and step.height_m > 0.0 and 0.0 < state.progress < 1.0
    return False


@dataclass(frozen=True)
class Support:
    """The support polygon of one control cycle."""

    t: float
    margin: float
    legs: tuple[int, ...]
    activity: str


def support_margins(r: RunResult) -> list[Support]:
    """The static stability margin of the commanded support feet in every control cycle.

    Each cycle takes the latest LegState of every leg; the support legs are those not in the
    air (:func:`airborne`); the CoG is the body centre shifted by the commanded pose. Cycles in
    which a leg turns about its trochanter (the robot rests on its body) are left out.
    """
    step: dict[int, StepCommand] = {}
    latest: dict[int, tuple[LegState, bool]] = {}
    pose = (0.0, 0.0)
    activity = ""
    out: list[Support] = []
    cycle_t: float | None = None

    def close() -> None:
        if cycle_t is None or len(latest) < N_LEGS:
            return
        if any(s.phase == "flip" for s, _ in latest.values()):
            return
        down = tuple(sorted(leg for leg, (_, up) in latest.items() if not up))
        points = np.array([latest[leg][0].foot for leg in down])
        margin = static_stability_margin(points, pose) if len(down) >= 3 else -math.inf
        out.append(Support(cycle_t, margin, down, activity))

    for entry in r.log.entries:
        m = entry.message
        if isinstance(m, StepCommand):
            step[m.leg] = m
        elif isinstance(m, BodyMotion):
            pose = (m.pose[0], m.pose[1])
        elif isinstance(m, LocomotionState):
            activity = m.activity
        elif isinstance(m, LegState):
            if m.t != cycle_t:
                close()
                cycle_t = m.t
            latest[m.leg] = (m, airborne(m, step.get(m.leg)))
    close()
    return out


def steady(states: Sequence[LocomotionState], activity: str, twist: Sequence[float]) -> list[float]:
    """Times of the cycles doing ``activity`` at exactly ``twist`` (the ramp finished)."""
    return [
        s.t
        for s in states
        if s.activity == activity
        and all(abs(a - b) < 1e-12 for a, b in zip(s.twist, twist, strict=True))
    ]


def previous(states: Sequence[LocomotionState], t: float) -> float:
    """The time of the control cycle before the one at ``t``."""
    times = [s.t for s in states]
    return times[times.index(t) - 1]


def whole_cycles(states: Sequence[LocomotionState]) -> tuple[float, float, int]:
    """(start, end, n): the span of the first to the last gait-phase wrap among ``states``."""
    wraps = [b.t for a, b in itertools.pairwise(states) if b.gait_phase < a.gait_phase]
    assert len(wraps) >= 3, f"fewer than two whole gait cycles in steady walking: {wraps}"
    return wraps[0], wraps[-1], len(wraps) - 1


# --------------------------------------------------------------------------- scenarios


@functools.cache
def gait_walk(name: str) -> RunResult:
    """Stand up, then walk straight ahead in gait ``name``.

    The tripod walk lasts 10 s and reads every servo (the displacement and measured-feet tests
    use it); the others read what the default plan reads.
    """
    speed = GAIT_SPEEDS[name]
    walk = [(WALK_START, command(gait=name, vx_m_s=speed))]
    if name == "tripod":
        return run_walk(walk, duration=14.0, graph=walk_graph(bus_params=FULL_FEEDBACK))
    return run_walk(walk, duration=12.0)


@functools.cache
def transitions_walk() -> RunResult:
    """Walking through gait changes (tripod → ripple → wave) and stance changes
    (default → high → low → narrow → default), the walk resuming after each."""
    return run_walk(
        [
            (WALK_START, command(vx_m_s=0.08)),
            (6.0, command(gait="ripple")),
            (10.0, command(gait="wave", vx_m_s=0.05)),
            (14.0, command(stance="high")),
            (19.5, command(stance="low")),
            (25.0, command(stance="narrow")),
            (30.5, command(stance="default")),
        ],
        duration=35.0,
    )


STANCES = ("high", "low", "narrow", "default")
STANCES_END = WALK_START + 3.0 * len(STANCES) + 0.5


@functools.cache
def stances_at_rest() -> RunResult:
    """Standing: default → high → low → narrow → default."""
    return run_walk(
        [(WALK_START + 3.0 * k, command(stance=name)) for k, name in enumerate(STANCES)],
        duration=STANCES_END,
    )


RIDES: dict[str, tuple[float, float, float]] = {
    "straight": (0.1, 0.0, 0.0),
    "sideways": (0.07, 0.07, 0.0),
    "spin": (0.0, 0.0, 0.3),
    "circle": (0.1, 0.0, 0.1),
}
"""Body twists of the ride: straight, sideways at 45°, spin in place, a circle of R = 1 m."""
CIRCLE_R = 1.0


@functools.cache
def ride() -> RunResult:
    """Walk → ride (straight, sideways, spin, circle) → walk → hybrid → walk."""
    return run_walk(
        [
            (WALK_START, command(mode="ride")),
            (6.0, command(vx_m_s=0.1)),
            (9.0, command(vx_m_s=0.07, vy_m_s=0.07)),
            (12.5, command(vx_m_s=0.0, vy_m_s=0.0, yaw_rate_rad_s=0.3)),
            (16.0, command(vx_m_s=0.1, turn_radius_m=CIRCLE_R)),
            (19.0, command(stop=True)),
            (20.0, command(mode="walk")),
            (23.0, command(vx_m_s=0.06)),
            (25.0, command(mode="hybrid", vx_m_s=0.1)),
            (31.0, command(mode="walk", vx_m_s=0.05)),
            (35.0, command(stop=True)),
        ],
        duration=37.0,
        graph=walk_graph(bus_params=FULL_FEEDBACK),
    )


@functools.cache
def flip() -> RunResult:
    """Flip onto the back, walk upside down, stop, flip back and stand."""
    return run_walk(
        [
            (WALK_START, command(upside_down=True)),
            (9.5, command(vx_m_s=0.06)),
            (13.5, command(stop=True)),
            (14.5, command(upside_down=False)),
        ],
        duration=22.5,
        graph=walk_graph(bus_params=FULL_FEEDBACK),
    )


BAD_COMMANDS: dict[str, MotionCommand] = {
    "unknown gait": command(gait="gallop", vx_m_s=0.1),
    "unknown mode": command(mode="fly", vx_m_s=0.1),
    "unknown stance": command(stance="squat", vx_m_s=0.1),
    "inside the body": command(vx_m_s=0.1, turn_radius_m=0.2),
    "upside down": command(mode="ride", upside_down=True),
    "not a finite number": command(vx_m_s=math.nan, gait="wave"),
}
"""Commands the coordinator must refuse whole, by a phrase of the reason it gives."""
BAD_END = WALK_START + 0.1 * len(BAD_COMMANDS) + 0.4
"""Nothing of the bad commands may have happened by then."""
TOO_LONG_STEP = 0.5
TOO_FAST = 1.0


@functools.cache
def bad_input() -> RunResult:
    """Refused commands while standing, then a too long step and a too fast walk."""
    timed = [(WALK_START + 0.1 * k, c) for k, c in enumerate(BAD_COMMANDS.values())]
    return run_walk(
        [
            *timed,
            (BAD_END, command(step_length_m=TOO_LONG_STEP)),
            (BAD_END + 0.1, command(vx_m_s=TOO_FAST)),
        ],
        duration=BAD_END + 3.0,
    )


REFLEX_T = 5.0
REFLEX_FEMUR = 0.3


@functools.cache
def reflex() -> RunResult:
    """Walking; at REFLEX_T a reflex takes RF's femur for one goal."""

    async def scenario(h: Harness) -> None:
        await h.sleep_until(WALK_START)
        await h.feed("commands", command(vx_m_s=0.08))
        await h.sleep_until(REFLEX_T)
        t = h.now()
        override = JointGoal(t=t, source="reflex", leg=0, joint=FEMUR, position_rad=REFLEX_FEMUR)
        await h.feed("reflex", JointGoals(t=t, source="reflex", goals=(override,), reflex=True))

    return run_actors(
        walk_graph(reflex=True),
        duration=REFLEX_T + 2.0,
        scenario=scenario,
        feeds=["commands", "reflex"],
    )


def short_walk() -> RunResult:
    return run_walk([(2.6, command(vx_m_s=0.05))], duration=3.4)


# --------------------------------------------------------------------------- 1. gaits


@pytest.mark.parametrize("name", list(GAITS))
def test_gait_walks_without_faults(name: str) -> None:
    r = gait_walk(name)
    assert r.exit_code == 0
    assert faults(r) == []
    assert r.log.events(of=CommandClamped) == []
    assert r.log.events(of=CommandRefused) == []
    assert ("standing", "walking") in changes(r, "activity")


@pytest.mark.parametrize("name", list(GAITS))
def test_gait_swing_legs_follow_the_phase_table(name: str) -> None:
    """In steady walking the coordinator's swing legs, and the legs' own phases, are those of
    the gait's phase table at the gait phase, except within ~2 bus cycles of a lift-off or a
    touchdown."""
    r = gait_walk(name)
    gait = GAITS[name]
    states = r.log.messages("locomotion", of=LocomotionState)
    times = set(steady(states, "walking", (GAIT_SPEEDS[name], 0.0, 0.0)))
    walking = [s for s in states if s.t in times]
    start, end, _ = whole_cycles(walking)
    window = [s for s in walking if start <= s.t <= end]
    rate = np.median(
        [
            (b.gait_phase - a.gait_phase) / (b.t - a.t)
            for a, b in itertools.pairwise(window)
            if b.gait_phase > a.gait_phase
        ]
    )
    bus_cycle = float(np.mean(np.diff([s.t for s in window])))
    tolerance = 2.5 * bus_cycle * rate  # ~2 bus cycles, in cycles of the gait
    events = gait.event_phases()
    legs = leg_states(r)
    checked = 0
    for s in window:
        distance = np.abs((s.gait_phase - events + 0.5) % 1.0 - 0.5).min()
        if distance < tolerance:
            continue
        table = tuple(LEG_NAMES.index(leg) for leg in gait.swing_legs(s.gait_phase))
        assert tuple(sorted(s.swing_legs)) == table, (s.t, s.gait_phase)
        swinging = tuple(leg for leg, state in sorted(legs[s.t].items()) if airborne(state, None))
        assert swinging == table, (s.t, s.gait_phase, {k: v.phase for k, v in legs[s.t].items()})
        checked += 1
    assert checked > 0.8 * len(window)


@pytest.mark.parametrize("name", list(GAITS))
def test_gait_duty_factor(name: str) -> None:
    """Over whole gait cycles of steady walking each leg is in the air 1 − β of the time."""
    r = gait_walk(name)
    gait = GAITS[name]
    states = r.log.messages("locomotion", of=LocomotionState)
    times = set(steady(states, "walking", (GAIT_SPEEDS[name], 0.0, 0.0)))
    start, end, n = whole_cycles([s for s in states if s.t in times])
    legs = leg_states(r)
    cycle_times = sorted(t for t in legs if start <= t <= end)
    air = np.zeros(N_LEGS)
    for a, b in itertools.pairwise(cycle_times):
        for leg, state in legs[a].items():
            if airborne(state, None):
                air[leg] += b - a
    fraction = air / (cycle_times[-1] - cycle_times[0])
    assert fraction == pytest.approx(np.full(N_LEGS, gait.swing_fraction), abs=0.02), n


# --------------------------------------------------------------------------- 2. stability


MARGIN_RUNS: dict[str, Callable[[], RunResult]] = {
    "tripod": lambda: gait_walk("tripod"),
    "tetrapod": lambda: gait_walk("tetrapod"),
    "ripple": lambda: gait_walk("ripple"),
    "wave": lambda: gait_walk("wave"),
    "gait and stance changes": transitions_walk,
    "stances at rest": stances_at_rest,
    "ride and hybrid": ride,
    "flip": flip,
    "fastest tripod": bad_input,
}


@pytest.mark.parametrize("run", list(MARGIN_RUNS))
def test_static_stability_margin_never_below_minimum(run: str) -> None:
    r = MARGIN_RUNS[run]()
    supports = support_margins(r)
    assert len(supports) > 500
    worst = min(supports, key=lambda s: s.margin)
    assert worst.margin >= MIN_MARGIN, worst
    assert any(len(s.legs) <= 5 for s in supports)  # legs did lift


# --------------------------------------------------------------------------- 3. wheels


def expected_wheels(
    name: str, contacts: np.ndarray[Any, Any], coxa: np.ndarray[Any, Any]
) -> WheelCommand:
    """The wheel set-points of eq. 5.8–5.18 for ride ``name``, by the matching function."""
    vx, vy, w = RIDES[name]
    if name == "straight":
        return wheel_straight(contacts, vx, coxa=coxa, wheel_radius=WHEEL_RADIUS)
    if name == "sideways":
        return wheel_sideways(
            contacts, math.hypot(vx, vy), math.atan2(vy, vx), coxa=coxa, wheel_radius=WHEEL_RADIUS
        )
    if name == "spin":
        return wheel_spin(contacts, w, coxa=coxa, wheel_radius=WHEEL_RADIUS)
    return wheel_turn(contacts, CIRCLE_R, speed=vx, coxa=coxa, wheel_radius=WHEEL_RADIUS)


def contact(state: LegState) -> tuple[float, float, float]:
    """Where the coordinator puts a wheel: the measured foot on its grid, else the commanded."""
    m, g = state.measured_foot, CONTACT_GRID_M
    if m is None:
        return state.foot
    return (round(m[0] / g) * g, round(m[1] / g) * g, round(m[2] / g) * g)


def wrap(angle: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
    return np.asarray((angle + math.pi) % (2 * math.pi) - math.pi)


@pytest.mark.parametrize("name", list(RIDES))
def test_ride_wheels_follow_the_equations(name: str) -> None:
    """Steady riding: the coordinator's headings and speeds and the legs' direction and wheel
    goals are those of eq. 5.8–5.18 for the feet's contact points and the coxa angles sent."""
    r = ride()
    states = r.log.messages("locomotion", of=LocomotionState)
    times = steady(states, "riding", RIDES[name])
    # The legs act on the BodyMotion of the cycle before (they run beside the coordinator).
    times = [b for a, b in itertools.pairwise(times) if a == previous(states, b)]
    assert len(times) > 50
    motions = {m.t: m for m in r.log.messages("motion", of=BodyMotion)}
    goals = leg_goals(r)
    legs = leg_states(r)
    for t in times:
        contacts = np.array([contact(legs[t][leg]) for leg in range(N_LEGS)])
        coxa = np.array([goal(goals[t][leg], COXA).position_rad for leg in range(N_LEGS)])
        want = expected_wheels(name, contacts, coxa)
        general = wheel_twist(contacts, *RIDES[name], coxa=coxa, wheel_radius=WHEEL_RADIUS)
        np.testing.assert_allclose(want.heading, general.heading, atol=1e-12)
        motion = motions[t]
        assert motion.steer
        np.testing.assert_allclose(motion.wheel_heading_rad, want.heading, atol=1e-9)
        np.testing.assert_allclose(motion.wheel_speed_m_s, want.speed, atol=1e-9)
        direction = np.array([goal(goals[t][leg], DIRECTION).position_rad for leg in range(N_LEGS)])
        rate = np.array([goal(goals[t][leg], WHEEL).velocity_rad_s for leg in range(N_LEGS)])
        # A leg sends a goal again only when it moves by half a tick (HALF_TICK_RAD).
        np.testing.assert_allclose(wrap(direction - want.direction), 0.0, atol=HALF_TICK_RAD)
        np.testing.assert_allclose(rate, want.wheel_rate, atol=1e-9)


@pytest.mark.parametrize("name", list(RIDES))
def test_ride_direction_servos_reach_their_goals(name: str) -> None:
    """By the end of each steady ride the emulated direction servos stand at the goals the
    legs sent and the wheels turn at theirs."""
    r = ride()
    states = r.log.messages("locomotion", of=LocomotionState)
    t = steady(states, "riding", RIDES[name])[-1]
    goals = leg_goals(r)[t]
    present = servo_states(r)[t]
    for leg in range(N_LEGS):
        position, _ = present[(leg, DIRECTION)]
        want = goal(goals[leg], DIRECTION).position_rad
        assert want is not None
        assert abs(wrap(np.array(position - want))) < 0.01, (LEG_NAMES[leg], position, want)
        _, velocity = present[(leg, WHEEL)]
        rate = goal(goals[leg], WHEEL).velocity_rad_s
        assert rate is not None
        assert velocity == pytest.approx(rate, rel=0.02, abs=0.02), LEG_NAMES[leg]


def test_ride_changes_headings_only_at_zero_speed() -> None:
    r = ride()
    riding = {s.t for s in r.log.messages("locomotion", of=LocomotionState) if s.mode == "ride"}
    motions = [m for m in r.log.messages("motion", of=BodyMotion) if m.steer and m.t in riding]
    turned = 0
    for a, b in itertools.pairwise(motions):
        if (
            max(abs(x - y) for x, y in zip(a.wheel_heading_rad, b.wheel_heading_rad, strict=True))
            > 1e-9
        ):
            turned += 1
            assert not any(a.wheel_speed_m_s), b.t
            assert not any(b.wheel_speed_m_s), b.t
    assert turned >= 3


# --------------------------------------------------------------------------- 4. transitions


def test_stance_changes_at_rest() -> None:
    r = stances_at_rest()
    assert r.exit_code == 0
    assert faults(r) == []
    assert changes(r, "stance") == list(zip(("default", *STANCES), STANCES, strict=False))
    activity = [after for _, after in changes(r, "activity")]
    assert activity.count("transition") == len(STANCES)
    after = [activity[k + 1] for k, a in enumerate(activity) if a == "transition"]
    assert after == ["standing"] * len(STANCES)
    before_stop = STANCES_END - 0.1  # the run ends sitting down
    last = [s for s in r.log.messages("locomotion", of=LocomotionState) if s.t < before_stop]
    assert (last[-1].stance, last[-1].activity) == ("default", "standing")


def test_gait_and_stance_changes_while_walking() -> None:
    r = transitions_walk()
    assert r.exit_code == 0
    assert changes(r, "gait") == [("tripod", "ripple"), ("ripple", "wave")]
    assert changes(r, "stance") == list(zip(("default", *STANCES), STANCES, strict=False))
    activity = [after for _, after in changes(r, "activity")]
    # Each change stops the walk, re-places the feet, and the walk resumes.
    assert activity.count("walking") == 1 + 2 + len(STANCES)


def test_gait_and_stance_changes_while_walking_within_limits() -> None:
    assert faults(transitions_walk()) == []


def test_stance_change_right_after_walking_within_limits() -> None:
    r = run_walk([(WALK_START, command(vx_m_s=0.08)), (6.0, command(stance="high"))], duration=9.0)
    assert faults(r) == []
    assert changes(r, "stance") == [("default", "high")]


def test_walk_resumed_after_a_stop_within_limits() -> None:
    r = run_walk(
        [
            (WALK_START, command(vx_m_s=0.06)),
            (5.0, command(stop=True)),
            (8.0, command(vx_m_s=0.06)),
        ],
        duration=12.0,
    )
    assert faults(r) == []


def test_walk_started_in_the_high_stance_within_limits() -> None:
    r = run_walk([(2.6, command(stance="high")), (6.0, command(vx_m_s=0.1))], duration=9.0)
    assert faults(r) == []


def test_walk_ride_walk_and_hybrid() -> None:
    r = ride()
    assert r.exit_code == 0
    assert faults(r) == []
    assert changes(r, "mode") == [
        ("walk", "ride"),
        ("ride", "walk"),
        ("walk", "hybrid"),
        ("hybrid", "walk"),
    ]
    assert changes(r, "stance") == [("default", "basic"), ("basic", "default")]
    activity = [after for _, after in changes(r, "activity")]
    for expected in ("riding", "walking", "hybrid"):
        assert expected in activity
    assert activity.index("riding") < activity.index("walking") < activity.index("hybrid")
    assert "walking" in activity[activity.index("hybrid") :]


def test_hybrid_wheels_stop_in_the_air() -> None:
    """Hybrid gait: the wheels of the feet on the ground drive, a lifted foot's wheel stands."""
    r = ride()
    hybrid = {s.t for s in r.log.messages("locomotion", of=LocomotionState) if s.mode == "hybrid"}
    goals = leg_goals(r)
    legs = leg_states(r)
    rolling = swung = 0
    for t in sorted(hybrid & goals.keys() & legs.keys()):
        for leg, state in legs[t].items():
            rate = goal(goals[t][leg], WHEEL).velocity_rad_s
            if airborne(state, None):
                swung += 1
                assert rate == 0.0, (t, LEG_NAMES[leg])
            elif rate:
                rolling += 1
    assert rolling > 100
    assert swung > 100


# --------------------------------------------------------------------------- 5. straight walk


def test_straight_walk_moves_the_body_as_the_stance_feet_say() -> None:
    """10 s at 0.08 m/s: the body moves by minus the stance feet's mean motion, as far as the
    commanded speed less the ramp carries it."""
    r = gait_walk("tripod")
    speed = GAIT_SPEEDS["tripod"]
    # The walk begins once the feet are placed for the gait (a re-placement after the command).
    start = min(
        m.t for m in r.log.messages("motion", of=BodyMotion) if m.t >= WALK_START and m.twist[0]
    )
    end = start + 10.0
    expected = speed * (end - start - speed / (2 * LOCO.max_accel_m_s2))
    legs = leg_states(r)
    times = [t for t in sorted(legs) if start <= t <= end]
    body = np.zeros(2)
    for a, b in itertools.pairwise(times):
        down = [
            np.subtract(legs[b][leg].foot, legs[a][leg].foot)[:2]
            for leg in range(N_LEGS)
            if not airborne(legs[a][leg], None) and not airborne(legs[b][leg], None)
        ]
        if down:
            body -= np.mean(down, axis=0)
    motions = [m for m in r.log.messages("motion", of=BodyMotion) if start <= m.t <= end]
    integrated = sum(b.twist[0] * (b.t - a.t) for a, b in itertools.pairwise(motions))
    assert integrated == pytest.approx(expected, rel=0.02)
    assert body[0] == pytest.approx(expected, rel=0.05)
    assert abs(body[1]) < 0.005


def tracking(r: RunResult, start: float, end: float) -> tuple[float, int]:
    """(worst distance, lag): how closely the measured feet (LegState.measured_foot) follow the
    commanded feet between ``start`` and ``end``, at the lag in bus cycles that fits best."""
    legs = leg_states(r)
    times = [t for t in sorted(legs) if start <= t <= end]
    best: tuple[float, int] | None = None
    for lag in range(5):
        errors = [
            math.dist(measured, legs[a][leg].foot)
            for a, b in zip(times, times[lag:], strict=False)
            for leg in range(N_LEGS)
            if (measured := legs[b][leg].measured_foot) is not None
        ]
        assert len(errors) == N_LEGS * (len(times) - lag), "a leg reported no measured foot"
        worst = max(errors)
        if best is None or worst < best[0]:
            best = (worst, lag)
    assert best is not None
    return best


def test_measured_feet_track_the_commanded_feet() -> None:
    """Steady walking: the feet the servos report (FK) follow the commanded feet within a few
    millimetres, a few bus cycles behind (goal → write → servo → read)."""
    worst, lag = tracking(gait_walk("tripod"), WALK_START + 2.0, WALK_START + 10.0)
    assert worst < 0.005, (worst, lag)


def test_measured_feet_with_the_default_read_plan() -> None:
    """The default plan does not read the trochanter: the legs take its goal instead."""
    worst, lag = tracking(gait_walk("tetrapod"), WALK_START + 2.0, WALK_START + 8.0)
    assert worst < 0.005, (worst, lag)


# --------------------------------------------------------------------------- 6. flip


def flip_windows(r: RunResult) -> list[tuple[float, float]]:
    """(start, end) of each turn of the legs about their trochanters."""
    events = [e for e in r.log.events(of=LocomotionChanged) if e.what == "activity"]
    starts = [e.t for e in events if e.after == "flipping"]
    ends = [e.t for e in events if e.before == "flipping"]
    return list(zip(starts, ends, strict=False))


def test_flip_completes_within_the_limits() -> None:
    r = flip()
    assert r.exit_code == 0
    assert faults(r) == []
    assert changes(r, "upside_down") == [("False", "True"), ("True", "False")]
    assert len(flip_windows(r)) == 2


def upside_down_walking(r: RunResult, upside_down: bool) -> list[float]:
    return [
        s.t
        for s in r.log.messages("locomotion", of=LocomotionState)
        if s.upside_down == upside_down and s.activity == "walking"
    ]


def test_flipped_legs_hold_the_trochanter_at_minus_pi_and_walk() -> None:
    r = flip()
    times = upside_down_walking(r, True)
    assert times
    goals = leg_goals(r)
    present = servo_states(r)
    for t in times:
        for leg in range(N_LEGS):
            troch = goal(goals[t][leg], TROCHANTER).position_rad
            assert troch == pytest.approx(FLIPPED_TROCHANTER, abs=HALF_TICK_RAD)  # tick 0
            assert goal(goals[t][leg], DIRECTION).position_rad == 0.0
            assert goal(goals[t][leg], WHEEL).velocity_rad_s == 0.0
            position, _ = present[t][(leg, TROCHANTER)]
            assert abs(abs(position) - math.pi) < 0.01
    swings = count_swings(r, times)
    assert min(swings) >= 1, swings


def test_flipped_back_legs_stand_upright() -> None:
    r = flip()
    back = flip_windows(r)[-1][1]
    times = [
        s.t
        for s in r.log.messages("locomotion", of=LocomotionState)
        if not s.upside_down and s.activity == "standing" and s.t > back + 0.5
    ]
    assert len(times) > 50
    goals = leg_goals(r)
    present = servo_states(r)
    for t in times:
        for leg in range(N_LEGS):
            assert goal(goals[t][leg], TROCHANTER).position_rad == pytest.approx(
                0, abs=HALF_TICK_RAD
            )
            position, _ = present[t][(leg, TROCHANTER)]
            assert abs(position) < 0.01


def count_swings(r: RunResult, times: Iterable[float]) -> list[int]:
    """Swings each leg started within ``times``."""
    legs = leg_states(r)
    ordered = sorted(times)
    started = [0] * N_LEGS
    for a, b in itertools.pairwise(ordered):
        for leg in range(N_LEGS):
            if legs[b][leg].phase == "swing" and legs[a][leg].phase != "swing":
                started[leg] += 1
    return started


FLIP_STEP = 0.1
"""Largest trochanter goal change per bus cycle of a flip (the min-jerk turn of π in
``flip_s`` peaks at 1.875·π/flip_s ≈ 3 rad/s, 0.04 rad a cycle)."""


@pytest.mark.parametrize(
    "which",
    ["over", "back"],
)
def test_flip_turns_the_trochanters_gradually(which: str) -> None:
    r = flip()
    start, end = flip_windows(r)[0 if which == "over" else 1]
    goals = leg_goals(r)
    times = [t for t in sorted(goals) if start - 0.1 <= t <= end]
    turned = 0.0
    for leg in range(N_LEGS):
        angles = np.array([goal(goals[t][leg], TROCHANTER).position_rad for t in times])
        steps = np.abs(np.diff(angles))
        assert steps.max() <= FLIP_STEP, (LEG_NAMES[leg], times[int(steps.argmax()) + 1])
        turned = max(turned, float(np.abs(angles[-1] - angles[0])))
    assert turned == pytest.approx(math.pi, abs=HALF_TICK_RAD)


# --------------------------------------------------------------------------- 7. bad input


def test_bad_commands_are_refused_and_nothing_applies() -> None:
    r = bad_input()
    refused = r.log.events(of=CommandRefused)
    assert len(refused) == len(BAD_COMMANDS)
    for phrase, event in zip(BAD_COMMANDS, refused, strict=True):
        assert phrase in event.reason, (phrase, event)
    assert [e for e in r.log.events(of=LocomotionChanged) if WALK_START <= e.t < BAD_END] == []
    for s in r.log.messages("locomotion", of=LocomotionState):
        if WALK_START <= s.t < BAD_END:
            assert (s.activity, s.mode, s.gait, s.stance) == (
                "standing",
                "walk",
                "tripod",
                "default",
            )
            assert s.twist == (0.0, 0.0, 0.0)
            assert not s.upside_down
            assert s.swing_legs == ()
    assert [s for s in r.log.messages("steps", of=StepCommand) if WALK_START <= s.t < BAD_END] == []
    assert faults(r) == []


def test_too_long_step_and_too_fast_walk_are_clamped() -> None:
    r = bad_input()
    clamped = r.log.events(of=CommandClamped)
    assert [e.field for e in clamped] == ["step_length_m", "speed"]
    step, speed = clamped
    assert step.requested == TOO_LONG_STEP
    assert step.applied == LOCO.max_step_length_mm / 1000
    assert speed.requested == pytest.approx(TOO_FAST)
    assert 0.0 < speed.applied < TOO_FAST
    fastest = max(s.twist[0] for s in r.log.messages("locomotion", of=LocomotionState))
    assert fastest == pytest.approx(speed.applied)
    assert faults(r) == []


def test_reflex_takes_the_joint_and_hands_it_back_smoothly() -> None:
    """An override goal for RF's femur: the leg alone decides its joints' goals. It holds
    the override's angle and reports the phase "reflex" while the goal holds
    (``reflex_hold_s`` from its time), then blends back to its own trajectory without a jump.
    The bus gets one goal message per leg and cycle — and the override's joint the moment
    it arrives — never a reflex one, each goal once."""
    r = reflex()
    assert faults(r) == []
    release = REFLEX_T + LOCO.reflex_hold_s
    to_bus = r.log.messages("goals", of=JointGoals)
    assert not any(m.reflex for m in to_bus)
    assert max(Counter((m.source, m.t) for m in to_bus).values()) == 1
    legs = leg_states(r)
    held = sorted(t for t, by_leg in legs.items() if by_leg[0].phase == "reflex")
    assert held
    taken = held[0]  # the first cycle after the override arrived
    assert abs(taken - REFLEX_T) < 0.05  # within a bus cycle (stamped with its read time)
    assert held[-1] > release - 0.02
    for t, by_leg in legs.items():
        assert (by_leg[0].phase == "reflex") == (taken <= t <= release), t
        assert all(by_leg[leg].phase != "reflex" for leg in range(1, N_LEGS))
    femur_said = [
        (m.t, g.position_rad)
        for m in to_bus
        if m.source == "leg-RF"
        for g in m.goals
        if g.joint == FEMUR and taken <= m.t <= release
    ]
    # Said once, as the override arrived (not at the leg's next cycle); the bus keeps it.
    assert femur_said == [(REFLEX_T, REFLEX_FEMUR)]
    goals = leg_goals(r)
    femur = [(t, goal(goals[t][0], FEMUR).position_rad) for t in sorted(goals)]
    # In force from its arrival (the cycle that reports it is stamped with its read time,
    # a little before).
    assert all(a == REFLEX_FEMUR for t, a in femur if REFLEX_T <= t <= release)
    # Handed back without a jump, then on the trajectory (the IK of the commanded foot).
    released = [a for t, a in femur if t >= REFLEX_T]
    assert float(np.abs(np.diff(np.array(released, dtype=float))).max()) < 0.03
    trajectory = [
        (t, a, trajectory_femur(legs[t][0]))
        for t, a in femur
        if WALK_START < t < taken or t > release + LOCO.reflex_blend_s + 0.02
    ]
    assert len(trajectory) > 300
    for t, angle, want in trajectory:
        assert angle == pytest.approx(want, abs=HALF_TICK_RAD), t
    # The blend did change something: the reflex's angle is far from the trajectory's.
    assert abs(trajectory_femur(legs[taken][0]) - REFLEX_FEMUR) > 0.1


def trajectory_femur(state: LegState) -> float:
    """The femur angle of the commanded foot of leg RF (upright, level body)."""
    feet = np.zeros((N_LEGS, 3))
    feet[state.leg] = state.foot
    point = body_to_leg(feet, GEOMETRY)[state.leg]
    return float(ik(point, GEOMETRY, target="contact").angles[FEMUR])


# --------------------------------------------------------------------------- 8. determinism


def test_same_scenario_same_log() -> None:
    first, second = short_walk(), short_walk()
    assert len(first.log.entries) > 1000
    assert first.log.digest() == second.log.digest()
