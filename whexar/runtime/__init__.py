"""The actor runtime: robot-agnostic, it imports nothing from the rest of whexar.

* :mod:`~whexar.runtime.clock` — the runtime clock, real or virtual time;
* :mod:`~whexar.runtime.messages` — the base message, its registry, the runtime's events;
* :mod:`~whexar.runtime.channels` — bounded channels and their overflow policies;
* :mod:`~whexar.runtime.actor` — the actor base class and its typed ports;
* :mod:`~whexar.runtime.ticker` — deadline-based control cycles;
* :mod:`~whexar.runtime.wiring` — the actor graph from configuration, checked;
* :mod:`~whexar.runtime.supervisor` — :class:`Runtime`: start, supervision, safe stop, shutdown;
* :mod:`~whexar.runtime.devices` — in-process devices (emulators, fakes) opened by name;
* :mod:`~whexar.runtime.schema` — configuration documents: sections, key paths, problems;
* :mod:`~whexar.runtime.checks` — scalar argument checks;
* :mod:`~whexar.runtime.errors` — the root of the error tree.

May import: the standard library, anyio, pydantic, numpy — and nothing of whexar
outside this package (``lint-imports`` checks it), so it could be published on
its own. The robot's actors and messages are in :mod:`whexar.actors`.
"""
