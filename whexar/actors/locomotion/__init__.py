"""Locomotion: the coordinator and the six leg controllers (Žák 2023, 4.2.5–4.2.6).

Each actor is a thin shell (its ports, its loop, publishing, the clock) around a plain
class whose methods take the time and the inputs and return what to send:

* :mod:`~.leg` — :class:`LegActor`, one per leg, around
  :class:`~.leg_controller.LegController`: steps, swing, IK, wheel, contact,
  overrides; with :mod:`~.frames` (the leg's frame through the body pose) and
  :mod:`~.steps` (the foot's path and the adaptive swing);
* :mod:`~.coordinator` — :class:`Coordinator`, around
  :class:`~.planner.LocomotionPlanner`: :mod:`~.intent` (commands checked),
  :mod:`~.activity` (what it does, and the table of what may follow what),
  :mod:`~.core` (its state and shared geometry), :mod:`~.scripts` (stand up, sit
  down, stance and mode changes, the flip) and :mod:`~.engines` (the gait, riding,
  the hybrid gait).

A graph names them ``whexar.actors.locomotion:LegActor`` and
``whexar.actors.locomotion:Coordinator``.

May import: :mod:`whexar.actors.messages`, :mod:`whexar.config` and the layers below; never
another actor subsystem (the actors talk through messages), nor the test helpers. The cores
(every module but the two actors) import no ``anyio``, channel or clock: the import
contracts say so.
"""

from whexar.actors.locomotion.coordinator import Coordinator
from whexar.actors.locomotion.leg import LegActor

__all__ = ["Coordinator", "LegActor"]
