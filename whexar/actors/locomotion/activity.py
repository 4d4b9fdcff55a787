"""What the coordinator is doing: its activities and the transitions between them.

Theory of operation
-------------------
The coordinator is always in exactly one :class:`Activity`. Scripts (stand
up, sit down, change stance or mode, flip, align the wheels, place the feet
for a gait) and the steady engines (the gait, riding, the hybrid gait) move
it from one to the next, and only along :data:`TRANSITIONS`: a change the
table does not hold is a bug, raised as :class:`ActivityError` where it
happens rather than published. The table is the whole state machine of the
coordinator's activities, in one place.
"""

from __future__ import annotations

from enum import StrEnum
from types import MappingProxyType
from typing import Final

from whexar.errors import WhexarError


class Activity(StrEnum):
    """The coordinator's activities, as :class:`~whexar.actors.messages.LocomotionState`
    reports them."""

    STANDING_UP = "standing_up"
    """From the pose the servos report to the stance (the start, and after a flip)."""
    STANDING = "standing"
    """On the feet, the body still."""
    WALKING = "walking"
    """The gait engine runs."""
    RIDING = "riding"
    """On the wheels, rolling."""
    HYBRID = "hybrid"
    """The hybrid gait: stepping while the wheels drive (6.6)."""
    TRANSITION = "transition"
    """Re-placing the feet: a stance or mode change, a gait's start, aligning the wheels."""
    FLIPPING = "flipping"
    """Seated, turning every leg 180° about its trochanter (6.8.1)."""
    SITTING_DOWN = "sitting_down"
    """Lowering the body to the ground (a stop, a safe stop, a flip)."""
    SEATED = "seated"
    """On the ground; the end of a stop, or the middle of a flip."""


_A = Activity
TRANSITIONS: Final = MappingProxyType(
    {
        _A.STANDING_UP: frozenset({_A.STANDING, _A.SITTING_DOWN}),
        _A.STANDING: frozenset({_A.WALKING, _A.RIDING, _A.HYBRID, _A.TRANSITION, _A.SITTING_DOWN}),
        _A.WALKING: frozenset({_A.STANDING, _A.TRANSITION, _A.SITTING_DOWN}),
        _A.RIDING: frozenset({_A.STANDING, _A.TRANSITION, _A.SITTING_DOWN}),
        _A.HYBRID: frozenset({_A.STANDING, _A.TRANSITION, _A.SITTING_DOWN}),
        _A.TRANSITION: frozenset({_A.STANDING, _A.WALKING, _A.RIDING, _A.HYBRID, _A.SITTING_DOWN}),
        _A.FLIPPING: frozenset({_A.STANDING, _A.SITTING_DOWN}),
        _A.SITTING_DOWN: frozenset({_A.SEATED}),
        _A.SEATED: frozenset({_A.FLIPPING}),
    }
)
"""Activity → the activities it may change to. Any activity but seated may be left for a
sit-down (a stop, a safe stop); a sit-down ends seated, and seated is left only by a flip,
which stands up on the other side."""

QUIET: Final = frozenset({_A.STANDING_UP, _A.SITTING_DOWN, _A.SEATED})
"""Activities during which no command starts a script: the robot is getting on or off its
feet."""
STEADY: Final = frozenset({_A.STANDING, _A.WALKING, _A.RIDING, _A.HYBRID})
"""Activities in which a commanded body height applies (the feet stay, the body moves)."""


class ActivityError(WhexarError):
    """A change of activity the transition table does not allow: a bug in the coordinator."""


def checked(before: Activity, after: Activity) -> Activity:
    """``after``, if the table lets ``before`` change to it; else :class:`ActivityError`."""
    if after not in TRANSITIONS[before]:
        allowed = ", ".join(sorted(TRANSITIONS[before])) or "none"
        raise ActivityError(f"activity {before} cannot change to {after}; allowed: {allowed}")
    return after
