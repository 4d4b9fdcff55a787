"""whexar: the asynchronous actor runtime of WHexaR, a wheeled hexapod robot.

Packages, bottom to top (each imports only from those below it; the
contracts in pyproject.toml say so and ``lint-imports`` checks them):

* :mod:`whexar.runtime` — the actor runtime, robot-agnostic;
* :mod:`whexar.errors`, :mod:`whexar.robot` — the error tree; legs, joints, servo IDs;
* :mod:`whexar.kinematics` — pure numpy: IK, body frames, wheels, gaits, stability;
* :mod:`whexar.bus`, :mod:`whexar.sensors` — the device links and their emulators;
* :mod:`whexar.config` — the robot configuration, validated;
* :mod:`whexar.actors` — the robot's actors and messages, and its one graph;
* :mod:`whexar.record`, :mod:`whexar.sim`, :mod:`whexar.campaign` — recordings and replay,
  the simulated robot, campaigns of runs;
* :mod:`whexar.testing` — helpers for tests (whexar's and its users');
* :mod:`whexar.bench` — benchmarks;
* :mod:`whexar.cli` — the ``whexar`` command.

Units: SI inside the code (metres, radians, seconds, kilograms, newtons,
amperes, volts). Files and command lines that use other units say so in the
name of every key or option (``_mm``, ``_deg``, ``_us``, ...).
"""

__version__ = "0.1.0"
