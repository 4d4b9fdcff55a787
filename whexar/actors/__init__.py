"""Actors: every subsystem of the runtime, exchanging typed messages.

* :mod:`~whexar.runtime.clock` — the runtime clock, real or virtual time;
* :mod:`~whexar.actors.messages` — every message type, immutable and stamped;
* :mod:`~whexar.runtime.channels` — bounded channels and their overflow policies;
* :mod:`~whexar.runtime.actor` — the actor base class and its typed ports;
* :mod:`~whexar.runtime.ticker` — deadline-based control cycles;
* :mod:`~whexar.runtime.wiring` — the actor graph from configuration, checked;
* :mod:`~whexar.runtime.supervisor` — start, supervision, safe stop, shutdown.

The robot's own actors (legs, coordinator, reflexes, bus, sensors) arrive
with the issues that need them.
"""
