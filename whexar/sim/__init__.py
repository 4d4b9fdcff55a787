"""The simulated WHexaR: a MuJoCo world behind the real bus and sensor paths.

* :mod:`~whexar.sim.motors` — the MX servos' motors and firmware gains, with sources;
* :mod:`~whexar.sim.model` — the MJCF (and URDF) model built from the configuration;
* :mod:`~whexar.sim.terrain` — the terrains;
* :mod:`~whexar.sim.world` — the physics world behind the servo emulator and the sensor
  emulators, advanced on the runtime's virtual clock;
* :mod:`~whexar.sim.run` — one run of the full runtime against the world (:func:`simulate`);
* :mod:`~whexar.sim.scenario` — scenario files (terrain, start, commands, faults);
* :mod:`~whexar.sim.report` and :mod:`~whexar.sim.video` — plots, summary, video;
* :mod:`~whexar.sim.urdf` — the same robot as URDF, for Foxglove and RViz.

May import: :mod:`whexar.record`, :mod:`whexar.actors` and everything below them; never
the test helpers (:mod:`whexar.testing`), the benchmarks or the command line.
"""
