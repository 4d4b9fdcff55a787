"""Device links: the Dynamixel servo bus, the sensor board's serial line and the IMU.

* :mod:`~whexar.bus.control_table` — MX (2.0) registers, models and units;
* :mod:`~whexar.bus.protocol` — the sans-IO Protocol 2.0 codec and wire sizes;
* :mod:`~whexar.bus.plan` — read plans (what the scheduler reads, how often);
* :mod:`~whexar.bus.sdk` — dynamixel-sdk behind one adapter, and the port owners;
* :mod:`~whexar.bus.emulator.chain` — 42 virtual servos, byte for byte, with timing;
* :mod:`~whexar.bus.emulator.faults` — declarative fault plans for the emulator;
* :mod:`~whexar.bus.emulator.pty` — the emulator on a pseudo-terminal, in real time;
* :mod:`~whexar.bus.scan` — ``whexar bus scan``;
* :mod:`~whexar.sensors.frame` — the sensor board's frames, a sans-IO codec;
* :mod:`~whexar.sensors.serial_link` — the board's serial port over pyserial-asyncio;
* :mod:`~whexar.sensors.board_emulator` — the board's firmware in Python, on virtual time;
* :mod:`~whexar.sensors.lsm9ds1` — the LSM9DS1 IMU driver over an SMBus.

The actors that own these links are :mod:`whexar.actors.bus`,
:mod:`whexar.actors.sensors` and :mod:`whexar.actors.imu`.
"""
