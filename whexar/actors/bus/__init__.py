"""The servo bus's actor: :class:`BusScheduler`, the only owner of the servo port.

A thin shell around pure cores, one module each:

* :mod:`~whexar.actors.bus.scheduler` — the actor: the port, the cycle, the clock,
  publishing;
* :mod:`~whexar.actors.bus.servos` — the servo table (joints, models, limits);
* :mod:`~whexar.actors.bus.goals` — the goal policy: latest goal per joint, within
  the limits, clamped or refused; which goals a cycle writes;
* :mod:`~whexar.actors.bus.reads` — the read plan bound to the servos, Fast Sync Read
  or not, decoding what was read;
* :mod:`~whexar.actors.bus.health` — the servo health machine: states, one transition
  table, the actions it asks for (reboot, restore, degrade, lose…);
* :mod:`~whexar.actors.bus.startup` — the start-up plan: survey, EEPROM diff, torque;
* :mod:`~whexar.actors.bus.stats` — :class:`~whexar.actors.messages.BusStats`;
* :mod:`~whexar.actors.bus.jobs` — the port jobs the shell hands the port owner.

The cores take the time and what was observed and return what to write and what to
say; they await nothing, own no channel and read no clock, so their tests call them
directly.

May import what :mod:`whexar.actors` may: the configuration, the device links
(:mod:`whexar.bus`), :mod:`whexar.robot`, :mod:`whexar.errors` and
:mod:`whexar.runtime` (the cores only its message types).
"""

from whexar.actors.bus.scheduler import BusScheduler
from whexar.actors.bus.wiggle import GoalWiggle

__all__ = ["BusScheduler", "GoalWiggle"]
