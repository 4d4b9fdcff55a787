"""The leg's policy, called directly: no runtime, no bus, no clock (milliseconds)."""

from __future__ import annotations

import math
from collections.abc import Callable

import pytest

from whexar.actors.locomotion.leg_controller import LegController
from whexar.actors.locomotion.wire_goals import HALF_TICK_RAD
from whexar.actors.messages import (
    BodyMotion,
    IkFailed,
    JointGoal,
    JointGoals,
    JointState,
    LegLoads,
    LegState,
    ServoStates,
    StepCommand,
    SwingEnded,
)
from whexar.config import RobotConfig
from whexar.kinematics.body import leg_to_body, stance_feet
from whexar.kinematics.leg import fk_point
from whexar.runtime.messages import Message

CFG = RobotConfig()
GEOMETRY = CFG.leg_geometry()
DT = 0.02
FEMUR = 2
_X, _Y, _Z = (float(v) for v in leg_to_body(stance_feet(CFG.stance("default")), GEOMETRY)[0])
NEUTRAL = (_X, _Y, _Z)
"""RF's neutral foot point, upright frame."""
LOADED_A = 1.5
"""A femur current above ``locomotion.contact_current_a``: the foot carries weight."""


def states(t: float, angles: list[float], *, femur_a: float = 0.0) -> ServoStates:
    """Servo states of RF at ``t``: its joints at ``angles`` (coxa…tarsus), its femur
    drawing ``femur_a``."""
    joints = tuple(
        JointState(
            leg=0,
            joint=j,
            servo_id=j + 1,
            position_rad=angles[j] if j < 5 else 0.0,
            current_a=femur_a if j == FEMUR else 0.0,
        )
        for j in range(7)
    )
    return ServoStates(t=t, source="bus", cycle=round(t / DT), joints=joints)


def step(
    kind: str,
    t: float,
    duration: float,
    target: tuple[float, float, float],
    *,
    height_m: float = 0.0,
    search_depth_m: float = 0.0,
    reach_depth_m: float = 0.0,
    share_load: bool = False,
) -> StepCommand:
    return StepCommand(
        t=t,
        source="coordinator",
        leg=0,
        kind=kind,
        start_t=t,
        duration_s=duration,
        target=target,
        height_m=height_m,
        search_depth_m=search_depth_m,
        reach_depth_m=reach_depth_m,
        share_load=share_load,
    )


def body_motion(
    t: float,
    *,
    trochanter_rad: float = 0.0,
    steer: bool = False,
    heading_rad: float = 0.0,
    speed_m_s: float = 0.0,
) -> BodyMotion:
    """The coordinator's body motion at ``t``: the body still, in its neutral pose."""
    return BodyMotion(
        t=t,
        source="coordinator",
        cycle=round(t / DT),
        twist=(0.0, 0.0, 0.0),
        pose=(0.0,) * 6,
        trochanter_rad=trochanter_rad,
        upside_down=False,
        steer=steer,
        wheel_heading_rad=(heading_rad,) * 6,
        wheel_speed_m_s=(speed_m_s,) * 6,
    )


def goals_of(out: list[Message]) -> list[JointGoals]:
    return [m for m in out if isinstance(m, JointGoals)]


def follow_goals(angles: list[float], said: list[Message]) -> None:
    """The servos reach the positioning goals the leg said, by the next cycle."""
    for msg in goals_of(said):
        for g in msg.goals:
            if g.joint < 5 and g.position_rad is not None:
                angles[g.joint] = g.position_rad


def run(
    leg: LegController,
    t0: float,
    t1: float,
    angles: list[float],
    *,
    femur_a: float | None = None,
    steps: tuple[StepCommand, ...] = (),
    overrides: tuple[JointGoals, ...] = (),
    follow: bool = True,
) -> list[Message]:
    """Cycles from ``t0`` to ``t1``; the servos reach each goal by the next cycle when
    ``follow``; with ``femur_a`` None the femur is loaded when the foot is on the ground."""
    out: list[Message] = []
    t = t0
    first = True
    while t < t1 - 1e-9:
        amps = femur_a
        if amps is None:
            amps = LOADED_A if leg.foot is None or leg.foot[2] <= NEUTRAL[2] + 1e-4 else 0.0
        said = leg.cycle(
            t,
            states(t, angles, femur_a=amps),
            steps=steps if first else (),
            overrides=overrides if first else (),
        )
        first = False
        out.extend(said)
        if follow:
            follow_goals(angles, said)
        t = round(t + DT, 9)
    return out


def placed(contact: str = "current", cfg: RobotConfig = CFG) -> tuple[LegController, list[float]]:
    """RF standing on its neutral point after its first move, from a seated pose."""
    leg = LegController(cfg, 0, name="leg-RF", contact=contact)  # type: ignore[arg-type]
    angles = [0.0, 0.0, 0.6, -1.6, -0.5]
    run(leg, 0.0, 1.06, angles, steps=(step("move", 0.0, 1.0, NEUTRAL),))
    return leg, angles


def test_nothing_is_said_before_the_first_step() -> None:
    leg = LegController(CFG, 0, name="leg-RF")
    assert leg.cycle(0.0, states(0.0, [0.0, 0.0, 0.5, -1.5, -0.6])) == []


def test_the_first_move_starts_from_the_reported_pose_in_joint_space() -> None:
    leg = LegController(CFG, 0, name="leg-RF", contact="none")
    seated = [0.1, 0.0, 0.6, -1.6, -0.5]
    out = run(leg, 0.0, 1.1, list(seated), steps=(step("move", 0.0, 1.0, NEUTRAL),))
    first = goals_of(out)[0]
    # The first goals are the pose the servos report (min-jerk at u = 0), not a jump.
    for g in first.goals:
        if g.joint < 5:
            assert g.position_rad == pytest.approx(seated[g.joint], abs=1e-9)
    # It ends on the IK of the target: the foot where it was sent.
    assert leg.angles is not None
    assert leg.frame.from_leg(fk_point(leg.angles, GEOMETRY)) == pytest.approx(NEUTRAL, abs=1e-6)
    states_said = [m for m in out if isinstance(m, LegState)]
    assert [s.phase for s in states_said][:3] == ["move"] * 3
    assert states_said[-1].phase == "hold"


def test_goals_are_said_only_when_they_change_by_half_a_tick() -> None:
    leg, angles = placed()
    out = run(leg, 1.06, 1.5, angles)  # holding still
    assert goals_of(out) == []
    assert leg.angles is not None
    leg.sent[FEMUR] = leg.angles[FEMUR] + 0.9 * HALF_TICK_RAD  # within half a tick
    assert goals_of(run(leg, 1.5, 1.52, angles)) == []
    leg.sent[FEMUR] = leg.angles[FEMUR] + 1.1 * HALF_TICK_RAD
    (said,) = goals_of(run(leg, 1.52, 1.54, angles))
    assert [g.joint for g in said.goals] == [FEMUR]


def swing_target() -> tuple[float, float, float]:
    return (NEUTRAL[0] + 0.05, NEUTRAL[1], NEUTRAL[2])


def swing_ends(out: list[Message]) -> list[SwingEnded]:
    return [m for m in out if isinstance(m, SwingEnded)]


def swing(
    leg: LegController,
    angles: list[float],
    amps: Callable[[float, float], float],
    follow: Callable[[float], bool] | None = None,
) -> list[Message]:
    """A 0.5 s swing from 1.1 s, run to 1.9 s; the femur draws ``amps(u, foot z)`` at the
    swing's phase u and the foot's height of the cycle before. The servos reach each goal
    by the next cycle while ``follow(u)`` (never without it)."""
    cmd = step("swing", 1.1, 0.5, swing_target(), height_m=0.04)
    out: list[Message] = []
    t = 1.1
    while t < 1.9:
        assert leg.foot is not None
        u = (t - 1.1) / 0.5
        current = amps(u, leg.foot[2])
        steps = (cmd,) if t == 1.1 else ()
        said = leg.cycle(t, states(t, angles, femur_a=current), steps=steps)
        out.extend(said)
        if follow is not None and follow(u):
            follow_goals(angles, said)
        t = round(t + DT, 9)
    return out


def test_a_swing_that_lands_where_expected_is_completed() -> None:
    leg, angles = placed()
    # The sensor feels the ground from the cycle the swing ends on (u = 1).
    out = swing(leg, angles, lambda u, z: LOADED_A if u >= 1.0 - 1e-9 else 0.0)
    (ended,) = swing_ends(out)
    assert (ended.outcome, ended.leg, ended.source) == ("completed", 0, "leg-RF")
    assert ended.ground_offset_m == pytest.approx(0.0, abs=1e-9)
    assert any(isinstance(m, LegState) and m.phase == "swing" for m in out)


def test_a_swing_that_ends_without_sensing_contact_is_completed() -> None:
    leg, angles = placed("none")
    out = run(
        leg, 1.1, 1.8, angles, steps=(step("swing", 1.1, 0.5, swing_target(), height_m=0.04),)
    )
    assert [e.outcome for e in swing_ends(out)] == ["completed"]


def test_a_swing_without_ground_ends_with_no_contact_once_touchdown_has_passed() -> None:
    leg, angles = placed()
    out = run(
        leg,
        1.1,
        1.9,
        angles,
        femur_a=0.0,
        steps=(step("swing", 1.1, 0.5, swing_target(), height_m=0.04),),
    )
    (ended,) = swing_ends(out)
    assert ended.outcome == "no_contact"
    # Judged touchdown_s after the swing's end (1.6 s), on the first cycle past it.
    assert 1.6 + CFG.contact.touchdown_s <= ended.t < 1.6 + CFG.contact.touchdown_s + DT
    after = [m.phase for m in out if isinstance(m, LegState) and m.t > 1.61]
    assert after == ["stance"] * len(after)
    assert len(after) >= 13


def cycles(
    leg: LegController,
    angles: list[float],
    until: float,
    steps: Callable[[float], tuple[StepCommand, ...]],
    amps: Callable[[float], float],
) -> list[Message]:
    """Cycles from 1.1 s to ``until``, the servos following their goals: ``steps(t)`` the
    steps arriving at ``t``, ``amps(t)`` the femur's current then."""
    out: list[Message] = []
    t = 1.1
    while t < until:
        said = leg.cycle(t, states(t, angles, femur_a=amps(t)), steps=steps(t))
        follow_goals(angles, said)
        out.extend(said)
        t = round(t + DT, 9)
    return out


def searching_swing(
    leg: LegController, angles: list[float], ground_z: float, until: float
) -> list[Message]:
    """A 0.5 s swing from 1.1 s that searches 6 cm down, the servos following their goals;
    the femur feels the ground once the foot is at ``ground_z`` or below."""
    cmd = step("swing", 1.1, 0.5, swing_target(), height_m=0.04, search_depth_m=0.06)

    def amps(t: float) -> float:
        assert leg.foot is not None
        return LOADED_A if t > 1.15 and leg.foot[2] <= ground_z + 1e-9 else 0.0

    return cycles(leg, angles, until, lambda t: (cmd,) if t == 1.1 else (), amps)


def test_a_searching_foot_the_ground_holds_has_found_it() -> None:
    # An unloaded leg: no current, whatever the foot meets; the servos stop at the floor.
    leg, angles = placed()
    cmd = step("swing", 1.1, 0.5, swing_target(), height_m=0.04, search_depth_m=0.06)
    out: list[Message] = []
    t = 1.1
    while t < 3.0:
        said = leg.cycle(t, states(t, angles, femur_a=0.0), steps=(cmd,) if t == 1.1 else ())
        assert leg.foot is not None
        if leg.foot[2] >= NEUTRAL[2] - 0.02:  # above the floor, 2 cm down: they follow
            follow_goals(angles, said)
        out.extend(said)
        t = round(t + DT, 9)
    (ended,) = swing_ends(out)
    assert ended.outcome == "completed"
    # Held at −2 cm; found once its goal went search_stop_m (15 mm) further down.
    stop = CFG.contact.search_stop_m
    assert -0.02 - stop - 0.003 <= ended.ground_offset_m <= -0.02 - stop + 0.003


def test_a_swing_that_searches_finds_lower_ground_and_stands_there() -> None:
    leg, angles = placed()
    ground = NEUTRAL[2] - 0.03  # a hole 3 cm deep under the target
    out = searching_swing(leg, angles, ground, 3.0)
    (ended,) = swing_ends(out)
    assert ended.outcome == "completed"
    assert ended.ground_offset_m == pytest.approx(-0.03, abs=0.002)
    phases = [m.phase for m in out if isinstance(m, LegState)]
    assert "search" in phases
    # Judged after touchdown_s, then 0.6 s down at 0.05 m/s: at 1.6 + 0.25 + 0.6 s.
    assert ended.t == pytest.approx(1.6 + CFG.contact.touchdown_s + 0.6, abs=0.03)
    assert leg.foot is not None
    assert leg.foot[2] == pytest.approx(ground, abs=0.002)  # the stance goes on from there


def test_a_swing_that_finds_nothing_within_its_depth_ends_with_no_contact() -> None:
    leg, angles = placed()
    out = searching_swing(leg, angles, NEUTRAL[2] - 0.5, 4.0)
    (ended,) = swing_ends(out)
    assert ended.outcome == "no_contact"
    assert ended.ground_offset_m == pytest.approx(-0.06)
    assert ended.t == pytest.approx(1.6 + CFG.contact.touchdown_s + 0.06 / 0.05, abs=0.03)


def test_a_contact_that_lags_the_swing_end_still_completes_it() -> None:
    leg, angles = placed()
    # The sensor feels the ground 0.12 s after the swing's end (the FSR's lag).
    out = swing(leg, angles, lambda u, z: LOADED_A if u >= 1.0 + 0.12 / 0.5 - 1e-9 else 0.0)
    (ended,) = swing_ends(out)
    assert ended.outcome == "completed"
    assert ended.t == pytest.approx(1.72)


def test_a_swing_stopped_on_the_way_down_ends_early_and_the_stance_stays_there() -> None:
    leg, angles = placed()
    ground = NEUTRAL[2] + 0.02  # 2 cm above the floor: met past the apex, coming down
    out = swing(
        leg, angles, lambda u, z: LOADED_A if u > 0.5 and z <= ground else 0.0, lambda u: True
    )
    (ended,) = swing_ends(out)
    assert ended.outcome == "early_contact"
    assert 0.0 < ended.ground_offset_m <= 0.025
    assert leg.foot is not None
    assert leg.foot[2] == pytest.approx(NEUTRAL[2] + ended.ground_offset_m)


def test_a_swing_stopped_by_an_edge_stands_where_its_foot_stopped() -> None:
    leg, angles = placed()
    # The foot meets a face at 80 % of the swing and stays there; its goal runs on, and
    # the contact comes (the force sensor's lag) a tenth of the swing later.
    out = swing(leg, angles, lambda u, z: LOADED_A if u >= 0.9 else 0.0, lambda u: u < 0.8 - 1e-9)
    (ended,) = swing_ends(out)
    assert ended.outcome == "early_contact"
    stopped = leg.frame.from_leg(fk_point(angles, GEOMETRY))
    assert stopped[0] < swing_target()[0] - 0.005  # short of the target: the face held it
    # The stance starts where the foot stands across the ground, not where its goal had
    # gone on to, so the leg does not push into the face; up and down it keeps its goal.
    assert leg.foot is not None
    assert leg.foot[:2] == pytest.approx(stopped[:2], abs=1e-6)
    assert leg.foot[2] < stopped[2]
    run(leg, 1.9, 2.0, angles, follow=False)
    on_the_wire = leg.frame.from_leg(fk_point(leg.sent[:5], GEOMETRY))
    assert on_the_wire[:2] == pytest.approx(stopped[:2], abs=1e-3)


def test_a_swing_that_never_lifted_its_foot_keeps_its_goal_when_it_stops_early() -> None:
    leg, angles = placed()
    # The foot never leaves its ground (a loaded leg that cannot lift): contact on the way
    # up, then again past the apex. The first is its load coming and going, not a block
    # (the joints never lifted it); its stance goes on from its goal: no edge stopped it.
    out = swing(
        leg, angles, lambda u, z: LOADED_A if 0.1 < u < 0.3 or u >= 0.6 else 0.0, lambda u: False
    )
    assert [e.outcome for e in swing_ends(out)] == ["early_contact"]
    stood = leg.frame.from_leg(fk_point(angles, GEOMETRY))
    assert leg.foot is not None
    assert leg.foot[0] > stood[0] + 0.02


def test_a_contact_that_began_before_the_foot_rose_is_not_a_block() -> None:
    leg, angles = placed()
    # The foot's load comes back as it lifts (a neighbour not yet down): the force sensor
    # reads contact from before the joints raised the foot and goes on reading it, lagging,
    # as they lift it. Nothing stood in its path.
    out = swing(leg, angles, lambda u, z: LOADED_A if 0.1 < u < 0.3 else 0.0, lambda u: True)
    assert "blocked" not in [e.outcome for e in swing_ends(out)]


def test_contact_on_the_way_up_is_blocked_once_and_the_swing_goes_on() -> None:
    leg, angles = placed()
    # Something pushes back on the way up, the foot lifted, then lets go.
    out = swing(leg, angles, lambda u, z: LOADED_A if 0.2 < u < 0.3 else 0.0, lambda u: u < 0.2)
    outcomes = [e.outcome for e in swing_ends(out)]
    assert outcomes[0] == "blocked"
    assert outcomes.count("blocked") == 1
    assert outcomes[-1] == "no_contact"


def test_a_contact_that_never_went_away_is_not_believed() -> None:
    leg, angles = placed()
    out = run(
        leg,
        1.1,
        1.8,
        angles,
        femur_a=LOADED_A,
        steps=(step("swing", 1.1, 0.5, swing_target(), height_m=0.04),),
    )
    # Neither blocked nor stopped early: the swing runs its course, then the stance.
    (ended,) = swing_ends(out)
    assert ended.outcome == "completed"
    assert ended.t == pytest.approx(1.6)
    assert leg.foot is not None
    assert leg.foot[0] == pytest.approx(swing_target()[0])


def override(t: float, angle: float, *, priority: int = 0, source: str = "reflex") -> JointGoals:
    g = JointGoal(t=t, source=source, leg=0, joint=FEMUR, position_rad=angle)
    return JointGoals(t=t, source=source, goals=(g,), reflex=True, priority=priority)


def femur_goals(out: list[Message]) -> list[tuple[float, float]]:
    return [
        (m.t, g.position_rad)
        for m in goals_of(out)
        for g in m.goals
        if g.joint == FEMUR and g.position_rad is not None
    ]


@pytest.mark.parametrize("order", [(0, 1), (1, 0)])
def test_contradictory_overrides_in_one_cycle_are_decided_by_priority(
    order: tuple[int, int],
) -> None:
    leg, angles = placed("none")
    own = angles[FEMUR]
    low = override(2.0, own + 0.2, priority=1, source="low")
    high = override(2.0, own - 0.2, priority=5, source="high")
    msgs = tuple((low, high)[i] for i in order)
    out = run(leg, 2.0, 2.1, angles, overrides=msgs)
    assert femur_goals(out)[0] == (2.0, own - 0.2)


def test_a_lower_priority_override_waits_for_a_higher_one_to_let_go() -> None:
    leg, angles = placed("none")
    own = angles[FEMUR]
    hold = CFG.locomotion.reflex_hold_s
    run(leg, 2.0, 2.05, angles, overrides=(override(2.0, own - 0.2, priority=5, source="hi"),))
    # Still held: a lower priority's goal is refused, an equal or higher one taken.
    run(leg, 2.05, 2.1, angles, overrides=(override(2.05, own + 0.2, priority=1, source="lo"),))
    assert leg.overrides.held[FEMUR][0] == own - 0.2
    out = run(
        leg, 2.1, 2.15, angles, overrides=(override(2.1, own + 0.3, priority=5, source="hi"),)
    )
    assert femur_goals(out)[0] == (2.1, own + 0.3)
    # Once it is no longer held, the lower priority takes the joint.
    later = 2.1 + hold + 0.05
    run(leg, 2.15, later, angles)
    out = run(
        leg, later, later + 0.05, angles, overrides=(override(later, own + 0.1, source="lo"),)
    )
    assert femur_goals(out)[0] == (later, own + 0.1)


def test_an_override_holds_the_joint_then_blends_back_without_a_jump() -> None:
    leg, angles = placed("none")
    own = angles[FEMUR]
    hold, blend = CFG.locomotion.reflex_hold_s, CFG.locomotion.reflex_blend_s
    out = run(leg, 2.0, 2.0 + hold + blend + 0.2, angles, overrides=(override(2.0, own + 0.4),))
    said = goals_of(out)
    assert not any(m.reflex for m in said)  # the bus gets the leg's own goals only
    femur = [
        (m.t, g.position_rad)
        for m in said
        for g in m.goals
        if g.joint == FEMUR and g.position_rad is not None
    ]
    assert femur[0] == (2.0, own + 0.4)  # taken at once
    assert all(a == own + 0.4 for t, a in femur if t <= 2.0 + hold)
    back = [a for t, a in femur if t > 2.0 + hold]
    assert back
    steps_ = [abs(b - a) for a, b in zip([own + 0.4, *back], back, strict=False)]
    assert max(steps_) < 0.05  # no jump
    assert back[-1] == pytest.approx(own, abs=HALF_TICK_RAD)
    phases = [(m.t, m.phase) for m in out if isinstance(m, LegState)]
    assert all((p == "reflex") == (t <= 2.0 + hold) for t, p in phases)


def test_an_override_for_another_leg_or_the_wheel_is_ignored() -> None:
    leg, angles = placed("none")
    other = JointGoal(t=2.0, source="reflex", leg=1, joint=FEMUR, position_rad=0.3)
    wheel = JointGoal(t=2.0, source="reflex", leg=0, joint=6, position_rad=0.3)
    nan = JointGoal(t=2.0, source="reflex", leg=0, joint=FEMUR, position_rad=math.nan)
    msgs = (JointGoals(t=2.0, source="reflex", goals=(other, wheel, nan), reflex=True),)
    out = run(leg, 2.0, 2.1, angles, overrides=msgs)
    assert goals_of(out) == []
    assert leg.overrides.held == {}


def test_an_unreachable_foot_holds_the_last_good_pose_and_says_so_once() -> None:
    leg, angles = placed("none")
    before = list(angles)
    far = (NEUTRAL[0] + 2.0, NEUTRAL[1], NEUTRAL[2])
    out = run(leg, 2.0, 2.5, angles, steps=(step("move", 2.0, 0.2, far),))
    failures = [m for m in out if isinstance(m, IkFailed)]
    assert len(failures) == 1
    assert 2.0 <= failures[0].t <= 2.2  # stamped with the clock's time handed in
    assert angles[FEMUR] == pytest.approx(before[FEMUR], abs=0.2)
    assert [m.ik_ok for m in out if isinstance(m, LegState)][-1] is False


def test_the_wheel_steers_to_the_heading_less_the_coxa_and_stops_in_the_air() -> None:
    leg, angles = placed("none")
    motion = body_motion(2.0, steer=True, heading_rad=0.3, speed_m_s=0.1)
    out = leg.cycle(2.0, states(2.0, angles), motion=motion)
    (said,) = goals_of(out)
    by_joint = {g.joint: g for g in said.goals}
    assert leg.angles is not None
    assert by_joint[5].position_rad == pytest.approx(0.3 - leg.angles[0])  # s·ψ − coxa, s = 1
    assert by_joint[6].velocity_rad_s == pytest.approx(0.1 / GEOMETRY.wheel_radius)


def test_the_trochanter_carries_the_foot_on_its_arc() -> None:
    # Nose up on 32°: the trochanter turns to the pitch and the foot goes where the
    # thesis's leg puts it, back and up by the arc (kinematics.leg.trochanter_arc).
    leg, angles = placed()
    theta = math.radians(-32.0)
    motion = body_motion(1.1, trochanter_rad=theta)
    leg.cycle(1.1, states(1.1, angles, femur_a=LOADED_A), motion=motion)
    assert leg.angles is not None
    assert leg.angles[1] == pytest.approx(theta)
    foot = leg.frame.from_leg(fk_point(leg.angles, GEOMETRY))
    depth = leg.frame.to_leg(NEUTRAL)[1]
    expected = (
        NEUTRAL[0] + depth * math.sin(theta),
        NEUTRAL[1],
        NEUTRAL[2] + depth * (1 - math.cos(theta)),
    )
    assert foot == pytest.approx(expected, abs=1e-6)
    # What the leg says is its plan, in the upright frame, which the arc does not change.
    assert leg.foot == pytest.approx(NEUTRAL)


def test_a_stop_during_a_touchdown_waits_for_it_before_judging() -> None:
    leg, angles = placed()
    # The swing ends at 1.6 s, no contact yet; a hold (the walk stops) comes at 1.65 s and
    # the sensor feels the ground at 1.75 s (its lag): completed, not a foot left hanging.
    cmd = step("swing", 1.1, 0.5, swing_target(), height_m=0.04)
    hold = step("hold", 1.65, 0.2, swing_target())
    out = cycles(
        leg,
        angles,
        2.2,
        lambda t: (cmd,) if t == 1.1 else (hold,) if t == pytest.approx(1.66) else (),
        lambda t: LOADED_A if t >= 1.75 else 0.0,
    )
    (ended,) = swing_ends(out)
    assert ended.outcome == "completed"
    assert ended.t == pytest.approx(1.76)


def test_a_settling_move_during_a_search_lets_the_search_go_on() -> None:
    leg, angles = placed()
    # A hole 3 cm deep under the target; 0.2 s into the search (1 cm down) the walk is
    # held and the planner settles the foot where it is (a move on the ground).
    ground = NEUTRAL[2] - 0.03
    cmd = step("swing", 1.1, 0.5, swing_target(), height_m=0.04, search_depth_m=0.06)
    settle = [1.6 + CFG.contact.touchdown_s + 0.2]

    def steps(t: float) -> tuple[StepCommand, ...]:
        assert leg.foot is not None
        if t == 1.1:
            return (cmd,)
        if t < settle[0]:
            return ()
        settle[0] = math.inf
        assert leg.foot[2] == pytest.approx(NEUTRAL[2] - 0.01, abs=0.002)
        return (step("move", t, 0.2, (leg.foot[0], leg.foot[1], leg.foot[2])),)

    def amps(t: float) -> float:
        assert leg.foot is not None
        return LOADED_A if t > 1.15 and leg.foot[2] <= ground + 1e-9 else 0.0

    (ended,) = swing_ends(cycles(leg, angles, 3.0, steps, amps))
    # Found, not cut short at 1 cm: judged against the swing's ground, the stance there.
    assert ended.outcome == "completed"
    assert ended.ground_offset_m == pytest.approx(-0.03, abs=0.002)
    assert leg.foot is not None
    assert leg.foot[2] == pytest.approx(ground, abs=0.002)


def test_a_search_goes_on_through_settling_moves_one_after_another() -> None:
    leg, angles = placed()
    # The walk held as the swing ends: the planner settles the foot every 0.2 s with a
    # 0.2 s move, so the foot is always moving. The search, once
    # left for the moves' ends, never ran (a foot hanging over a slope's foot for 5 s).
    ground = NEUTRAL[2] - 0.03
    cmd = step("swing", 1.1, 0.5, swing_target(), height_m=0.04, search_depth_m=0.06)

    def steps(t: float) -> tuple[StepCommand, ...]:
        if t == 1.1:
            return (cmd,)
        if t >= 1.7 and round((t - 1.7) / DT) % round(0.2 / DT) == 0:
            assert leg.foot is not None  # to where the leg says the foot is, as the planner
            return (step("move", t, 0.2, (leg.foot[0], leg.foot[1], leg.foot[2])),)
        return ()

    def amps(t: float) -> float:
        assert leg.foot is not None
        return LOADED_A if t > 1.15 and leg.foot[2] <= ground + 1e-9 else 0.0

    out = cycles(leg, angles, 3.2, steps, amps)
    (ended,) = swing_ends(out)
    assert ended.outcome == "completed"
    assert ended.ground_offset_m == pytest.approx(-0.03, abs=0.002)
    # As soon as without the moves: touchdown_s, then 0.6 s down at 0.05 m/s.
    assert ended.t == pytest.approx(1.6 + CFG.contact.touchdown_s + 0.6, abs=0.03)
    assert leg.foot is not None
    assert leg.foot[2] == pytest.approx(ground, abs=0.002)  # the moves keep it there
    pending = [m.t for m in out if isinstance(m, LegState) and m.touchdown_pending]
    assert min(pending) == pytest.approx(1.6, abs=0.03)  # the coordinator is told
    assert max(pending) == pytest.approx(ended.t - DT, abs=0.03)


def test_a_stance_foot_its_force_sensor_reads_lighter_than_the_others_goes_down() -> None:
    def loads(t: float, rf: int) -> LegLoads:
        counts = (rf, 500, 500, 500, 500, 500)
        contacts = (True,) * 6
        return LegLoads(t=t, source="sensors", seq=None, counts=counts, contacts=contacts)

    # The stance sharing its load (where the coordinator asks it: on a slope): read through
    # its force sensor, the foot goes down; read through the current, or not asked, it holds.
    gain = 5e-5
    cfg = RobotConfig.model_validate({"contact": {"balance_gain_m_s": gain}})
    for source, share, lower in (
        ("fsr", True, True),
        ("current", True, False),
        ("fsr", False, False),
    ):
        leg, angles = placed(source, cfg)
        t, first = 1.1, True
        while t < 1.6:
            said = leg.cycle(
                t,
                states(t, angles, femur_a=LOADED_A),
                loads=loads(t, 300),  # 200 counts under the loaded feet's mean
                steps=(step("stance", 1.1, 2.0, NEUTRAL, share_load=share),) if first else (),
            )
            follow_goals(angles, said)
            first, t = False, round(t + DT, 9)
        assert leg.foot is not None
        # Down at 5e-5 m/s per count of the 167 under the six feet's mean of 467.
        expected = NEUTRAL[2] - (gain * 167 * 0.5 if lower else 0.0)
        assert leg.foot[2] == pytest.approx(expected, abs=0.0008), (source, share)


def lost_support(
    leg: LegController, angles: list[float], drop_m: float, reach_m: float = 0.06
) -> list[Message]:
    """A swing whose stance reaches ``reach_m`` lands on the ground expected at 1.6 s; at
    2.5 s that ground drops ``drop_m`` under the stance foot (a support giving way)."""
    cmd = step("swing", 1.1, 0.5, swing_target(), height_m=0.04, reach_depth_m=reach_m)

    def amps(t: float) -> float:
        assert leg.foot is not None
        ground = NEUTRAL[2] - (drop_m if t >= 2.5 else 0.0)
        return LOADED_A if t > 1.15 and leg.foot[2] <= ground + 1e-9 else 0.0

    return cycles(leg, angles, 5.0, lambda t: (cmd,) if t == 1.1 else (), amps)


def test_a_stance_foot_that_loses_its_support_reaches_down_for_it() -> None:
    leg, angles = placed()
    out = lost_support(leg, angles, 0.03)
    assert [e.outcome for e in swing_ends(out)] == ["completed"]
    said = [m for m in out if isinstance(m, LegState)]
    reaching = [s.t for s in said if s.phase == "search"]
    # It held the loss touchdown_s, then went down at search_speed (3 cm: 0.6 s).
    assert reaching[0] == pytest.approx(2.5 + CFG.contact.touchdown_s, abs=0.03)
    assert reaching[-1] == pytest.approx(2.5 + CFG.contact.touchdown_s + 0.6, abs=0.04)
    assert said[-1].phase == "stance"
    assert leg.foot is not None
    assert leg.foot[2] == pytest.approx(NEUTRAL[2] - 0.03, abs=0.002)  # it stands there


def test_a_stance_foot_reaches_down_only_when_its_swing_asked_it_to() -> None:
    leg, angles = placed()
    out = lost_support(leg, angles, 0.03, reach_m=0.0)
    assert "search" not in {m.phase for m in out if isinstance(m, LegState)}
    assert leg.foot is not None
    assert leg.foot[2] == pytest.approx(NEUTRAL[2], abs=1e-6)


def test_a_stance_foot_reaches_down_no_further_than_its_depth() -> None:
    leg, angles = placed()
    out = lost_support(leg, angles, 0.5)
    # Down from 2.75 s at 0.05 m/s: the 6 cm by 3.95 s, then it stands where it got.
    after = [m.phase for m in out if isinstance(m, LegState) and m.t > 4.0]
    assert after == ["stance"] * len(after)
    assert leg.foot is not None
    assert leg.foot[2] == pytest.approx(NEUTRAL[2] - 0.06, abs=1e-6)
