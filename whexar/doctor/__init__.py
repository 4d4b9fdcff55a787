"""``whexar doctor``: is the robot ready to run? One check after another, each saying what
is wrong and the command that fixes it.

* :mod:`~whexar.doctor.report` — a check's typed result and the checks' shared state;
* :mod:`~whexar.doctor.run` — the checks in order, and the runner that skips a check
  whose prerequisite failed;
* :mod:`~whexar.doctor.environment` — everything a check touches (sysfs, ``/dev``, the
  user's groups, the servo port, the I²C bus, the disk), injected so tests fake each;
* :mod:`~whexar.doctor.host` — servo port and permissions, the adapter's latency
  timer, free disk for recordings, Python and package versions;
* :mod:`~whexar.doctor.servos` — the servo bus: the baud rate answers, every servo
  of the configuration with its model, firmware and ID (and nothing else), each
  servo's EEPROM against the configuration, supply voltage and temperatures;
* :mod:`~whexar.doctor.board` — the sensor board: its port, its frames and their rate;
* :mod:`~whexar.doctor.devices` — the IMU on I²C.

Each check is a plain function of the environment and what earlier checks found;
the command line (:mod:`whexar.cli.doctor`) only prints the results. May import
the configuration, the device links (:mod:`whexar.bus`, :mod:`whexar.sensors`),
the actors' pure parts (the servo table's tick limits), :mod:`whexar.record` (the
recordings folder) and everything below them; never the command line or the benches.
"""

from whexar.doctor.environment import Environment
from whexar.doctor.report import Check, CheckResult, Findings, Status
from whexar.doctor.run import CHECKS, ready, run_checks

__all__ = [
    "CHECKS",
    "Check",
    "CheckResult",
    "Environment",
    "Findings",
    "Status",
    "ready",
    "run_checks",
]
