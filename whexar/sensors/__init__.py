"""The sensor links: the ATmega2560 sensor board's serial line, the LSM9DS1 IMU, and the
Linux input devices a gamepad drives the robot through.

* :mod:`~whexar.sensors.frame` — the board's frames (``firmware/PROTOCOL.md``), a sans-IO codec;
* :mod:`~whexar.sensors.serial_link` — the board's serial port over pyserial-asyncio;
* :mod:`~whexar.sensors.board_emulator` — the board's firmware in Python, on virtual time;
* :mod:`~whexar.sensors.usart` — the serial rates the board's ATmega2560 can run at;
* :mod:`~whexar.sensors.gravity` — whether an accelerometer reading is gravity (tilt or none);
* :mod:`~whexar.sensors.lsm9ds1` — the LSM9DS1 IMU driver over an SMBus;
* :mod:`~whexar.sensors.imu_emulator` — a fake I²C bus and a register-level LSM9DS1;
* :mod:`~whexar.sensors.evdev` — Linux input events (a gamepad's ``struct input_event``
  records), a sans-IO codec; :mod:`~whexar.sensors.evdev_link` — the event device
  opened and read without blocking, and an in-process pad over a pipe;
* :mod:`~whexar.sensors.replay` — the board's link and the IMU's calls played back from a
  recording (``whexar replay``).

May import: :mod:`whexar.kinematics` (the ADC conversions of eq. 5.5–5.7),
:mod:`whexar.robot`, :mod:`whexar.errors` and :mod:`whexar.runtime` — never the
configuration (callers pass values) nor the servo bus. The actors that own
these links are :mod:`whexar.actors.sensing.board` and :mod:`whexar.actors.sensing.imu`;
the gamepad's is the command source, :mod:`whexar.actors.commands.source`.
"""
