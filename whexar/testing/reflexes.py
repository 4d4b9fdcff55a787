"""Helpers for testing a reflex's policy directly: the messages it reads, made short.

A reflex's policy is a plain class (:class:`~whexar.actors.reactive.Reflex`); its test
makes it and calls ``react`` with the messages of its inputs. The coordinator's state, its
body motion and a leg's state are the ones with many fields: :func:`locomotion_state`,
:func:`body_motion` and :func:`leg_state` fill them in.
"""

from __future__ import annotations

from whexar.actors.messages import BodyMotion, LegState, LocomotionState, Vec3


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


def body_motion(t: float, trochanter_rad: float = 0.0) -> BodyMotion:
    """The coordinator's body motion at ``t``: the body still in its neutral pose, every
    trochanter at ``trochanter_rad``."""
    return BodyMotion(
        t=t,
        source="coordinator",
        cycle=0,
        twist=(0.0, 0.0, 0.0),
        pose=(0.0,) * 6,
        trochanter_rad=trochanter_rad,
        upside_down=False,
    )


def leg_state(
    t: float,
    leg: int,
    phase: str,
    *,
    contact: bool = True,
    confidence: float = 0.9,
    foot_error_m: float | None = None,
    foot_z: float = 0.0,
    measured_foot: Vec3 | None = None,
) -> LegState:
    """Leg ``leg``'s state at ``t`` in ``phase``, its contact as its estimate says (the force
    sensor's, believed ``confidence``), its foot ``foot_error_m`` from its goals' point,
    planned at height ``foot_z`` and where its joints put it, ``measured_foot`` (None:
    unread)."""
    return LegState(
        t=t,
        source="leg",
        leg=leg,
        cycle=0,
        phase=phase,
        progress=0.5,
        foot=(0.0, 0.0, foot_z),
        measured_foot=measured_foot,
        contact=contact,
        contact_source="fsr",
        load=(None, None),
        contact_confidence=confidence,
        foot_error_m=foot_error_m,
    )
