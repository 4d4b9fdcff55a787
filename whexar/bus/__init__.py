"""Device links: the Dynamixel servo bus and (with its issue) the sensor-board serial line.

* :mod:`~whexar.bus.control_table` — MX (2.0) registers, models and units;
* :mod:`~whexar.bus.protocol` — the sans-IO Protocol 2.0 codec and wire sizes;
* :mod:`~whexar.bus.plan` — read plans (what the scheduler reads, how often);
* :mod:`~whexar.bus.sdk` — dynamixel-sdk behind one adapter, and the port owners;
* :mod:`~whexar.bus.emulator` — 42 virtual servos, byte for byte, with timing;
* :mod:`~whexar.bus.faults` — declarative fault plans for the emulator;
* :mod:`~whexar.bus.pty` — the emulator on a pseudo-terminal, in real time;
* :mod:`~whexar.bus.scan` — ``whexar bus scan``.

The scheduler actor that owns the port is :mod:`whexar.actors.bus`.
"""
