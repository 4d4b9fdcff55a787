"""How a servo's horn moves and what current it draws: the seam a physics world plugs into.

Theory of operation
-------------------
A :class:`~whexar.bus.emulator.servo.VirtualServo` is its control table: the
e-manual's access rules, limits and error bits. What the motor does between
two bus transactions is not the table's business, so it is asked of two
small interfaces:

* :class:`ServoDynamics` — ``advance(motion, drive, dt)``: move the horn
  (:class:`Motion`: position, velocity, acceleration in ticks) for ``dt``
  seconds under the orders the table gives (:class:`Drive`: torque,
  operating mode, goal, profile limits);
* :data:`LoadModel` — ``(servo, t) -> amperes``: Present Current when a
  read needs it.

The defaults are the e-manual's behaviour without a load:
:class:`TrapezoidalProfile` (trapezoidal position profiles, velocity ramps,
no motion without torque) and :func:`default_load`. The physics simulator
replaces both with the world's joint and its torque; the table, the
protocol and the timing stay as they are. Dynamics are advanced lazily and
exactly, only when a transaction comes: nothing moves or is sampled between
transactions, and the result does not depend on how time is sliced.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Final, NamedTuple, Protocol

from whexar.bus.control_table import TICKS_PER_REV, ServoModel

POSITION_MODES: Final = frozenset({3, 4, 5})
"""Operating Mode (11): position, extended position, current-based position (e-manual)."""
VELOCITY_MODE: Final = 1
"""Operating Mode (11): velocity control (the wheel)."""
_RAD_PER_TICK: Final = 2.0 * math.pi / TICKS_PER_REV


class Drive(NamedTuple):
    """What the control table asks of the motor, in ticks and seconds.

    A named tuple: a servo makes one after every write that changes it
    (42 goal writes a cycle), and a tuple is made in a fraction of a frozen
    dataclass's time (docs/sim.md, "Speed").
    """

    torque: bool
    """Torque Enable (64)."""
    mode: int
    """Operating Mode (11)."""
    goal_position: int
    """Goal Position (116), ticks."""
    profile_active: bool
    """A position profile toward the goal is under way (Moving Status bit 1)."""
    goal_velocity: float
    """Goal Velocity (104) within ±Velocity Limit (44), ticks/s: the target in velocity mode."""
    max_velocity: float
    """Profile Velocity (112), or Velocity Limit (44) when 0 or above it, ticks/s."""
    max_acceleration: float
    """Profile Acceleration (108), ticks/s²; ``math.inf`` when 0 (a step in velocity)."""


@dataclass(slots=True)
class Motion:
    """Where the horn is and how it moves: ticks, ticks/s, ticks/s² (unrounded)."""

    position: float
    velocity: float = 0.0
    acceleration: float = 0.0
    """Of the current profile phase; 0 when steady."""


class ServoDynamics(Protocol):
    """Moves a servo's horn between bus transactions (the physics world's seam)."""

    def advance(self, motion: Motion, drive: Drive, dt: float) -> None:
        """Move ``motion`` in place for ``dt`` > 0 seconds under ``drive``."""
        ...


class ServoView(Protocol):
    """What a :data:`LoadModel` may read of a servo."""

    model: ServoModel

    @property
    def id(self) -> int: ...

    @property
    def torque_enabled(self) -> bool: ...

    @property
    def position(self) -> float: ...

    @property
    def velocity(self) -> float: ...

    @property
    def acceleration(self) -> float: ...


LoadModel = Callable[[ServoView, float], float]
"""``(servo, t) -> present current in A`` (MX-28: Present Load as a fraction of full torque)."""


# --------------------------------------------------------------------------- defaults


class TrapezoidalProfile:
    """The e-manual's motion without a load (the default :class:`ServoDynamics`).

    With torque on, in the position modes Present Position follows a
    trapezoidal profile to Goal Position, limited by Profile Velocity and
    Profile Acceleration; in velocity mode Present Velocity ramps to Goal
    Velocity at Profile Acceleration. Current and PWM modes hold still (no
    torque model), and so does a servo without torque.
    """

    def advance(self, motion: Motion, drive: Drive, dt: float) -> None:
        """Move ``motion`` in place for ``dt`` seconds under ``drive``."""
        if not drive.torque:
            motion.velocity = motion.acceleration = 0.0
            return
        if drive.mode in POSITION_MODES:
            if not drive.profile_active:
                return
            motion.position, motion.velocity, motion.acceleration = _trapezoid(
                motion.position,
                motion.velocity,
                drive.goal_position,
                drive.max_velocity,
                drive.max_acceleration,
                dt,
            )
        elif drive.mode == VELOCITY_MODE:
            target = drive.goal_velocity
            amax = drive.max_acceleration
            gap = target - motion.velocity
            h = dt if gap == 0.0 else min(dt, abs(gap) / amax)
            acc = 0.0 if gap == 0.0 or math.isinf(amax) else math.copysign(amax, gap)
            motion.position += motion.velocity * h + 0.5 * acc * h * h
            motion.velocity += acc * h
            if h < dt:
                motion.velocity = target
                motion.position += target * (dt - h)
                acc = 0.0
            motion.acceleration = acc
        else:  # current and PWM modes: no torque model, so no motion
            motion.velocity = motion.acceleration = 0.0


TRAPEZOIDAL: Final = TrapezoidalProfile()
"""The default dynamics of every virtual servo (it keeps no state of its own)."""


STANDBY_CURRENT_A: Final = 0.1
"""Holding term of the default load model: "Standby Current 100 mA" (e-manual, MX-64(2.0))."""
ACCEL_CURRENT_A_PER_RAD_S2: Final = 0.004
"""Default load model's current per rad/s² of profile acceleration: 0.4 A at 100 rad/s².
Illustrative (a leg segment's inertia through a 200:1 gear), not measured."""
MX28_STALL_CURRENT_A: Final = 1.4
"""MX-28 current at stall torque, 12 V (Table 5.1; ``servo_models."MX-28"``): full load."""


def default_load(servo: ServoView, t: float) -> float:
    """Standby current plus a term proportional to |acceleration|; 0 with torque off.

    The sign follows the acceleration. For the MX-28 the current is
    expressed as a fraction of its stall current (Present Load).
    """
    if not servo.torque_enabled:
        return 0.0
    amps = STANDBY_CURRENT_A + ACCEL_CURRENT_A_PER_RAD_S2 * abs(servo.acceleration) * _RAD_PER_TICK
    amps = -amps if servo.acceleration < 0 else amps
    return amps if servo.model.current_unit_a is not None else amps / MX28_STALL_CURRENT_A


def _trapezoid(
    x: float, v: float, goal: float, vmax: float, amax: float, dt: float
) -> tuple[float, float, float]:
    """Move ``(x, v)`` toward ``goal`` for ``dt`` with |v| ≤ vmax, |a| ≤ amax (∞: steps).

    Exact piecewise-constant-acceleration phases (brake if moving away or if
    the stopping distance has reached the goal, else accelerate, cruise, brake),
    so the result does not depend on how time is sliced. Returns (x, v, a).
    """
    a_last = 0.0
    if vmax <= 0.0:
        return x, 0.0, 0.0
    for _ in range(16):
        if dt <= 0.0:
            break
        d = goal - x
        if d == 0.0 and v == 0.0:
            return goal, 0.0, 0.0
        s = 1.0 if d > 0.0 or (d == 0.0 and v < 0.0) else -1.0
        dist = d * s
        u = v * s
        if math.isinf(amax):
            if dist <= vmax * dt:
                return goal, 0.0, 0.0
            return x + s * vmax * dt, s * vmax, 0.0
        eps = 1e-9 * max(1.0, dist)
        stop = u * u / (2.0 * amax)
        if u < 0.0:  # moving away: brake to zero
            acc, span = amax, -u / amax
        elif stop >= dist - eps:  # brake now (lands on the goal, or overshoots and returns)
            acc, span = -amax, u / amax
        elif u > vmax * (1.0 + 1e-12):  # faster than the profile allows: slow down
            acc, span = -amax, (u - vmax) / amax
        elif u < vmax * (1.0 - 1e-12):  # accelerate to vmax or to the braking point
            u_switch = math.sqrt(u * u + amax * (dist - stop))
            acc, span = amax, (min(u_switch, vmax) - u) / amax
        else:  # cruise to the braking point
            acc, span = 0.0, (dist - stop) / u
        h = min(span, dt)
        x += s * (u * h + 0.5 * acc * h * h)
        v = s * (u + acc * h)
        a_last = s * acc
        dt -= h
        if abs(goal - x) < 1e-6 and abs(v) < 1e-6:
            return goal, 0.0, 0.0
    return x, v, a_last
