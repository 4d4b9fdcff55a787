"""The robot's actors and messages: the subsystems of WHexaR, on the actor runtime.

One subpackage per subsystem; each actor is a thin shell (ports, loop, publishing,
clock) around a pure core, a plain class tested directly (docs/architecture.md):

* :mod:`~whexar.actors.messages` — the robot's messages: servo goals and states,
  sensor frames, ranges, loads, tilt, and the devices' events;
* :mod:`~whexar.actors.bus` — :class:`~whexar.actors.bus.BusScheduler`, the only owner
  of the servo bus;
* :mod:`~whexar.actors.sensing` — the sensor board's reader (its serial line) and the
  IMU's (the LSM9DS1 on I²C);
* :mod:`~whexar.actors.locomotion` — the leg actors (one per leg: steps, IK, wheel,
  contact, overrides) and the coordinator, each a shell around a pure core;
* :mod:`~whexar.actors.commands` — :class:`~whexar.actors.commands.CommandSource`:
  command scripts, stdin and the keyboard;
* :mod:`~whexar.actors.reactive` — the reflexes, the contact and terrain estimates and
  the gait selector, to come: how one plugs in;
* :mod:`~whexar.actors.graph` — the robot's one graph, ``config/graphs/walk.toml``,
  loaded with its edges (devices, command source) swapped by name.

The subsystems never import one another: they talk through messages. The runtime
they run on (actors, ports, channels, clock, wiring, supervision) is
:mod:`whexar.runtime`.

May import: :mod:`whexar.config`, the device links (:mod:`whexar.bus`,
:mod:`whexar.sensors`), :mod:`whexar.kinematics`, :mod:`whexar.robot`,
:mod:`whexar.errors` and :mod:`whexar.runtime` — never the test helpers, the
benchmarks or the command line.
"""
