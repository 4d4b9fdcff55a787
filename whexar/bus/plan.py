"""Read plans: which registers of which servos the bus scheduler reads, and how often.

Theory of operation
-------------------
A control cycle is bus-bound: one read of the registers the controller
needs, then one Sync Write of the goals that changed. A plan lists its reads;
each read names registers (their covering span is read in one Sync Read, or
Fast Sync Read), the joints and legs whose servos answer it, and a rate:

* no ``rate_hz`` — every cycle (positions, currents);
* ``rate_hz`` — only in cycles where it is due, at most that often; with
  ``chunk`` the servos take turns, ``chunk`` of them per due cycle, so that
  slow values (voltage, temperature, Hardware Error Status) cost little.

The presets are the thesis's way (6.1.1, two separate reads), full feedback
(current + velocity + position, 126–135, in one read), the same with Fast
Sync Read, positioning (positions of the 24 coxa/femur/tibia/tarsus servos,
the thesis's trimmed loop of 6.1.4) and ``default``: positions and currents
of those 24 every cycle, health round-robin at a few Hz.
"""

from __future__ import annotations

from typing import Annotated, Final, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from whexar.bus.control_table import MODELS, block
from whexar.errors import UsageError
from whexar.robot import JOINT_NAMES, LEG_NAMES

JointName = Literal["coxa", "trochanter", "femur", "tibia", "tarsus", "direction", "wheel"]
LegName = Literal["RF", "LF", "RM", "LM", "RR", "LR"]
FastMode = Literal["auto", "on", "off"]


class PlanRead(BaseModel):
    """One read: the span covering ``registers``, from the servos of ``joints`` × ``legs``."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    registers: Annotated[tuple[str, ...], Field(min_length=1)]
    joints: tuple[JointName, ...] = JOINT_NAMES
    legs: tuple[LegName, ...] = LEG_NAMES
    rate_hz: Annotated[float, Field(gt=0)] | None = None
    """At most this often; absent: every cycle."""
    chunk: Annotated[int, Field(gt=0)] | None = None
    """Servos per due cycle, taking turns; absent: all of them each time."""

    @field_validator("registers")
    @classmethod
    def _known(cls, names: tuple[str, ...]) -> tuple[str, ...]:
        try:
            block(names, MODELS.values())
        except UsageError as exc:
            raise ValueError(str(exc)) from None
        return names


class ReadPlan(BaseModel):
    """A named list of reads, how to read (Fast Sync Read or not) and an optional rate cap."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str = "custom"
    reads: tuple[PlanRead, ...]
    fast_sync_read: FastMode = "auto"
    """``auto``: try Fast Sync Read at start and after failures, fall back to Sync Read."""
    rate_hz: Annotated[float, Field(gt=0)] | None = None
    """Cap on the cycle rate; absent: as fast as the bus allows."""

    @field_validator("reads")
    @classmethod
    def _some(cls, reads: tuple[PlanRead, ...]) -> tuple[PlanRead, ...]:
        # Checked here, not with min_length, so one bad read is one problem.
        if not reads:
            raise ValueError("at least one read")
        return reads


_POSITIONING: Final = ("coxa", "femur", "tibia", "tarsus")
_HEALTH: Final = (
    PlanRead(registers=("hardware_error_status",), rate_hz=10, chunk=7),
    PlanRead(registers=("present_input_voltage", "present_temperature"), rate_hz=5, chunk=7),
)

PRESETS: Final[dict[str, ReadPlan]] = {
    p.name: p
    for p in (
        ReadPlan(
            name="thesis",
            reads=(
                PlanRead(registers=("present_position",)),
                PlanRead(registers=("present_current",)),
            ),
            fast_sync_read="off",
        ),
        ReadPlan(
            name="full_feedback",
            reads=(
                PlanRead(registers=("present_current", "present_velocity", "present_position")),
            ),
            fast_sync_read="off",
        ),
        ReadPlan(
            name="fast_full_feedback",
            reads=(
                PlanRead(registers=("present_current", "present_velocity", "present_position")),
            ),
            fast_sync_read="on",
        ),
        ReadPlan(
            name="positioning",
            reads=(PlanRead(registers=("present_position",), joints=_POSITIONING),),
            fast_sync_read="off",
        ),
        ReadPlan(
            name="default",
            reads=(
                PlanRead(registers=("present_current", "present_position"), joints=_POSITIONING),
                *_HEALTH,
            ),
        ),
    )
}
"""The named plans; ``default`` is what the runtime uses unless configured otherwise."""


def resolve_plan(plan: str | ReadPlan) -> ReadPlan:
    """A preset by name, or ``plan`` itself; :class:`UsageError` lists the preset names."""
    if isinstance(plan, ReadPlan):
        return plan
    try:
        return PRESETS[plan]
    except KeyError:
        raise UsageError(
            f"unknown read plan {plan!r}; allowed: {', '.join(PRESETS)} or a [bus.plan] table"
        ) from None
