"""A leg's step under way: the foot's path and the adaptive swing (Diosdado 2014, 3.3–3.6).

A :class:`Step` is what a :class:`~whexar.actors.messages.StepCommand` became
when the leg took it: where the foot started, where it goes, and how the
swing has gone so far. :func:`advance` moves the foot along it to a time:

* a swing follows its shape (:class:`~whexar.kinematics.trajectory.SwingTable`)
  from the lift-off point to the target, the apex ``height`` above the line
  between them; with contact sensing it adapts (below);
* a move follows a minimum-jerk path, lifted by ``height`` on the way;
* on the ground — stance, hold, a finished swing or move — the body carries
  the foot: p ← p − (v + ω ẑ × p)·dt.

Adaptive swing: a contact that comes once the foot has been seen off the
ground is new ground. Before the apex it is an obstacle on the way up
(``blocked``, said once; the swing goes on); from the apex on the foot stops
there (``early_contact``) and the stance continues from that height; at the
end of the swing it is ``completed``. A foot with no contact at the end of its
swing is put down and judged ``touchdown_s`` later: ``completed`` if contact
came meanwhile (a sensor lags the foot: the force sensor's frames by up to a
tenth of a second), ``no_contact`` if none did — no ground where it was
expected. A swing with a ``search_depth`` (the searching reflex's, 4.2.2)
then searches down for the ground at ``search_speed`` (phase ``search``), the
body carrying the foot as in stance: contact within the depth is a
``completed`` swing whose ground lies lower (a negative ground offset), the
stance going on from there; none is ``no_contact`` at the full depth. A
contact that never went away after lift-off is not believed (a stuck sensor).
A stance whose foot had contact and lost it for ``touchdown_s`` (a support
that gave way, or a body that rolled off it) reaches down for it in the same
way, as far as the swing's ``reach_depth``, while the walk goes on: the
stance goes on from where the foot finds ground (the searching reflex asks
for it where four or five feet hold the body, and, told by the leg's phase,
steps it again when it finds none).
The leg asks :func:`interrupted` what a new step does to a touchdown still
awaited: a new swing judges it at once, a settling move on the ground carries
its search on, searching during the move too, and another step on the ground
leaves it to be judged when due. The leg says a touchdown is awaited
(``LegState.touchdown_pending``), and the coordinator lifts no such foot.

A stance can share the load ("the controller that controlled the leg
loading", 6.8.1; ``contact.balance_gain_m_s``, where the coordinator asks it
with ``StepCommand.share_load``: on a slope): a stance foot
whose force sensor reads fewer counts than the loaded feet's mean goes down,
one that reads more goes up, at ``balance_gain`` per count of difference (at
most ``balance_speed``), by at most ``balance_m`` from where its stance
began. The loaded feet's moves sum to nothing, so the body keeps its height,
and the feet do not settle on a diagonal pair as the body rolls on a slope.
Each stance starts again from the planned height. Measured, with what it
costs at a trench's edge, in docs/reflexes.md.
Plain functions over plain data: no time is read, nothing is sent.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

from whexar.kinematics.trajectory import SwingOutcome, SwingTable, min_jerk

if TYPE_CHECKING:
    from whexar.actors.messages import StepCommand
    from whexar.config.motion import ContactSpec


@dataclass(frozen=True, slots=True)
class StepSpec:
    """What each step of a leg takes from the configuration (``[contact]``)."""

    touchdown_s: float
    search_speed: float
    balance_gain: float
    balance_speed: float
    balance_m: float

    @classmethod
    def of(cls, contact: ContactSpec) -> StepSpec:
        return cls(
            contact.touchdown_s,
            contact.search_speed_m_s,
            contact.balance_gain_m_s,
            contact.balance_speed_m_s,
            contact.balance_m,
        )


@dataclass(slots=True)
class Step:
    """A step under way (module docstring)."""

    kind: str
    """swing, stance, move or hold."""
    start_t: float
    duration: float
    origin: list[float]
    target: tuple[float, float, float]
    height: float
    shape: SwingTable | None
    joint_space: tuple[list[float], list[float]] | None = None
    """A move made in joint space: (start, goal) angles (the first move after start)."""
    lifted: bool = False
    """A swing's foot was seen off the ground (so a contact now is new ground)."""
    grounded: bool = False
    """The contact read now began before the joints had lifted the foot: its own ground,
    loaded again, not something met (the force sensor's reading lags the lift)."""
    reported: bool = False
    ended: bool = False
    awaiting: bool = False
    """The swing ended with no contact: its outcome waits for ``touchdown_s``."""
    touchdown_s: float = 0.0
    """How long a swing that ended without contact waits for one."""
    search_depth: float = 0.0
    """How far below the expected ground a swing then searches, m."""
    search_speed: float = 0.0
    """… going down at this speed, m/s."""
    searched: float = 0.0
    """How far it has searched so far, m."""
    ground_z: float | None = None
    """Where the ground was expected, for a search this step carries on from an
    interrupted swing's (None: at its own target)."""
    due_t: float | None = None
    """When the touchdown it carries on is due (None: ``touchdown_s`` after its end)."""
    sink: float = 0.0
    """How far the search it carries has lowered this move's path so far, m."""
    balance_gain: float = 0.0
    """How fast a stance foot moves per count of load below the loaded feet's mean, m/s."""
    balance_speed: float = 0.0
    """… at most, m/s."""
    balance_m: float = 0.0
    """… and no further than this from where its stance began, m."""
    balanced: float = 0.0
    """How far it has moved so (+ up), m."""
    supported: bool = False
    """Its stance has had contact (so that a loss of it is a support lost)."""
    free_since: float | None = None
    """When the stance lost its contact (None: it has it, or never had)."""
    reach_depth: float = 0.0
    """How far its stance foot reaches down for a support it lost, m (0: it does not)."""
    reached: float = 0.0
    """How far it has reached so far, m."""

    def ground(self) -> float:
        """Where its swing expected the ground (upright frame, m)."""
        return self.target[2] if self.ground_z is None else self.ground_z

    def due(self) -> float:
        """When a swing that ended with no contact has waited its ``touchdown_s``."""
        if self.due_t is not None:
            return self.due_t
        return self.start_t + self.duration + self.touchdown_s

    def touchdown_due(self, t: float) -> bool:
        """A swing that ended with no contact has waited its ``touchdown_s`` by ``t``."""
        return t >= self.due()

    def carry_search(self, swing: Step) -> None:
        """Go on with ``swing``'s wait for its touchdown, and its search, from this step
        on the ground (a settling move made while the walk is held): the search goes on
        during the move, which keeps the foot's height (the walk held settles a foot
        every 0.2 s with a 0.2 s move: a search left for the moves' ends never ran), and
        its outcome is judged against the swing's ground."""
        self.awaiting = True
        self.due_t = swing.due()
        self.search_depth, self.search_speed = swing.search_depth, swing.search_speed
        self.searched = swing.searched
        self.ground_z = swing.ground()
        self.target = (self.target[0], self.target[1], self.origin[2])

    def judged(self, contact: bool) -> SwingOutcome:
        """The outcome of a swing still awaiting its touchdown, judged now."""
        self.awaiting = False
        return "completed" if contact else "no_contact"


def begin(
    cmd: StepCommand,
    origin: list[float],
    shape: SwingTable | None,
    joint_space: tuple[list[float], list[float]] | None,
    spec: StepSpec,
) -> Step:
    """The step a leg takes up for ``cmd``, its foot at ``origin``."""
    depth, reach = cmd.search_depth_m, cmd.reach_depth_m
    return Step(
        cmd.kind,
        cmd.start_t,
        max(cmd.duration_s, 1e-6),
        origin,
        cmd.target,
        cmd.height_m,
        shape,
        joint_space,
        touchdown_s=spec.touchdown_s,
        balance_gain=spec.balance_gain if cmd.share_load else 0.0,
        balance_speed=spec.balance_speed,
        balance_m=spec.balance_m,
        search_depth=depth if math.isfinite(depth) else 0.0,
        reach_depth=reach if math.isfinite(reach) else 0.0,
        search_speed=spec.search_speed,
    )


def interrupted(old: Step, cmd: StepCommand, contact: bool) -> Literal["judge", "carry", "wait"]:
    """What ``cmd`` does to ``old``, a swing still awaiting its touchdown: a new swing, or a
    contact, has it judged now; a settling move on the ground (the walk held) carries its
    search on, not cut short; any other step on the ground (a stop, a lifted move) leaves
    it to be judged when due."""
    if cmd.kind == "swing" or contact:
        return "judge"
    if cmd.kind == "move" and cmd.height_m <= 0.0 and old.search_depth > 0.0:
        return "carry"
    return "wait"


def advance(
    step: Step,
    foot: list[float],
    twist: tuple[float, float, float],
    t: float,
    dt: float,
    contact: bool,
    source: str,
    load_error: float | None = None,
    raised: bool = True,
) -> tuple[str, float, SwingOutcome | None]:
    """Move ``foot`` (upright frame, in place) along ``step`` to time ``t``; ``dt`` since the
    last cycle, ``twist`` the body's, ``contact`` this cycle's reading from ``source``
    (``"none"``: the leg senses no contact), ``load_error`` how many counts its force
    sensor reads below the loaded feet's mean (None: not known), ``raised`` whether the
    joints have lifted the foot off its ground (a swing is blocked on its way up only
    then). Returns the phase (swing, move, stance, hold, ride, search), the progress
    through the step and, when the swing's outcome is known now, that."""
    u = (t - step.start_t) / step.duration
    u = 0.0 if u < 0.0 else 1.0 if u > 1.0 else u
    if step.kind == "swing" and not step.ended:
        assert step.shape is not None
        f, h = step.shape.at(u)
        o, g = step.origin, step.target
        foot[0] = o[0] + (g[0] - o[0]) * f
        foot[1] = o[1] + (g[1] - o[1]) * f
        foot[2] = o[2] + (g[2] - o[2]) * f + step.height * h
        if source != "none":
            outcome = _adapt(step, u, contact, raised)
            if outcome is None and step.ended:  # down with no contact: wait for it
                step.awaiting = True
                if step.touchdown_s <= 0.0 and step.search_depth <= 0.0:
                    outcome = step.judged(False)
            return "swing", u, outcome
        if u >= 1.0:
            step.ended = True
            return "swing", u, "completed"
        return "swing", u, None
    if step.kind == "move" and not step.ended:
        s = min_jerk(u)
        o, g = step.origin, step.target
        foot[0] = o[0] + (g[0] - o[0]) * s
        foot[1] = o[1] + (g[1] - o[1]) * s
        foot[2] = o[2] + (g[2] - o[2]) * s + step.height * math.sin(math.pi * u) - step.sink
        phase, outcome = "move", None
        if step.awaiting:  # a settling move carrying a swing's search on (carry_search)
            phase, outcome = _touchdown(step, foot, t, dt, contact, "move")
        if u >= 1.0:
            step.ended = True  # its last pose (joint space included) is sent this cycle
        return phase, u, outcome
    if step.kind == "ride":
        return "ride", u, None  # its wheel carries it over the ground; the foot stays put
    # On the ground: the body carries the foot (stance, hold, a finished swing or move).
    vx, vy, w = twist
    if dt > 0.0 and (vx or vy or w):
        x, y = foot[0], foot[1]
        if w:
            c, s_ = math.cos(-w * dt), math.sin(-w * dt)
            x, y = c * x - s_ * y, s_ * x + c * y
        foot[0], foot[1] = x - vx * dt, y - vy * dt
    kind = "stance" if step.kind in ("swing", "stance") else "hold"
    if step.awaiting:
        phase, outcome = _touchdown(step, foot, t, dt, contact, kind)
        if phase == "search" or outcome is not None:
            return phase, u, outcome
    elif (
        kind == "stance"
        and step.reach_depth > 0.0
        and source != "none"
        and _reach(step, foot, t, dt, contact)
    ):
        return "search", u, None
    if (
        kind == "stance"
        and not step.awaiting
        and load_error is not None
        and step.balance_gain > 0.0
    ):
        v = step.balance_gain * load_error
        v = max(-step.balance_speed, min(step.balance_speed, v))
        to = max(-step.balance_m, min(step.balance_m, step.balanced - v * dt))
        foot[2] += to - step.balanced
        step.balanced = to
    return kind, u, None


def _touchdown(
    step: Step, foot: list[float], t: float, dt: float, contact: bool, phase: str
) -> tuple[str, SwingOutcome | None]:
    """A swing's touchdown still awaited: judged at a contact, else once due searched for
    down at ``search_speed``, and judged with none at the full ``search_depth``. Returns
    the phase (``phase``, or search while it searches) and the outcome if judged now."""
    if contact:
        return phase, step.judged(True)
    if not step.touchdown_due(t):
        return phase, None
    if step.searched >= step.search_depth:
        return phase, step.judged(False)
    down = _lower(foot, step.search_speed * dt, step.search_depth - step.searched)
    step.searched += down
    step.sink += down  # a move's path is drawn again each cycle: it keeps the depth
    return "search", None


def _reach(step: Step, foot: list[float], t: float, dt: float, contact: bool) -> bool:
    """A stance foot that had contact and lost it for ``touchdown_s`` reaches down for it at
    ``search_speed``, as far as ``reach_depth`` (6.7.3: "first in the downward
    direction"); the body and the walk go on. Returns whether it reaches now."""
    if contact:
        step.supported, step.free_since = True, None
        return False
    if not step.supported or step.reached >= step.reach_depth:
        return False
    if step.free_since is None:
        step.free_since = t
    if t - step.free_since < step.touchdown_s:
        return False
    step.reached += _lower(foot, step.search_speed * dt, step.reach_depth - step.reached)
    return True


def _lower(foot: list[float], by: float, left: float) -> float:
    """Lower ``foot`` by ``by``, no further than ``left``: how far it went."""
    down = min(by, left)
    foot[2] -= down
    return down


def load_error(counts: Sequence[int], contacts: Sequence[bool], leg: int) -> float | None:
    """How many counts ``leg``'s force sensor reads below the mean of the loaded feet's
    (those whose sensor says contact); None with fewer than three loaded: no stance to
    share."""
    loaded = [c for c, on in zip(counts, contacts, strict=True) if on]
    return sum(loaded) / len(loaded) - counts[leg] if len(loaded) >= 3 else None


def _adapt(step: Step, u: float, contact: bool, raised: bool = True) -> SwingOutcome | None:
    """Adaptive swing (Diosdado 2014, 3.5–3.6) on the contact reading of this cycle."""
    assert step.shape is not None
    if not contact:
        step.grounded = False
        if u > 0.0:
            step.lifted = True
        if u >= 1.0:
            step.ended = True  # no contact yet: advance() waits touchdown_s for one
        return None
    if u >= 1.0:
        step.ended = True
        return "completed"  # touchdown where expected (or a sensor that never let go)
    if not step.lifted or u <= 0.0:
        return None  # still on the ground at lift-off, or a sensor stuck on
    if u < step.shape.apex_u:
        if not raised or step.grounded:
            # The foot had not left its ground when this contact began: its load coming
            # back as it lifts (a neighbour not yet down), not something in its path.
            step.grounded = True
            return None
        if not step.reported:
            step.reported = True
            return "blocked"  # the elevator reflex's case
        return None
    step.ended = True
    return "early_contact"
