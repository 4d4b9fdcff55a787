"""The reactive layer: reflexes, the contact estimate, the terrain estimator and the gait
selector (Žák 2023, 4.2.2–4.2.4, 5.4, 6.7). Empty today; this is where they will live.

What will live here, one actor each, each a thin shell around a plain class (its policy,
tested directly): the reflexes of the thesis (trochanter, tarsus, stepping, elevator,
searching, obstacle, battery) and beyond it (heading hold, a lost servo reported), one
contact estimate per leg, the terrain estimator and the gait selector.

How a reflex plugs in — no file of the core changes:

* it **subscribes** to the messages it needs, by wiring its inputs in the robot's graph
  (``config/graphs/walk.toml``): the legs' swing ends (:class:`SwingEnded` on
  ``swings``, typed outcomes: the elevator and searching reflexes' signal), the legs'
  states (``legs``), the servo states, the force sensors (``loads``), the ranges, the
  tilt, the locomotion state;
* it **acts on a leg** through the leg's override input (``reflex``):
  :class:`JointGoals` marked ``reflex`` take joints over for
  ``locomotion.reflex_hold_s``, after which the leg blends back to its own trajectory.
  The leg alone decides its joints' goals, so a reflex never writes to the bus;
* it **asks the coordinator** through a typed request message (to come, with the
  layer: a step height, a stop, a gait);
* its thresholds and gains are its ``Params`` (validated, each with its source).

README, "Adding an actor", walks through one, and ``tests/actors/reactive/`` holds the
worked example as a test.

May import: :mod:`whexar.actors.messages`, :mod:`whexar.config` and the layers below;
never another actor subsystem (the actors talk through messages), nor the test helpers.
"""
