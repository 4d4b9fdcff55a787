"""The start-up plan: survey → EEPROM diff → torque plan.

Start-up reads before it writes. It pings every configured servo (waiting
up to ``bus.boot_timeout_s`` for servos still booting) and checks its model
(:func:`model_mismatches`), then reads each servo's Return Delay Time,
Operating Mode, Shutdown, Torque Enable, Velocity Limit, Bus Watchdog,
position gains and goal in one Sync Read (:data:`SURVEY`). From that survey
:func:`plan_start` makes the :class:`StartPlan`: only a servo whose EEPROM
settings differ from the configuration has its torque turned off, and only
the values that differ are written (:func:`eeprom_diff`): a robot standing
under torque keeps standing through a restart. A servo already under torque keeps its goal
(brought within the limits); the others get their present position
(likewise) and torque on. A Bus Watchdog error left by a host that stopped
without stopping the servos is reported and cleared. Position gains the
configuration sets (``joints.*.gains``) are written where they differ
(:func:`gains_diff`): RAM, so under torque, before any goal is written.

These are plain functions of the survey's values; the shell does the port
work (and the retries of torque-on) and publishes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Final

from whexar.actors.bus.servos import (
    OPERATING_MODE,
    RETURN_DELAY,
    WATCHDOG_ERROR,
    Servo,
)
from whexar.bus import control_table as ct
from whexar.bus.sdk import Reply

SURVEY: Final = ct.block(
    [
        "return_delay_time",
        "operating_mode",
        "velocity_limit",
        "shutdown",
        "torque_enable",
        "hardware_error_status",
        "bus_watchdog",
        "position_d_gain",
        "position_i_gain",
        "position_p_gain",
        "goal_position",
        "present_position",
    ]
)
"""What start-up reads of every servo before it writes anything: one Sync Read of 9–135."""
SETTINGS: Final = ct.block(["return_delay_time", "operating_mode"])
"""Return Delay Time (9) and Operating Mode (11): the EEPROM the scheduler sets."""

Change = tuple[ct.Register, int]
"""An EEPROM register and the value to write to it."""


def model_mismatches(servos: Sequence[Servo], pings: Mapping[int, Reply]) -> list[str]:
    """Each servo that answered its ping with another model than the configuration's."""
    return [
        f"{s.name} is a {ct.model_name(pings[s.id].value)} (model {pings[s.id].value}); "
        f"the configuration says {s.model.name} (model {s.model.model_number})"
        for s in servos
        if pings[s.id].ok and pings[s.id].value != s.model.model_number
    ]


def gains_diff(servo: Servo, have: Mapping[str, int]) -> list[Change]:
    """The position gains the configuration gives ``servo`` where ``have`` (read from it)
    differs: RAM, written under torque."""
    return [(reg, v) for reg, v in servo.gains if have[reg.name] != v]


def eeprom_diff(servo: Servo, have: Mapping[str, int], return_delay: int) -> list[Change]:
    """The settings ``servo`` must be given: Return Delay Time ``return_delay`` (2 µs
    units) and its Operating Mode, where ``have`` (read from it) differs."""
    wanted = ((RETURN_DELAY, return_delay), (OPERATING_MODE, servo.mode))
    return [(reg, v) for reg, v in wanted if have[reg.name] != v]


@dataclass(frozen=True, slots=True)
class StartPlan:
    """What start-up does, decided from the survey; every collection in ID order."""

    speed_limits: dict[int, int]
    """Velocity Limit (44) of each servo (a wheel's clamp)."""
    shutdowns: dict[int, int]
    """Shutdown (63) of each servo (its latching error bits)."""
    stopped: tuple[int, ...]
    """Servos whose Bus Watchdog stopped them (−1): reported, then cleared."""
    changes: dict[int, list[Change]]
    """EEPROM to write, per servo (torque off first: EEPROM needs it)."""
    gains: dict[int, list[Change]]
    """Position gains to write, per servo (RAM: under torque, before any goal moves)."""
    holding: frozenset[int]
    """Servos under torque whose EEPROM is right: they keep torque and goal."""
    start_ticks: dict[int, int]
    """Each servo's start goal before the limits: its goal (holding), its present
    position (limp) or zero speed (a wheel)."""
    held_goals: dict[int, int]
    """Goal Position read from each holding positioned servo."""
    limp: tuple[int, ...]
    """Servos whose torque start-up enables (holding each where it is)."""

    def hold_writes(self, goals: Mapping[int, int | None]) -> tuple[dict[int, int], list[int]]:
        """For the holding servos, given the start ``goals`` (within the limits): the
        position goals that had to change, and the wheels (all brought to zero speed)."""
        moved = {
            sid: goals[sid] or 0 for sid, held in self.held_goals.items() if goals[sid] != held
        }
        wheels = [sid for sid in self.holding_ids if sid not in self.held_goals]
        return moved, wheels

    @property
    def holding_ids(self) -> list[int]:
        """:attr:`holding`, in ID order."""
        return sorted(self.holding)


def plan_start(
    servos: Sequence[Servo], survey: Mapping[int, Mapping[str, int]], return_delay: int
) -> StartPlan:
    """The start-up of ``servos`` (in ID order) from their ``survey`` (:data:`SURVEY`,
    decoded, every servo answered); ``return_delay`` is Return Delay Time in 2 µs units."""
    changes: dict[int, list[Change]] = {}
    for s in servos:
        diff = eeprom_diff(s, survey[s.id], return_delay)
        if diff:
            changes[s.id] = diff
    holding = frozenset(
        s.id for s in servos if s.id not in changes and survey[s.id]["torque_enable"]
    )
    start: dict[int, int] = {}
    held: dict[int, int] = {}
    for s in servos:
        if s.endless:
            start[s.id] = 0  # a wheel starts still, whatever it did before
        elif s.id in holding:
            start[s.id] = held[s.id] = survey[s.id]["goal_position"]
        else:
            start[s.id] = survey[s.id]["present_position"]
    return StartPlan(
        speed_limits={s.id: survey[s.id]["velocity_limit"] for s in servos},
        shutdowns={s.id: survey[s.id]["shutdown"] for s in servos},
        stopped=tuple(
            sid for sid, regs in survey.items() if regs["bus_watchdog"] == WATCHDOG_ERROR
        ),
        changes=changes,
        gains={s.id: d for s in servos if (d := gains_diff(s, survey[s.id]))},
        holding=holding,
        start_ticks=start,
        held_goals=held,
        limp=tuple(s.id for s in servos if s.id not in holding),
    )
