"""The searching reflex's policy, called directly: it asks every swing to search down,
steps a foot that found nothing around, then holds the body; a support lost in stance is
stepped again (4.2.2, 6.7.3)."""

from __future__ import annotations

from whexar.actors.messages import LegState, NoFoothold, ReflexRequest, SwingEnded
from whexar.actors.reactive import Command, check_params
from whexar.actors.reactive.searching import Searching
from whexar.config import RobotConfig
from whexar.testing.reflexes import leg_state, locomotion_state

CFG = RobotConfig()


def searching(**params: object) -> Searching:
    return Searching(check_params(Searching, params), name="reflex-searching", cfg=CFG)


def ended(t: float, outcome: str, leg: int = 1, confidence: float = 0.9) -> SwingEnded:
    """A swing's end: a failed search 6 cm down, or ground where expected."""
    return SwingEnded(
        t=t,
        source="leg",
        leg=leg,
        outcome=outcome,  # type: ignore[arg-type]
        ground_offset_m=-0.06 if outcome == "no_contact" else 0.0,
        confidence=confidence,
    )


def state(t: float, phase: str, contact: bool, leg: int = 2, z: float = 0.0) -> LegState:
    return leg_state(t, leg, phase, contact=contact, foot_z=z)


def requests(out: object) -> list[ReflexRequest]:
    return [m for m in out if isinstance(m, ReflexRequest)]  # type: ignore[attr-defined]


def test_it_asks_every_swing_to_search_once() -> None:
    s = searching(depth_m=0.05)
    (req,) = requests(s.tick(0.5))
    assert req.search_depth_m == 0.05
    assert requests(s.tick(1.0)) == []


def test_nothing_found_steps_around_then_holds_the_body_until_ground_is_found() -> None:
    s = searching()
    out: list[Command] = [*s.react(1.0, ended(1.0, "no_contact"))]
    out += s.react(2.0, ended(2.0, "no_contact"))
    (forward, back) = requests(out)
    assert (forward.restep_leg, forward.restep_offset_m) == (1, (0.04, 0.0))
    assert (back.restep_leg, back.restep_offset_m) == (1, (-0.04, 0.0))
    assert s.active
    last = [*s.react(3.0, ended(3.0, "no_contact"))]
    (halt,) = requests(last)
    assert halt.halt is True
    (said,) = [m for m in last if isinstance(m, NoFoothold)]
    assert (said.leg, said.attempts, said.searched_m) == (1, 2, 0.06)
    # The leg found ground at last: the body goes on, the reflex is quiet.
    (go,) = requests(s.react(4.0, ended(4.0, "completed")))
    assert go.halt is False
    assert not s.active


def test_a_foot_that_finds_ground_only_when_stepped_around_has_no_foothold() -> None:
    # At the 20 cm trench's edge the body tipped: a rear foot found the floor when stepped
    # around, lost it at its next swing, and the count began again, 6 s a round, for good.
    s = searching()
    out: list[Command] = []
    for t in (1.0, 3.0):
        out += s.react(t, ended(t, "no_contact"))  # its gait's swing: nothing
        out += s.react(t + 1.0, ended(t + 1.0, "completed"))  # stepped around: found
    last = [*s.react(5.0, ended(5.0, "no_contact"))]
    assert [r.restep_offset_m for r in requests(out)] == [(0.04, 0.0), (-0.04, 0.0)]
    (halt,) = requests(last)
    assert halt.halt is True  # the safe stop
    # A swing of its gait that finds ground is a foothold: the count starts again.
    s.react(6.0, ended(6.0, "completed"))
    s.react(7.0, ended(7.0, "completed"))
    (again,) = requests(s.react(8.0, ended(8.0, "no_contact")))
    assert again.restep_offset_m == (0.04, 0.0)


def test_a_loss_the_contact_estimate_does_not_believe_is_left_alone() -> None:
    s = searching()
    assert requests(s.react(1.0, ended(1.0, "no_contact", confidence=0.2))) == []
    assert not s.active


def test_a_support_lost_in_stance_is_stepped_again_once() -> None:
    s = searching()
    lost = CFG.contact.touchdown_s
    assert requests(s.react(1.0, state(1.0, "stance", True))) == []
    out: list[Command] = []
    for k in range(60):
        t = 1.01 + 0.01 * k
        out += s.react(t, state(t, "stance", False))
    (req,) = requests(out)
    assert (req.restep_leg, req.restep_offset_m) == (2, (0.0, 0.0))
    assert req.t >= 1.01 + lost - 1e-9
    assert "lost its support" in s.reason


def test_a_stance_foot_reaching_into_a_hole_is_active_and_stepped_again_if_it_finds_none() -> None:
    s = searching()
    s.react(0.5, locomotion_state(0.5, "walking", gait="ripple"))
    s.react(1.0, state(1.0, "stance", True, z=-0.29))
    # The leg held the loss itself and reaches down (phase search): nothing is asked, and
    # nothing is a hole before the foot is found_m (2.5 cm) below where it stood.
    assert requests(s.react(1.3, state(1.3, "search", False, z=-0.29))) == []
    assert requests(s.react(1.4, state(1.4, "search", False, z=-0.31))) == []
    assert not s.active
    assert requests(s.react(1.5, state(1.5, "search", False, z=-0.315))) == []
    assert s.active
    assert "reaching down" in s.reason
    # It found ground 3 cm down: the walk went on all along; the reflex is quiet soon after.
    assert requests(s.react(1.6, state(1.6, "stance", True, z=-0.32))) == []
    assert "found ground 3 cm lower" in s.reason
    s.tick(1.6 + 0.5)
    assert not s.active
    # Its swing came while it reached: that swing searches, nothing is asked.
    s.react(2.0, state(2.0, "stance", True))
    s.react(2.3, state(2.3, "search", False))
    s.react(2.35, state(2.35, "search", False, z=-0.02))
    assert requests(s.react(2.4, state(2.4, "swing", False))) == []
    assert not s.active
    s.react(2.9, state(2.9, "stance", True))
    # Later it loses it again, and finds nothing within its reach.
    s.react(3.0, state(3.0, "search", False))
    (req,) = requests(s.react(4.2, state(4.2, "stance", False, z=-0.06)))
    assert (req.restep_leg, req.restep_offset_m) == (2, (0.0, 0.0))
    assert "stepped again" in s.reason
    assert s.active


def test_a_stance_foot_that_finds_the_ground_within_found_m_is_no_activation() -> None:
    # On 30° the body rolls off a middle foot every few steps; it reaches a few millimetres
    # and has its load back (in 200 s, 98 reaches, the deepest 1.4 cm): no hole.
    s = searching()
    s.react(0.5, locomotion_state(0.5, "walking", gait="wave"))
    s.react(1.0, state(1.0, "stance", True, z=-0.29))
    s.react(1.3, state(1.3, "search", False, z=-0.29))
    s.react(1.4, state(1.4, "search", False, z=-0.304))
    assert requests(s.react(1.45, state(1.45, "stance", True, z=-0.304))) == []
    assert not s.active
    assert s.reason == ""


def test_stance_feet_are_asked_to_reach_down_where_four_or_five_feet_hold_the_body() -> None:
    s = searching()
    (ripple,) = requests(s.react(0.5, locomotion_state(0.5, "walking", gait="ripple")))
    assert ripple.reach_depth_m == 0.06
    assert requests(s.react(0.6, locomotion_state(0.6, "walking", gait="wave"))) == []
    (tripod,) = requests(s.react(0.7, locomotion_state(0.7, "walking", gait="tripod")))
    assert tripod.reach_depth_m == 0.0


def test_in_the_tripod_a_stance_foot_reaching_down_is_stepped_again_at_once() -> None:
    s = searching()
    s.react(0.5, locomotion_state(0.5, "walking", gait="tripod"))
    s.react(1.0, state(1.0, "stance", True))
    (req,) = requests(s.react(1.3, state(1.3, "search", False)))
    assert (req.restep_leg, req.restep_offset_m) == (2, (0.0, 0.0))


def test_a_stance_that_never_had_contact_is_no_loss() -> None:
    s = searching()
    out: list[Command] = []
    for k in range(60):
        out += s.react(1.0 + 0.01 * k, state(1.0 + 0.01 * k, "stance", False))
    assert requests(out) == []


def test_ground_found_a_hole_deep_is_a_moment_of_activity_a_press_is_not() -> None:
    s = searching()
    s.react(1.0, state(1.0, "search", False))
    assert not s.active  # the leg searches on its own
    pressed = SwingEnded(t=1.5, source="leg", leg=2, outcome="completed", ground_offset_m=-0.02)
    s.react(1.5, pressed)
    assert not s.active  # 2 cm: on 30° the ground itself is found that much lower
    hole = SwingEnded(t=2.0, source="leg", leg=2, outcome="completed", ground_offset_m=-0.03)
    s.react(2.0, hole)
    assert s.active
    assert s.reason == "RM found ground 3 cm lower"
    s.tick(2.2)
    assert s.active
    s.tick(2.6)
    assert not s.active


def test_in_a_gait_left_out_of_around_gaits_the_walk_goes_on_without_the_foothold() -> None:
    s = searching(around_gaits=("tripod",))
    s.react(0.5, locomotion_state(0.5, "walking", gait="ripple"))
    # No step around (it would halt the walk): the leg tries again at its next swing.
    out = list(s.react(1.0, ended(1.0, "no_contact")))
    assert requests(out) == []
    (said,) = [m for m in out if isinstance(m, NoFoothold)]
    assert (said.leg, said.attempts) == (1, 0)
    assert s.active
    # The leg found ground at its next swing: the reflex is quiet.
    assert requests(s.react(2.0, ended(2.0, "completed"))) == []
    assert not s.active
    # A support lost in stance: the other feet hold the body, nothing is asked.
    s.react(3.0, state(3.0, "stance", True))
    lost: list[Command] = []
    for k in range(60):
        lost += s.react(3.01 + 0.01 * k, state(3.01 + 0.01 * k, "stance", False))
    assert requests(lost) == []


def test_in_the_tripod_a_foot_with_no_ground_is_stepped_around_then_the_body_held() -> None:
    s = searching()
    s.react(0.5, locomotion_state(0.5, "walking", gait="tripod"))
    out: list[Command] = []
    for k in range(3):
        out += s.react(1.0 + k, ended(1.0 + k, "no_contact"))
    reqs = requests(out)
    assert [r.restep_leg for r in reqs[:2]] == [1, 1]  # forward, then back
    assert reqs[2].halt is True
    assert [m.attempts for m in out if isinstance(m, NoFoothold)] == [2]


def test_in_a_gait_on_four_or_five_feet_the_walk_goes_on_without_the_foothold() -> None:
    s = searching()
    s.react(0.5, locomotion_state(0.5, "walking", gait="ripple"))
    out: list[Command] = []
    for k in range(3):
        out += s.react(1.0 + k, ended(1.0 + k, "no_contact"))
    assert [r.halt for r in requests(out)] == [None, None]  # two steps around, no halt
    (said,) = [m for m in out if isinstance(m, NoFoothold)]
    assert said.leg == 1
    # It tries again at the leg's next swing: around once more.
    (again,) = requests(list(s.react(4.0, ended(4.0, "no_contact"))))
    assert again.restep_leg == 1


def test_a_loss_seen_a_cycle_before_the_leg_reaches_is_its_reach_not_a_step_again() -> None:
    # The leg holds the loss itself, from its own reading: its reach may begin a cycle
    # after the reflex has seen the loss.
    hold = CFG.contact.touchdown_s
    s = searching()
    s.react(0.5, locomotion_state(0.5, "walking", gait="wave"))
    s.react(1.0, state(1.0, "stance", True, z=-0.29))
    s.react(1.01, state(1.01, "stance", False, z=-0.29))
    assert requests(s.react(1.01 + hold, state(1.01 + hold, "stance", False, z=-0.29))) == []
    assert requests(s.react(1.02 + hold, state(1.02 + hold, "search", False, z=-0.291))) == []
    assert requests(s.react(1.2 + hold, state(1.2 + hold, "stance", True, z=-0.295))) == []
    assert not s.active
    # One whose reach never begins (it has reached all it may this stance) is stepped again.
    s.react(3.0, state(3.0, "stance", True, z=-0.29))
    s.react(3.01, state(3.01, "stance", False, z=-0.29))
    assert requests(s.react(3.01 + hold, state(3.01 + hold, "stance", False, z=-0.29))) == []
    (req,) = requests(s.react(3.1 + hold, state(3.1 + hold, "stance", False, z=-0.29)))
    assert req.restep_leg == 2
    assert "stepped again" in s.reason


def stand(s: Searching, t: float, feet: dict[int, tuple[float, float, float]]) -> None:
    """Legs in stance, their joints putting their feet at ``feet``."""
    for leg, foot in feet.items():
        s.react(t, leg_state(t, leg, "stance", measured_foot=foot))


OTHERS = {
    0: (0.3, -0.25, -0.27),
    1: (0.3, 0.25, -0.27),
    3: (0.0, 0.35, -0.27),
    5: (-0.3, 0.3, -0.27),
}
"""Four feet in stance on level ground (RM, leg 2, is the one that swings)."""


def test_ground_found_lower_with_the_other_feet_as_low_is_no_hole() -> None:
    # On 30° a swing the servos could not follow came down late, the body tilted over its
    # feet: the plan's ground was 3 cm too high here, and so for the feet around it.
    s = searching()
    tilted = {leg: (x, y, z - 0.1 * y + 0.05 * x) for leg, (x, y, z) in OTHERS.items()}
    stand(s, 1.98, tilted)
    s.react(1.99, leg_state(1.99, 2, "search", measured_foot=(0.0, -0.35, -0.27 + 0.035)))
    hole = SwingEnded(t=2.0, source="leg", leg=2, outcome="completed", ground_offset_m=-0.03)
    s.react(2.0, hole)
    assert not s.active


def test_ground_found_lower_than_the_other_feet_stand_is_a_hole() -> None:
    s = searching()
    stand(s, 1.98, OTHERS)
    s.react(1.99, leg_state(1.99, 2, "search", measured_foot=(0.0, -0.35, -0.30)))
    hole = SwingEnded(t=2.0, source="leg", leg=2, outcome="completed", ground_offset_m=-0.03)
    s.react(2.0, hole)
    assert s.active
    assert s.reason == "RM found ground 3 cm lower"


def test_with_fewer_than_three_feet_in_stance_the_plan_judges() -> None:
    s = searching()
    stand(s, 1.98, {0: OTHERS[0], 1: OTHERS[1]})
    stand(s, 1.0, {3: OTHERS[3], 5: OTHERS[5]})  # too old to say where they stand
    s.react(1.99, leg_state(1.99, 2, "search", measured_foot=(0.0, -0.35, -0.27)))
    hole = SwingEnded(t=2.0, source="leg", leg=2, outcome="completed", ground_offset_m=-0.03)
    s.react(2.0, hole)
    assert s.active


def test_a_reach_no_lower_than_the_other_feet_stand_is_no_hole() -> None:
    # The body tipped over its feet: RM lost its support and reached 3 cm down to where
    # the feet around it stand (their plane tilted as much), then found the ground.
    s = searching()
    s.react(0.5, locomotion_state(0.5, "walking", gait="ripple"))
    tilted = {leg: (x, y, z + 0.1 * y) for leg, (x, y, z) in OTHERS.items()}  # −0.305 at RM
    level = (0.0, -0.35, -0.27)
    stand(s, 1.0, tilted)
    s.react(1.0, leg_state(1.0, 2, "stance", foot_z=-0.29, measured_foot=level))
    s.react(1.3, leg_state(1.3, 2, "search", contact=False, foot_z=-0.29, measured_foot=level))
    stand(s, 1.5, tilted)
    low = (0.0, -0.35, -0.30)  # 3 cm down, 5 mm above the others' plane
    s.react(1.5, leg_state(1.5, 2, "search", contact=False, foot_z=-0.32, measured_foot=low))
    assert not s.active
    stand(s, 1.6, tilted)
    s.react(1.6, leg_state(1.6, 2, "stance", foot_z=-0.32, measured_foot=low))
    assert not s.active
    assert "lower" not in s.reason
    # Level feet around it: the same reach is a hole.
    stand(s, 2.0, OTHERS)
    s.react(2.0, leg_state(2.0, 2, "stance", foot_z=-0.29, measured_foot=level))
    s.react(2.3, leg_state(2.3, 2, "search", contact=False, foot_z=-0.29, measured_foot=level))
    stand(s, 2.5, OTHERS)
    deep = (0.0, -0.35, -0.30)
    s.react(2.5, leg_state(2.5, 2, "search", contact=False, foot_z=-0.32, measured_foot=deep))
    assert s.active
    assert "reaching down" in s.reason
