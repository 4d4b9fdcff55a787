"""The Dynamixel servo bus: 42 MX (2.0) servos on one half-duplex line, Protocol 2.0.

* :mod:`~whexar.bus.control_table` — MX (2.0) registers, models and units;
* :mod:`~whexar.bus.protocol` — the sans-IO Protocol 2.0 codec and wire sizes;
* :mod:`~whexar.bus.plan` — read plans (what the scheduler reads, how often);
* :mod:`~whexar.bus.sdk` — dynamixel-sdk behind one adapter, and the port owners;
* :mod:`~whexar.bus.scan` — ``whexar bus scan``;
* :mod:`~whexar.bus.replay` — a recorded bus played back to dynamixel-sdk (``whexar replay``);
* :mod:`whexar.bus.emulator` — the servos in-process or on a pty, with fault plans.

May import :mod:`whexar.robot`, :mod:`whexar.errors` and :mod:`whexar.runtime`
(the clock, the device registry, the configuration schema) — never the robot
configuration, which imports the bus's plans and IDs to validate ``[bus]``,
nor the sensors. The actor that owns the bus is :mod:`whexar.actors.bus`.
"""
