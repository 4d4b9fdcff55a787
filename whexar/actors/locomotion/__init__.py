"""Locomotion: the coordinator and the six leg controllers (Žák 2023, 4.2.5–4.2.6).

* :mod:`~whexar.actors.locomotion.leg` — :class:`~whexar.actors.locomotion.leg.LegActor`,
  one per leg, a shell around
  :class:`~whexar.actors.locomotion.leg_controller.LegController`: steps, swing, IK,
  wheel, contact, overrides;
* :mod:`~whexar.actors.locomotion.coordinator` — the coordinator: gaits, riding, the
  hybrid gait, stances, the flip, stand up and sit down.

Each actor is a thin shell (its ports, its loop, publishing, the clock) around a plain
class whose methods take the time and the inputs and return what to send.
"""
