"""The servo table: which servo drives which joint, within which limits.

One :class:`Servo` per configured servo, built from the configuration by
:func:`servo_table`; start-up fills in what only the servo knows (its
Velocity Limit and Shutdown mask). The registers the scheduler reads and
writes by name are here too, with the values of the few that have meanings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Final

from whexar.bus import control_table as ct
from whexar.config import RobotConfig
from whexar.robot import JOINT_NAMES, LEG_NAMES

CRITICAL_JOINTS: Final = frozenset({"femur", "tibia"})
"""Joints whose loss leaves a leg unable to carry the body: a safe stop (issue brief)."""

# The MX (2.0) models share these addresses (e-manual control tables).
_MX: Final = ct.MODELS["MX-64"]
PRESENT_POSITION: Final = _MX.register("present_position")
TORQUE_ENABLE: Final = _MX.register("torque_enable")
HARDWARE_ERROR: Final = _MX.register("hardware_error_status")
GOAL_POSITION: Final = _MX.register("goal_position")
GOAL_VELOCITY: Final = _MX.register("goal_velocity")
RETURN_DELAY: Final = _MX.register("return_delay_time")
OPERATING_MODE: Final = _MX.register("operating_mode")
BUS_WATCHDOG: Final = _MX.register("bus_watchdog")

MODE_VELOCITY: Final = 1
MODE_POSITION: Final = 3
"""Operating Mode (11): 1 velocity control (the wheel), 3 position control (e-manual)."""
WATCHDOG_ERROR: Final = -1
"""Bus Watchdog (98) reads −1 after it stopped the servo (e-manual)."""
WATCHDOG_UNIT_S: Final = 0.02
"""Bus Watchdog counts 20 ms units (e-manual)."""
DEFAULT_SHUTDOWN: Final = 0x34
"""Shutdown (63)'s initial value, 52: overheating, electrical shock, overload (e-manual)."""


def tick_limits(lo: float, hi: float) -> tuple[int, int]:
    """The first and last Goal Position ticks whose angle lies within [lo, hi] (rad).

    Rounding to the nearest tick could step past a limit (tibia 150° is tick
    3754.67: 3755 is 150.03°); these are the ticks inside, with no tolerance,
    within the register's one turn (0…4095).
    """
    per_tick = ct.ticks_to_rad(ct.CENTER_TICKS + 1)
    first = max(0, ct.CENTER_TICKS + math.ceil(lo / per_tick) - 1)
    while ct.ticks_to_rad(first) < lo:
        first += 1
    last = min(ct.TICKS_PER_REV - 1, ct.CENTER_TICKS + math.floor(hi / per_tick) + 1)
    while ct.ticks_to_rad(last) > hi:
        last -= 1
    return first, last


@dataclass(slots=True)
class Servo:
    """One servo of the chain: its joint, its model and the limits of its goals."""

    id: int
    leg: int
    joint: int
    model: ct.ServoModel
    endless: bool
    """The wheel: velocity control, no position limits."""
    lo: float
    hi: float
    """The joint's limits (rad) within what Goal Position can express."""
    lo_tick: int
    hi_tick: int
    """The ticks inside ``lo``…``hi`` (:func:`tick_limits`)."""
    critical: bool
    """Its loss leaves a leg unable to carry the body (:data:`CRITICAL_JOINTS`)."""
    speed_limit: int
    """Velocity Limit (44) in velocity units, read at start-up (the wheel's clamp)."""
    shutdown: int = DEFAULT_SHUTDOWN
    """Shutdown (63): the error bits that latch and turn torque off (read at start-up)."""
    gains: tuple[tuple[ct.Register, int], ...] = ()
    """The position gains the configuration sets (``joints.*.gains``), each register with
    its value; empty: the servo keeps its own."""
    current_unit: float = field(init=False)
    """A per unit of Present Current (Present Load's unit on the MX-28)."""

    def __post_init__(self) -> None:
        self.current_unit = ct.current_to_a(1, self.model)

    @property
    def name(self) -> str:
        """How events and errors name it: ``servo 3 (RF femur)``."""
        return f"servo {self.id} ({LEG_NAMES[self.leg]} {JOINT_NAMES[self.joint]})"

    @property
    def mode(self) -> int:
        """The Operating Mode (11) it must be in."""
        return MODE_VELOCITY if self.endless else MODE_POSITION

    @property
    def goal_register(self) -> ct.Register:
        """Goal Velocity for the wheel, Goal Position for the others."""
        return GOAL_VELOCITY if self.endless else GOAL_POSITION

    def clamp_tick(self, tick: int) -> int:
        """``tick`` within :attr:`lo_tick`…:attr:`hi_tick`."""
        return min(max(tick, self.lo_tick), self.hi_tick)


def servo_table(cfg: RobotConfig) -> dict[int, Servo]:
    """Every configured servo by ID, leg by leg in the configuration's order."""
    servos: dict[int, Servo] = {}
    for leg, leg_spec in enumerate(cfg.legs):
        for j, sid in enumerate(leg_spec.servo_ids):
            joint = cfg.joints.by_name(JOINT_NAMES[j])
            limits = joint.limits_rad
            model = ct.model(joint.model)
            # Goal Position spans one turn, 0…4095 around the centre (2048).
            lo = max(limits[0], ct.ticks_to_rad(0)) if limits else -math.inf
            hi = min(limits[1], ct.ticks_to_rad(ct.TICKS_PER_REV - 1)) if limits else math.inf
            lo_tick, hi_tick = tick_limits(lo, hi) if limits else (0, ct.TICKS_PER_REV - 1)
            servos[sid] = Servo(
                sid,
                leg,
                j,
                model,
                joint.endless,
                lo,
                hi,
                lo_tick,
                hi_tick,
                JOINT_NAMES[j] in CRITICAL_JOINTS,
                model.register("velocity_limit").initial or 0,
                gains=tuple(
                    (model.register(name), value)
                    for name, value in (joint.gains.registers() if joint.gains else {}).items()
                ),
            )
    return servos
