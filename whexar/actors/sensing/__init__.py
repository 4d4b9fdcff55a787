"""Sensing: the readers of the robot's sensors, each the only owner of its link.

* :mod:`~whexar.actors.sensing.board` — :class:`SensorReader`, the sensor board's serial
  line: IR ranges, force sensors (leg loads), the optional accelerometer's tilt;
* :mod:`~whexar.actors.sensing.imu` — :class:`ImuReader`, the LSM9DS1 on I²C: body tilt.

A graph names them ``whexar.actors.sensing:SensorReader`` and
``whexar.actors.sensing:ImuReader``.

May import: :mod:`whexar.actors.messages`, :mod:`whexar.config`, the device links of
:mod:`whexar.sensors` and the layers below; never another actor subsystem.
"""

from whexar.actors.sensing.board import SensorReader, emulated_board
from whexar.actors.sensing.imu import ImuReader

__all__ = ["ImuReader", "SensorReader", "emulated_board"]
