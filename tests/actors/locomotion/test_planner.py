"""The coordinator's policy, called directly: no runtime, no bus, no clock (milliseconds).

The legs are perfect here: each foot is at its last step's target once the step's time is
over (and on its way, linearly, before).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

import pytest

from whexar.actors.locomotion.activity import TRANSITIONS, Activity, ActivityError, checked
from whexar.actors.locomotion.intent import Wanted, take_command
from whexar.actors.locomotion.planner import LocomotionPlanner
from whexar.actors.messages import (
    BodyMotion,
    CommandClamped,
    CommandRefused,
    JointState,
    LegState,
    LocomotionChanged,
    LocomotionState,
    MotionCommand,
    ReflexRequest,
    Restepped,
    ServoStates,
    StepCommand,
    SwingDelayed,
)
from whexar.config import RobotConfig
from whexar.kinematics.gait import TRIPOD
from whexar.robot import LEG_NAMES, N_LEGS
from whexar.runtime.messages import Message

CFG = RobotConfig()
DT = 0.01


def cmd(**fields: object) -> MotionCommand:
    return MotionCommand(t=0.0, source="test", **fields)  # type: ignore[arg-type]


class PerfectLegs:
    """Six legs that carry out every step exactly: linearly from where they were."""

    def __init__(self) -> None:
        self.steps: dict[int, tuple[StepCommand, tuple[float, float, float]]] = {}
        self.feet: dict[int, tuple[float, float, float]] = {}
        self.judged_at: dict[int, float] = {}
        """Legs whose touchdown is awaited (``touchdown_pending``) until a time."""

    def take(self, step: StepCommand) -> None:
        start = self.feet.get(step.leg, step.target)
        self.steps[step.leg] = (step, start)

    def states(self, t: float, cycle: int) -> list[LegState]:
        out = []
        for leg, (step, start) in self.steps.items():
            u = min(max((t - step.start_t) / step.duration_s, 0.0), 1.0)
            foot = (
                start[0] + (step.target[0] - start[0]) * u,
                start[1] + (step.target[1] - start[1]) * u,
                start[2] + (step.target[2] - start[2]) * u,
            )
            self.feet[leg] = foot
            out.append(
                LegState(
                    t=t,
                    source=f"leg-{LEG_NAMES[leg]}",
                    leg=leg,
                    cycle=cycle,
                    phase=step.kind,
                    progress=u,
                    foot=foot,
                    measured_foot=None,
                    contact=True,
                    contact_source="none",
                    load=(None, None),
                    touchdown_pending=t < self.judged_at.get(leg, -math.inf),
                )
            )
        return out


def drive(
    planner: LocomotionPlanner,
    legs: PerfectLegs,
    t0: float,
    t1: float,
    commands: Mapping[float, MotionCommand] = {},
    requests: Mapping[float, ReflexRequest] = {},
    joints: Callable[[float], tuple[JointState, ...]] = lambda t: (),
) -> list[Message]:
    """Cycles every :data:`DT` from ``t0`` to ``t1``; each command and request at its time,
    the servo states carrying ``joints(t)``."""
    said: list[Message] = []
    n = round((t1 - t0) / DT)
    for k in range(n):
        t = round(t0 + k * DT, 9)
        cycle = round(t / DT)
        states = ServoStates(t=t, source="bus", cycle=cycle, joints=joints(t))
        now = [c for at, c in commands.items() if abs(at - t) < DT / 2]
        asked = [r for at, r in requests.items() if abs(at - t) < DT / 2]
        out = planner.cycle(states, commands=now, legs=legs.states(t, cycle), requests=asked)
        for msg in out:
            if isinstance(msg, StepCommand):
                legs.take(msg)
        said.extend(out)
    return said


def standing() -> tuple[LocomotionPlanner, PerfectLegs]:
    planner = LocomotionPlanner(CFG, name="coordinator")
    legs = PerfectLegs()
    drive(planner, legs, 0.0, CFG.locomotion.stand_up_s + 0.3)
    assert planner.activity == Activity.STANDING
    return planner, legs


T0 = 3.0
"""When a walk below starts: the planner stands by then."""


def walked(
    seconds: float,
    requests: Mapping[float, ReflexRequest] = {},
    joints: Callable[[float], tuple[JointState, ...]] = lambda t: (),
) -> tuple[LocomotionPlanner, list[Message]]:
    """A standing planner asked to walk at 0.1 m/s at :data:`T0`, cycled ``seconds`` on
    with ``requests`` at their times: the planner, and what it said."""
    planner, legs = standing()
    said = drive(planner, legs, T0, T0 + seconds, {T0: cmd(vx_m_s=0.1)}, requests, joints)
    return planner, said


def activities(said: list[Message]) -> list[tuple[str, str]]:
    return [
        (e.before, e.after)
        for e in said
        if isinstance(e, LocomotionChanged) and e.what == "activity"
    ]


# --------------------------------------------------------------------------- activities


def test_every_activity_has_its_transitions_and_seated_is_left_only_by_a_flip() -> None:
    assert set(TRANSITIONS) == set(Activity)
    for before, after in TRANSITIONS.items():
        assert before not in after
        if before not in (Activity.SEATED, Activity.SITTING_DOWN):
            assert Activity.SITTING_DOWN in after  # a stop can always sit down
    assert TRANSITIONS[Activity.SEATED] == {Activity.FLIPPING}
    assert TRANSITIONS[Activity.SITTING_DOWN] == {Activity.SEATED}


def test_a_change_the_table_does_not_hold_is_an_error() -> None:
    assert checked(Activity.STANDING, Activity.WALKING) is Activity.WALKING
    with pytest.raises(ActivityError, match="seated cannot change to walking"):
        checked(Activity.SEATED, Activity.WALKING)
    planner = LocomotionPlanner(CFG, name="coordinator")
    planner.activity = Activity.SITTING_DOWN
    with pytest.raises(ActivityError):
        planner.set_activity(Activity.WALKING)


# --------------------------------------------------------------------------- scripts


def test_it_stands_up_in_two_moves_of_every_leg() -> None:
    planner = LocomotionPlanner(CFG, name="coordinator")
    legs = PerfectLegs()
    said = drive(planner, legs, 0.0, CFG.locomotion.stand_up_s + 0.3)
    moves = [m for m in said if isinstance(m, StepCommand)]
    assert [m.kind for m in moves] == ["move"] * 12
    assert sorted(m.leg for m in moves[:6]) == list(range(N_LEGS))
    seated, stood = moves[0].target[2], moves[6].target[2]
    assert seated == pytest.approx(-CFG.locomotion.sit_height_mm / 1000)
    assert stood == pytest.approx(-CFG.stance("default").height)
    assert activities(said) == [("standing_up", "standing")]
    # Every cycle says the body motion, then the state.
    motions = [m for m in said if isinstance(m, BodyMotion)]
    states = [m for m in said if isinstance(m, LocomotionState)]
    assert len(motions) == len(states) == round((CFG.locomotion.stand_up_s + 0.3) / DT)
    assert isinstance(said[-1], LocomotionState)
    assert states[-1].activity == "standing"


def test_a_tripod_walk_lifts_one_group_at_a_time_and_keeps_its_margin() -> None:
    planner, legs = standing()
    t0 = 3.0
    said = drive(planner, legs, t0, t0 + 6.0, {t0: cmd(vx_m_s=0.1)})
    swings = [m for m in said if isinstance(m, StepCommand) and m.kind == "swing"]
    assert len(swings) >= 12
    groups = {frozenset(LEG_NAMES.index(n) for n in g) for g in TRIPOD.groups}
    by_time: dict[float, set[int]] = {}
    for s in swings:
        by_time.setdefault(s.t, set()).add(s.leg)
    assert {frozenset(legs_) for legs_ in by_time.values()} <= groups
    states = [m for m in said if isinstance(m, LocomotionState) and m.activity == "walking"]
    assert states
    minimum = CFG.locomotion.min_stability_margin_mm / 1000
    assert min(s.margin_m for s in states) >= minimum
    assert max(s.twist[0] for s in states) == pytest.approx(0.1)
    assert not [m for m in said if isinstance(m, SwingDelayed)]


def test_a_gait_change_winds_down_first() -> None:
    planner, legs = standing()
    t0 = 3.0
    said = drive(planner, legs, t0, t0 + 8.0, {t0: cmd(vx_m_s=0.1), t0 + 3.0: cmd(gait="ripple")})
    changes = [e for e in said if isinstance(e, LocomotionChanged) and e.what == "gait"]
    assert [(e.before, e.after) for e in changes] == [("tripod", "ripple")]
    # When the gait changed the body was still and no leg was in the air.
    at = changes[0].t
    state = next(m for m in said if isinstance(m, LocomotionState) and m.t >= at)
    assert state.twist == (0.0, 0.0, 0.0)
    assert state.swing_legs == ()
    assert planner.gait.name == "ripple"
    assert ("standing", "walking") in activities(said)


def test_a_safe_stop_sits_down_and_refuses_what_comes_after() -> None:
    planner, legs = standing()
    t0 = 3.0
    drive(planner, legs, t0, t0 + 2.0, {t0: cmd(vx_m_s=0.1)})
    assert planner.begin_sit(t0 + 2.0)
    said = drive(planner, legs, t0 + 2.0, t0 + 4.5, {t0 + 2.5: cmd(vx_m_s=0.1)})
    assert activities(said)[-2:] == [("walking", "sitting_down"), ("sitting_down", "seated")]
    (refused,) = [e for e in said if isinstance(e, CommandRefused)]
    assert refused.reason == "a safe stop is under way"
    assert not planner.begin_sit(t0 + 4.5)  # seated already
    assert all(f is not None and f[2] > -0.1 for f in legs.feet.values())


def ask(reflex: str = "reflex-test", **fields: object) -> ReflexRequest:
    return ReflexRequest(t=0.0, source=reflex, reflex=reflex, **fields)  # type: ignore[arg-type]


def states_of(said: list[Message]) -> list[LocomotionState]:
    return [m for m in said if isinstance(m, LocomotionState)]


def test_a_reflex_that_asks_to_sit_down_sits_the_robot_and_it_stays_seated() -> None:
    planner, legs = standing()
    t0 = 3.0
    drive(planner, legs, t0, t0 + 2.0, {t0: cmd(vx_m_s=0.1)})
    said = drive(
        planner,
        legs,
        t0 + 2.0,
        t0 + 5.0,
        {t0 + 4.0: cmd(vx_m_s=0.1)},
        {t0 + 2.0: ask("reflex-battery", sit_down=True, reason="battery at 10.1 V")},
    )
    (seated_by,) = [e for e in said if isinstance(e, LocomotionChanged) and e.what == "seated_by"]
    assert seated_by.after == "reflex-battery: battery at 10.1 V"
    assert activities(said)[-2:] == [("walking", "sitting_down"), ("sitting_down", "seated")]
    (refused,) = [e for e in said if isinstance(e, CommandRefused)]
    assert refused.reason == "reflex-battery sat the robot down: battery at 10.1 V"
    assert planner.activity == Activity.SEATED


def test_a_halt_stops_the_body_until_withdrawn_and_the_walk_goes_on() -> None:
    t0 = T0
    planner, said = walked(
        8.0,
        {t0 + 2.0: ask(halt=True, reason="obstacle"), t0 + 5.0: ask(halt=False)},
    )
    speed = {round(s.t, 2): s.twist[0] for s in states_of(said)}
    assert speed[t0 + 1.9] == pytest.approx(0.1)
    assert speed[t0 + 4.9] == pytest.approx(0.0, abs=1e-6)  # held still
    assert speed[t0 + 7.9] == pytest.approx(0.1)  # the operator's walk again
    assert planner.want.vx == pytest.approx(0.1)  # what the operator wants never changed


def test_the_step_is_as_high_as_the_highest_request_within_the_limit() -> None:
    planner, legs = standing()
    t0 = 3.0
    own = planner.want.step_height
    limit = CFG.locomotion.max_step_height_mm / 1000
    said = drive(
        planner,
        legs,
        t0,
        t0 + 9.0,
        {t0: cmd(vx_m_s=0.1)},
        {
            t0 + 2.0: ask("reflex-a", step_height_m=own + 0.02),
            t0 + 4.0: ask("reflex-b", step_height_m=10.0),
            t0 + 6.0: ask("reflex-b", step_height_m=0.0),
        },
    )
    swings = [(m.t, m.height_m) for m in said if isinstance(m, StepCommand) and m.kind == "swing"]
    heights = {
        "before": {round(h, 6) for t, h in swings if t < t0 + 2.0},
        "one": {round(h, 6) for t, h in swings if t0 + 2.1 < t < t0 + 4.0},
        "both": {round(h, 6) for t, h in swings if t0 + 4.1 < t < t0 + 6.0},
        "one again": {round(h, 6) for t, h in swings if t > t0 + 6.1},
    }
    assert heights == {
        "before": {round(own, 6)},
        "one": {round(own + 0.02, 6)},
        "both": {round(limit, 6)},
        "one again": {round(own + 0.02, 6)},
    }


def test_a_raise_lifts_the_operators_step_within_the_limit() -> None:
    planner, legs = standing()
    t0 = 3.0
    own = planner.want.step_height
    said = drive(
        planner,
        legs,
        t0,
        t0 + 6.0,
        {t0: cmd(vx_m_s=0.1)},
        {t0 + 2.0: ask(step_raise_m=0.03), t0 + 4.0: ask(step_raise_m=0.0)},
    )
    swings = [(m.t, m.height_m) for m in said if isinstance(m, StepCommand) and m.kind == "swing"]
    raised = {round(h, 6) for t, h in swings if t0 + 2.1 < t < t0 + 4.0}
    after = {round(h, 6) for t, h in swings if t > t0 + 4.1}
    assert raised == {round(own + 0.03, 6)}
    assert after == {round(own, 6)}


def test_swings_search_as_deep_as_the_deepest_request() -> None:
    t0 = T0
    _, said = walked(
        6.0,
        {
            t0 + 2.0: ask("reflex-a", search_depth_m=0.06),
            t0 + 3.0: ask("reflex-b", search_depth_m=0.08),
            t0 + 4.0: ask("reflex-b", search_depth_m=0.0),
        },
    )
    swings = [(m.t, m.search_depth_m) for m in said if isinstance(m, StepCommand)]
    swings = [(t, d) for t, d in swings if d is not None]
    assert {d for t, d in swings if t < t0 + 2.0} == {0.0}
    assert {d for t, d in swings if t0 + 3.1 < t < t0 + 4.0} == {0.08}
    assert {d for t, d in swings if t > t0 + 4.1} == {0.06}
    moves = [m for m in said if isinstance(m, StepCommand) and m.kind != "swing"]
    assert {m.search_depth_m for m in moves} <= {0.0}  # only swings search


def test_swings_stances_reach_as_far_as_asked_until_withdrawn() -> None:
    t0 = T0
    _, said = walked(
        5.0,
        {t0 + 2.0: ask("reflex-a", reach_depth_m=0.06), t0 + 3.5: ask("reflex-a", reach_depth_m=0)},
    )
    swings = [(m.t, m.reach_depth_m) for m in said if isinstance(m, StepCommand)]
    assert {d for t, d in swings if t < t0 + 2.0} == {0.0}
    assert {d for t, d in swings if t0 + 2.0 < t < t0 + 3.5} == {0.06}
    assert {d for t, d in swings if t > t0 + 3.5} == {0.0}


def test_a_restep_halts_the_walk_steps_the_leg_and_the_walk_goes_on() -> None:
    t0 = T0
    planner, said = walked(
        8.0,
        {t0 + 2.0: ask("reflex-stepping", restep_leg=2, restep_offset_m=(0.03, 0.0))},
    )
    (done,) = [m for m in said if isinstance(m, Restepped)]
    n = planner.neutral_points[2]
    assert (done.leg, done.reflex, done.done) == (2, "reflex-stepping", True)
    assert done.target == pytest.approx((n[0] + 0.03, n[1], n[2]))
    (step,) = [
        m for m in said if isinstance(m, StepCommand) and m.leg == 2 and m.target == done.target
    ]
    assert step.kind == "swing"
    assert step.t > t0 + 2.0
    # Nothing else moved while it swung; the walk went on after.
    others = [m for m in said if isinstance(m, StepCommand) and step.t <= m.t < done.t]
    assert others == [step]
    speed = {round(s.t, 2): s.twist[0] for s in states_of(said)}
    assert speed[t0 + 7.9] == pytest.approx(0.1)


def lifted(said: list[Message], leg: int) -> list[float]:
    """When ``leg`` was told to lift its foot: a swing, or a move through the air."""
    return [
        m.t
        for m in said
        if isinstance(m, StepCommand)
        and m.leg == leg
        and (m.kind == "swing" or (m.kind == "move" and m.height_m > 0.0))
    ]


@pytest.mark.parametrize(("pending_s", "lifts_by"), [(1.0, 1.0), (math.inf, 2.65)])
def test_a_walk_starts_once_every_touchdown_is_judged(pending_s: float, lifts_by: float) -> None:
    # RM's last step still searches for the ground: lifted now, it would be judged in
    # the air. The start waits for its judgement, or at most a touchdown's wait and a
    # search as deep as the highest step (0.25 s + 12 cm at 5 cm/s) for a leg that never
    # says.
    planner, legs = standing()
    legs.judged_at[2] = T0 + pending_s
    said = drive(planner, legs, T0, T0 + 6.0, {T0: cmd(vx_m_s=0.1)})
    first = min(t for leg in range(N_LEGS) for t in lifted(said, leg))
    assert T0 + min(pending_s, lifts_by) <= first <= T0 + lifts_by + 0.05
    assert planner.activity == Activity.WALKING


def test_a_restep_is_refused_on_the_wheels_and_for_no_such_leg() -> None:
    planner, legs = standing()
    said = drive(planner, legs, 2.8, 3.0, {}, {2.8: ask(restep_leg=9)})
    (bad,) = [m for m in said if isinstance(m, Restepped)]
    assert (bad.done, bad.reason) == (False, "no leg 9: legs are 0…5")
    said = drive(planner, legs, 3.0, 3.5, {}, {3.0: ask(restep_leg=0)})
    said += drive(planner, legs, 3.5, 7.0, {3.5: cmd(mode="ride")}, {6.5: ask(restep_leg=0)})
    refused = [m for m in said if isinstance(m, Restepped)]
    assert [(m.done, m.reason) for m in refused] == [
        (True, ""),
        (False, "riding: the legs stand on their wheels"),
    ]


def test_a_heading_correction_turns_a_translating_body_only() -> None:
    planner, legs = standing()
    t0 = 3.0
    said = drive(planner, legs, t0, t0 + 2.0, requests={t0: ask(yaw_rate_rad_s=0.05)})
    assert all(s.twist == (0.0, 0.0, 0.0) for s in states_of(said))  # standing: no spin
    said = drive(planner, legs, t0 + 2.0, t0 + 6.0, {t0 + 2.0: cmd(vx_m_s=0.1)})
    assert states_of(said)[-1].twist[2] == pytest.approx(0.05)
    said = drive(planner, legs, t0 + 6.0, t0 + 8.0, requests={t0 + 6.0: ask(yaw_rate_rad_s=0.0)})
    assert states_of(said)[-1].twist[2] == pytest.approx(0.0, abs=1e-9)


def test_no_sit_down_when_the_bus_went_silent() -> None:
    planner, _ = standing()
    assert not planner.begin_sit(planner.last_states_t + 0.5)


# --------------------------------------------------------------------------- commands


def test_a_bad_command_is_refused_whole() -> None:
    want = Wanted.of(CFG)
    before = Wanted.of(CFG)
    for bad, reason in [
        (cmd(vx_m_s=0.1, gait="gallop"), "unknown gait"),
        (cmd(mode="fly"), "unknown mode"),
        (cmd(stance="squat"), "unknown stance"),
        (cmd(vx_m_s=math.nan), "not a finite number"),
        (cmd(mode="ride", upside_down=True), "upside down"),
        (cmd(vx_m_s=0.1, turn_radius_m=0.05), "inside the body"),
    ]:
        (event,) = take_command(want, bad, CFG, t=1.0, source="coordinator")
        assert isinstance(event, CommandRefused)
        assert reason in event.reason
        assert want == before


def test_a_command_beyond_a_limit_is_clamped_and_the_rest_applies() -> None:
    want = Wanted.of(CFG)
    events = take_command(
        want, cmd(vx_m_s=0.05, step_height_m=1.0, roll_rad=1.0), CFG, t=1.0, source="c"
    )
    assert [(e.field, e.applied) for e in events if isinstance(e, CommandClamped)] == [
        ("step_height_m", CFG.locomotion.max_step_height_mm / 1000),
        ("roll_rad", math.radians(20.0)),
    ]
    assert want.vx == 0.05
    assert want.step_height == CFG.locomotion.max_step_height_mm / 1000


def test_a_turn_radius_sets_the_yaw_rate_from_the_speed() -> None:
    want = Wanted.of(CFG)
    take_command(want, cmd(vx_m_s=0.1, turn_radius_m=1.0), CFG, t=0.0, source="c")
    vx, vy, w = want.twist()
    assert (vx, vy) == (0.1, 0.0)
    assert w == pytest.approx(0.1)
    take_command(want, cmd(yaw_rate_rad_s=0.2), CFG, t=0.0, source="c")
    assert want.twist() == (0.1, 0.0, 0.2)


def test_too_fast_a_walk_is_clamped_once_per_command() -> None:
    planner, legs = standing()
    said = drive(planner, legs, 3.0, 4.0, {3.0: cmd(vx_m_s=5.0)})
    (clamped,) = [e for e in said if isinstance(e, CommandClamped)]
    assert clamped.field == "speed"
    assert 0.0 < clamped.applied < 5.0


def _tilted(planner: LocomotionPlanner, pitch: float) -> None:
    """The planner settled on ground tilted by ``pitch`` (its low-pass run out)."""
    planner.tilt_pitch = pitch
    planner.tilt_measured = (0.0, pitch)


def test_on_a_slope_the_margin_projects_the_cog_along_gravity() -> None:
    # Nose up on 23° without the trochanter: the robot's CoG, 43 mm below the coxa joints
    # (body.cog_mm), 0.247 m above the feet, falls 0.247 m · tan 23° = 105 mm behind the
    # point below it, and a tripod's margin is 158 − 0.80·247·tan θ mm (the slopes note's
    # 158 − 233·tan θ for a CoG at the body centre).
    planner, legs = standing()
    planner.loco = planner.loco.model_copy(update={"trochanter_follows_pitch": False})
    flat = planner.margin([0, 3, 4])
    assert flat == pytest.approx(0.158, abs=0.002)
    _tilted(planner, math.radians(-23.0))
    drive(planner, legs, 3.0, 3.05)
    assert planner.trochanter_rad == 0.0
    assert planner.margin([0, 3, 4]) == pytest.approx(
        0.158 - 0.80 * 0.247 * math.tan(math.radians(23)), abs=0.003
    )
    # A CoG at the body centre (as the slopes note had it) leaves less.
    planner.cog = (0.0, 0.0, 0.0)
    assert planner.margin([0, 3, 4]) == pytest.approx(
        0.158 - 0.233 * math.tan(math.radians(23)), abs=0.003
    )


def test_the_trochanter_arc_brings_the_feet_back_under_the_cog() -> None:
    # With the trochanter the feet move downhill by depth·sin θ: most of the margin returns.
    planner, legs = standing()
    _tilted(planner, math.radians(-23.0))
    drive(planner, legs, 3.0, 3.05)
    assert planner.trochanter_rad == pytest.approx(math.radians(-23.0))
    without = 0.158 - 0.80 * 0.247 * math.tan(math.radians(23))
    assert planner.margin([0, 3, 4]) > without + 0.06


def test_the_trochanter_follows_the_pitch_up_to_its_configured_limit() -> None:
    planner, legs = standing()
    _tilted(planner, math.radians(-70.0))
    drive(planner, legs, 3.0, 3.05)
    assert planner.trochanter_rad == pytest.approx(-math.radians(CFG.locomotion.max_trochanter_deg))


def test_the_stances_share_their_load_where_the_ground_tilts_enough() -> None:
    # contact.balance_tilt_deg (20°): on 15° the steps are plain, on 25° every swing carries
    # the share (for the stance it goes on into); the moves that settle the feet do not.
    def steps_on(pitch_deg: float, roll_deg: float = 0.0) -> list[StepCommand]:
        planner, legs = standing()
        planner.tilt_measured = (math.radians(roll_deg), math.radians(pitch_deg))
        planner.tilt_roll, planner.tilt_pitch = planner.tilt_measured
        said = drive(planner, legs, T0, T0 + 3.0, {T0: cmd(vx_m_s=0.1)})
        return [m for m in said if isinstance(m, StepCommand)]

    assert CFG.contact.balance_tilt_deg == 20.0
    assert not any(s.share_load for s in steps_on(-15.0))
    tilted = steps_on(-25.0)
    assert {s.kind for s in tilted if s.share_load} == {"swing"}
    assert all(s.share_load for s in tilted if s.kind == "swing")
    # Tilted across (roll) as well as along: the angle from level: 14.2° each way is 20°.
    assert all(s.share_load for s in steps_on(-14.4, 14.4) if s.kind == "swing")
    assert not any(s.share_load for s in steps_on(-14.0, 14.0))
