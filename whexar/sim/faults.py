"""Sensor faults in a simulated run: what the sensor board and the IMU can do wrong.

The bus has its fault plans (:mod:`whexar.bus.emulator.faults`); these are the
sensor side's, applied at their times by :func:`whexar.sim.run.simulate`:

* ``unplug`` — the board's USB cable or the IMU's I²C link goes away for
  ``duration_s`` (0: for good), then comes back;
* ``corrupt`` / ``drop`` — the board's next ``frames`` frames arrive with a
  flipped bit, or not at all;
* ``freeze`` — the IMU's readings stop changing for ``duration_s`` (a hung chip);
* ``dead_fsr`` — leg ``leg``'s force sensor reads 0 from now on (a broken wire);
* ``dead_ir`` — rangefinder ``sensor`` (0 right, 1 left) reads 0 counts: no reading.

Each becomes what the readers see on the robot: a link down and up again, a
rejected frame, a gap, a stale link, a contact that never comes.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from whexar.runtime.errors import Problem
from whexar.runtime.schema import NonNegative, Section

FaultKind = Literal["unplug", "corrupt", "drop", "freeze", "dead_fsr", "dead_ir"]
Device = Literal["board", "imu"]


class SensorFault(Section):
    """One sensor fault of a scenario (``[[sensor_faults]]``)."""

    at_s: NonNegative
    """When it happens, s of simulated time."""
    kind: FaultKind
    device: Device = "board"
    duration_s: NonNegative = 0.0
    """``unplug`` and ``freeze``: how long (0: for good)."""
    frames: int = Field(default=1, ge=1)
    """``corrupt`` and ``drop``: how many frames."""
    leg: int = Field(default=0, ge=0, le=5)
    """``dead_fsr``: the leg, 0…5 (RF, LF, RM, LM, RR, LR)."""
    sensor: int = Field(default=0, ge=0, le=1)
    """``dead_ir``: the rangefinder, 0 right, 1 left."""

    def problems(self, at: str) -> list[Problem]:
        found = []
        board_only = ("corrupt", "drop", "dead_fsr", "dead_ir")
        if self.kind in board_only and self.device != "board":
            found.append(Problem(f"{at}.device", self.device, f"'board': {self.kind} is its"))
        if self.kind == "freeze" and self.device != "imu":
            found.append(Problem(f"{at}.device", self.device, "'imu': only the IMU freezes"))
        return found


__all__ = ["Device", "FaultKind", "SensorFault"]
