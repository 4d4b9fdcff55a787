"""Actors: every subsystem of the runtime, exchanging typed messages.

* :mod:`~whexar.actors.clock` — the runtime clock, real or virtual time;
* :mod:`~whexar.actors.messages` — every message type, immutable and stamped;
* :mod:`~whexar.actors.channels` — bounded channels and their overflow policies;
* :mod:`~whexar.actors.actor` — the actor base class and its typed ports;
* :mod:`~whexar.actors.ticker` — deadline-based control cycles;
* :mod:`~whexar.actors.wiring` — the actor graph from configuration, checked;
* :mod:`~whexar.actors.runtime` — start, supervision, safe stop, shutdown.

The robot's own actors (legs, coordinator, reflexes, bus, sensors) arrive
with the issues that need them.
"""
