"""WHexaR kinematics: pure numpy, SI units, vectorised over legs and points.

* :mod:`~whexar.kinematics.geometry` — the legs' geometry (DH table, limits, mounts);
* :mod:`~whexar.kinematics.leg` — forward and inverse kinematics of one leg (4.2–4.3);
* :mod:`~whexar.kinematics.body` — body and leg frames, body poses, stances;
* :mod:`~whexar.kinematics.wheels` — steering angles and wheel rates (5.4);
* :mod:`~whexar.kinematics.trajectory`, :mod:`~whexar.kinematics.cpg` — foot trajectories,
  CPG orbits;
* :mod:`~whexar.kinematics.gait`, :mod:`~whexar.kinematics.stability` — gaits, stability;
* :mod:`~whexar.kinematics.indices`, :mod:`~whexar.kinematics.sensing` — performance
  indices, sensor conversions (eq. 5.5–5.7).

Every function takes its geometry, stance or wheel radius as an argument;
:class:`whexar.config.RobotConfig` builds them (``leg_geometry()``, ``stance()``).

May import: :mod:`whexar.robot`, :mod:`whexar.errors` and the runtime's
argument checks (:mod:`whexar.runtime.checks`) — never the configuration.
"""
