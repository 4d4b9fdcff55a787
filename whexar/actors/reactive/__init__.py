"""The reactive layer: reflexes, the contact estimate, the terrain estimator and the gait
selector (Žák 2023, 4.2.2–4.2.4, 5.4, 6.7).

Today: the plug-in interface — :class:`Reflex` (a reflex's policy: declared inputs,
validated ``Params``, a priority, what it inhibits), :class:`ReflexActor` (the shell
that runs one) and ``[[reflexes]]`` (:func:`add_reflexes`: written in the graph file or
the robot configuration, found by class path or the ``whexar.reflexes`` entry points);
docs/extending.md walks through one. The terrain estimator (:mod:`.terrain`, 4.2.3)
and the gait selector (:mod:`.selector`, Table 5.9), run by
:class:`TerrainEstimatorActor` and :class:`GaitSelectorActor`: the coordinator walks
the selector's gait while the operator's gait is ``auto``. The reflexes' shared
contact estimate is each leg's (:mod:`whexar.kinematics.contact`), in its
:class:`~whexar.actors.messages.LegState`.

What will live here too, one actor each, each a thin shell around a plain class (its
policy, tested directly): the obstacle reflex (4.2.2, 6.7.4). A lost servo is the
coordinator's own (:mod:`whexar.actors.locomotion.losses`).

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
* it **asks the coordinator** through a typed request (:class:`ReflexRequest` on
  ``reflex-requests``: a higher step, a halt, a heading correction, to sit down);
* its thresholds and gains are its ``Params`` (validated, each with its source).

docs/extending.md (a reflex plug-in) and docs/architecture.md, "Adding an actor" (any
actor) walk through one; ``tests/actors/reactive/`` runs both as tests.

May import: :mod:`whexar.actors.messages`, :mod:`whexar.config` and the layers below;
never another actor subsystem (the actors talk through messages), nor the test helpers.
"""

from whexar.actors.reactive.layer import (
    ACTIVITY,
    OVERRIDES,
    REQUESTS,
    add_reflexes,
    entry_name,
    merged,
    parse_entries,
)
from whexar.actors.reactive.reflex import (
    ENTRY_POINTS,
    STREAMS,
    Command,
    Reflex,
    ReflexParams,
    Shutdown,
    check_params,
    resolve_reflex,
)
from whexar.actors.reactive.selection import GaitSelectorActor, TerrainEstimatorActor
from whexar.actors.reactive.shell import ReflexActor

__all__ = [
    "ACTIVITY",
    "ENTRY_POINTS",
    "OVERRIDES",
    "REQUESTS",
    "STREAMS",
    "Command",
    "GaitSelectorActor",
    "Reflex",
    "ReflexActor",
    "ReflexParams",
    "Shutdown",
    "TerrainEstimatorActor",
    "add_reflexes",
    "check_params",
    "entry_name",
    "merged",
    "parse_entries",
    "resolve_reflex",
]
