"""The servo emulator: 42 virtual MX (2.0) servos on one bus, byte for byte, on bus time.

By what it models, from the wire inwards:

* :mod:`~whexar.bus.emulator.port` — the chain as a serial port that dynamixel-sdk drives;
* :mod:`~whexar.bus.emulator.chain` — the bus: instructions, broadcast rules, faults;
* :mod:`~whexar.bus.emulator.timing` — how long each exchange keeps the bus busy;
* :mod:`~whexar.bus.emulator.servo` — one servo: control table, access rules, error bits;
* :mod:`~whexar.bus.emulator.dynamics` — its motor: the seam a physics world replaces;
* :mod:`~whexar.bus.emulator.faults` — declarative fault plans (``config/faults/*.toml``);
* :mod:`~whexar.bus.emulator.pty` — the chain on a pseudo-terminal, in real time.

May import the rest of :mod:`whexar.bus`, :mod:`whexar.errors` and
:mod:`whexar.runtime` (the clock, the device registry); never the
configuration: callers pass servo IDs and models
(:meth:`~whexar.bus.emulator.chain.ServoChain.for_models`).
"""
