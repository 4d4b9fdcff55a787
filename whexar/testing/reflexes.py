"""Helpers for testing a reflex's policy directly: the messages it reads, made short.

A reflex's policy is a plain class (:class:`~whexar.actors.reactive.Reflex`); its test
makes it and calls ``react`` with the messages of its inputs. The coordinator's state is
the one with many fields: :func:`locomotion_state` fills them in.
"""

from __future__ import annotations

from whexar.actors.messages import LocomotionState, Vec3


def locomotion_state(
    t: float,
    activity: str,
    *,
    twist: Vec3 = (0.0, 0.0, 0.0),
    mode: str = "walk",
    gait: str = "tripod",
    stance: str = "default",
) -> LocomotionState:
    """The coordinator's state at ``t``, doing ``activity`` with body ``twist``."""
    return LocomotionState(
        t=t,
        source="coordinator",
        activity=activity,
        mode=mode,
        gait=gait,
        stance=stance,
        twist=twist,
        gait_phase=0.0,
        swing_legs=(),
        margin_m=0.1,
        upside_down=False,
    )
