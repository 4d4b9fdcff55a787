"""The searching reflex: a foot that finds no ground looks for it (4.2.2, 5.4, 6.7.3).

Theory of operation
-------------------
"If there is a change in the amount of pressure the leg applies on the surface,
the searching reflex is activated and attempts to find a new foothold, first in
the downward direction and eventually in other directions" (6.7.3). Here:

* **down**: the reflex asks the coordinator that every swing search
  ``depth_m`` below where it expects the ground
  (:class:`~whexar.actors.messages.ReflexRequest` ``search_depth_m``): a foot
  with no contact at the end of its swing goes on down at
  ``contact.search_speed_m_s`` until it finds ground, and the stance goes on
  from there (:mod:`whexar.actors.locomotion.steps`). A swing that searched
  and found ground completes with a negative ground offset; one ``found_m``
  or more below the expected ground is a hole found, and the reflex is
  active for a moment (``found_m``: a foot pressed a few millimetres into
  ground it did not feel at once, as an unloaded leg uphill, is no hole) —
  if the foot also stands ``found_m`` below the plane of the other feet in
  stance, where three or more stand: a body tilted over its feet lowers
  the ground under a swing as much as under them (on 30°, a swing the
  servos could not follow; docs/reflexes.md, "30°, traced");
* **around**: a swing that found nothing within the depth (``no_contact``,
  believed by the leg's contact estimate) makes the reflex ask for the leg to
  be stepped again, forward by ``around_m``, then back by it
  (``restep_leg``), each step searching down again, in the ``around_gaits``
  (all by default). A step around halts the walk while it is made; in the
  gaits left out the leg rather tries again at its next swing, the gait
  carrying it forward;
* **a safe stop**: when ``attempts`` steps around found nothing either, it
  says so (:class:`NoFoothold`) and, in a gait that stands on three legs (the
  tripod's, ``halt_gaits``), holds the body still (``halt``) until that leg
  finds ground: "in the tripod gait ... loss of support of any leg caused the
  robot to fall. For more stable gaits, the robot compensated the loss of
  support of one leg" (6.7.3) — there the walk goes on, the leg trying again
  at its next swing;
* **support lost in stance**: a foot that had contact in its stance and lost
  it for ``contact.touchdown_s`` (the estimate believing it) reaches down for
  it as a swing searches (the leg's phase ``search``,
  :mod:`whexar.actors.locomotion.steps`), the walk going on where four or
  five feet hold the body; in the ``halt_gaits`` (three feet), and when it
  finds nothing within the depth, it is stepped again where it should be,
  searching, in the ``around_gaits``; in the others the other feet hold the
  body and its next swing searches (the terrain estimator counts each loss as
  a "disappeared support", 5.4, in every gait). As for a swing, a foot that
  finds the ground again less than ``found_m`` below where it stood found no
  hole: the body rolled off it, and the reach gave it its load back — the
  reflex is active once a reach goes deeper, below the other feet's plane
  too, or finds nothing.

The early-contact stop of 6.7.3 is the leg's own adaptive swing.
"""

from __future__ import annotations

from collections.abc import Iterable

from pydantic import Field

from whexar.actors.messages import LegState, LocomotionState, NoFoothold, SwingEnded
from whexar.actors.reactive.reflex import Command, Reflex, ReflexParams
from whexar.config import RobotConfig
from whexar.kinematics.contact import StanceLoss, depth_below_plane
from whexar.robot import LEG_NAMES, N_LEGS
from whexar.runtime.messages import Message

FOUND_S = 0.5
"""A hole found keeps the reflex active this long: a spell the timeline shows."""
REACH_START_S = 0.05
"""A stance leg that lost its support begins its reach within this long of the loss seen
here: it holds the loss itself, counted from its own reading, a cycle or two apart. On 30°
six of eleven activations in 600 s were legs stepped again in that cycle, their reach
about to begin (docs/reflexes.md, "searching")."""
FRESH_S = 0.05
"""A leg's state older than this no longer says where its foot stands (a few control
cycles)."""


class SearchingParams(ReflexParams):
    """How deep and how far around the searching reflex looks (docs/reflexes.md)."""

    depth_m: float = Field(0.06, gt=0.0, le=0.15)
    """How far below the expected ground a swing searches, m: the default step height —
    a leg reaches down as far as it lifts."""
    around_m: float = Field(0.04, gt=0.0, le=0.1)
    """How far forward, then back, a foot that found nothing is stepped again, m: half
    the wheel's diameter, past the edge of a hole the size of a foot."""
    attempts: int = Field(2, ge=0, le=6)
    """Steps around before the safe stop: forward, then back."""
    halt_gaits: tuple[str, ...] = ("tripod",)
    """The gaits in which a foothold not found holds the body (6.7.3: the tripod fell)."""
    around_gaits: tuple[str, ...] = ("tripod", "tetrapod", "ripple", "wave")
    """The gaits in which a foot that found no ground, or lost it in stance, is stepped
    again; in the others four or five feet hold the body ("for more stable gaits, the
    robot compensated the loss of support of one leg", 6.7.3) and the leg tries again at
    its next swing. The tripod's alone passed the ripple over the 5 cm trench 5 times of 5
    instead of 0, and raised 30°'s false triggers (docs/reflexes.md, "searching")."""
    confidence: float = Field(0.5, gt=0.0, lt=1.0)
    """A loss counts when the leg's contact estimate believes it at least this much."""
    found_m: float = Field(0.025, gt=0.0, le=0.1)
    """Ground found this far below the expected (a swing's), or below where a stance foot
    stood (a reach's), and as far below the other stance feet's plane where they make one,
    is a hole: above what the ground itself gives (the flat's 0–9 mm;
    on 30° swings end up to 2.0 cm lower, reaches up to 1.4 cm), half the 5 cm trench's
    (docs/reflexes.md, "searching")."""


class Searching(Reflex):
    """Searches down, then around, for a foothold (module docstring)."""

    inputs = ("swings", "legs", "locomotion")
    priority = 25
    tick_s = 0.5
    Params = SearchingParams
    params: SearchingParams

    def __init__(self, params: ReflexParams, *, name: str, cfg: RobotConfig) -> None:
        super().__init__(params, name=name, cfg=cfg)
        self.asked = False
        self.tries = [0] * N_LEGS
        """Per leg: steps around since it last found ground."""
        self.searching: set[int] = set()
        """Legs whose foot looks for ground now."""
        self.halted: set[int] = set()
        """Legs that found none: the body is held for them."""
        self.reaching: dict[int, float] = {}
        """Stance legs reaching down for a support they lost: where each foot stood, m."""
        self.reach_t = [0.0] * N_LEGS
        """Per leg: when its reach began (its loss seen here)."""
        self.holes: set[int] = set()
        """… those that reached ``found_m`` or deeper: a hole (the reflex active)."""
        self.losses = StanceLoss(N_LEGS, cfg.contact.touchdown_s, self.params.confidence)
        self.gait = "tripod"
        """The gait the coordinator walks (its state)."""
        self.found_until = -1e9
        """A hole found keeps the reflex active until then (a spell on the timeline)."""
        self.reach = 0.0
        """How far it asked stance feet to reach down (0 in the ``halt_gaits``)."""
        self.feet: dict[int, LegState] = {}
        """Per leg: its latest state."""

    def tick(self, t: float) -> Iterable[Command]:
        if self.found_until <= t:
            self._settle(t)
        if self.asked:
            return ()
        self.asked = True
        return (self.request(t, search_depth_m=self.params.depth_m, reason="search for ground"),)

    def react(self, t: float, msg: Message) -> Iterable[Command]:
        if isinstance(msg, SwingEnded):
            return self._swing(t, msg)
        if isinstance(msg, LegState):
            self.feet[msg.leg] = msg
            return self._leg(t, msg)
        if isinstance(msg, LocomotionState):
            self.gait = msg.gait
            reach = 0.0 if msg.gait in self.params.halt_gaits else self.params.depth_m
            if reach != self.reach:
                self.reach = reach
                why = f"stance feet reach down for lost ground ({msg.gait})"
                return (self.request(t, reach_depth_m=reach, reason=why),)
        return ()

    def _swing(self, t: float, msg: SwingEnded) -> list[Command]:
        leg, p = msg.leg, self.params
        if msg.outcome != "no_contact":
            if leg not in self.searching:
                self.tries[leg] = 0  # a swing of the gait's found ground: a foothold
            # A step around that found ground keeps its count: a foot that loses it again at
            # its next swing has not found a foothold (at the 20 cm trench's edge the body
            # tipped, a rear foot found the floor only when stepped around, and the walk went
            # on and stopped, 6 s a round, for good).
            self.searching.discard(leg)
            out: list[Command] = []
            if leg in self.halted:
                self.halted.discard(leg)
                if not self.halted:
                    out.append(self.request(t, halt=False, reason=f"{LEG_NAMES[leg]} found ground"))
            if (
                msg.outcome == "completed"
                and msg.ground_offset_m <= -p.found_m
                and self._below_the_others(t, leg)
            ):
                self.active = True
                self.found_until = t + FOUND_S
                self.reason = (
                    f"{LEG_NAMES[leg]} found ground {-msg.ground_offset_m * 100:.0f} cm lower"
                )
            else:
                self._settle(t)
            return out
        if msg.confidence < p.confidence:
            return []
        self.active = True
        k = self.tries[leg]
        if k < p.attempts and self.gait in p.around_gaits:
            self.tries[leg] = k + 1
            self.searching.add(leg)
            dx = p.around_m if k % 2 == 0 else -p.around_m
            self.reason = f"{LEG_NAMES[leg]} found no ground: a step {dx * 100:+.0f} cm"
            return [self.request(t, restep_leg=leg, restep_offset_m=(dx, 0.0), reason=self.reason)]
        said = NoFoothold(t=t, source=self.name, leg=leg, searched_m=p.depth_m, attempts=k)
        if self.gait not in p.halt_gaits:
            self.tries[leg] = 0  # four or five feet hold the body: it tries again next swing
            self.searching.discard(leg)
            self.reason = f"{LEG_NAMES[leg]} found no foothold: the walk goes on ({self.gait})"
            return [said]
        self.halted.add(leg)
        self.reason = f"{LEG_NAMES[leg]} found no foothold: the body held"
        return [self.request(t, halt=True, reason=self.reason), said]

    def _leg(self, t: float, msg: LegState) -> list[Command]:
        i = msg.leg
        lost = self.losses.lost(t, i, msg.phase, msg.contact, msg.contact_confidence)
        if lost and self.reach > 0.0:
            # The leg reaches down while four or five feet hold the body; on three (the
            # tripod's) the walk rocks over the edge that took the support: stepped again.
            # Its reach may begin a cycle after the loss is seen here (its own hold).
            self.reaching[i] = msg.foot[2]
            self.reach_t[i] = t
            return []
        if i in self.reaching:
            depth = self.reaching[i] - msg.foot[2]
            if msg.phase == "stance" and not msg.contact and t - self.reach_t[i] < REACH_START_S:
                return []  # its reach not begun yet
            if msg.phase == "search":
                if (
                    i not in self.holes
                    and depth >= self.params.found_m
                    and self._below_the_others(t, i)
                ):
                    self.holes.add(i)
                    self.active = True
                    self.reason = f"{LEG_NAMES[i]} lost its support in stance: reaching down"
                return []
            del self.reaching[i]
            self.holes.discard(i)
            if msg.contact or msg.phase != "stance":
                if msg.contact and depth >= self.params.found_m and self._below_the_others(t, i):
                    self.found_until = t + FOUND_S
                    self.reason = f"{LEG_NAMES[i]} found ground {depth * 100:.0f} cm lower"
                self._settle(t)  # found, or its swing came first: that swing searches
                return []
            lost = True  # nothing within its reach
        if not lost:
            return []
        if self.gait not in self.params.around_gaits:
            self._settle(t)
            return []  # the other feet hold the body; its next swing searches
        self.active = True
        self.searching.add(i)
        self.reason = f"{LEG_NAMES[i]} lost its support in stance: stepped again"
        return [self.request(t, restep_leg=i, reason=self.reason)]

    def _below_the_others(self, t: float, leg: int) -> bool:
        """Whether ``leg``'s foot stands ``found_m`` or more below the plane of the other
        feet in stance (their joints' forward kinematics), where three or more stand; with
        fewer, or its own foot unread, the plan's ground alone judges (True)."""
        mine = self.feet.get(leg)
        if mine is None or mine.measured_foot is None:
            return True
        feet = [
            s.measured_foot
            for i, s in self.feet.items()
            if i != leg
            and s.phase == "stance"
            and s.measured_foot is not None
            and t - s.t <= FRESH_S
        ]
        depth = depth_below_plane(feet, mine.measured_foot)
        return depth is None or depth >= self.params.found_m

    def _settle(self, t: float) -> None:
        if not (self.searching or self.halted or self.holes) and self.found_until <= t:
            self.active = False
            self.reason = ""
