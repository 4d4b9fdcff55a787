"""Public test helpers: run actors on virtual time, feed them, capture, compare.

Used by whexar's own tests and meant for anyone extending the runtime::

    from whexar.testing import run_actors

    result = run_actors(graph, duration=5.0)
    assert result.exit_code == 0
    beats = result.messages("beats")

See :func:`run_actors`, :class:`Harness` and :class:`MessageLog` (the run harness
itself lives beside the runtime, :mod:`whexar.runtime.harness`, because the
simulation and replay run on it too). :func:`~whexar.testing.walk.walk_graph`
is the robot's one graph without its sensors. The small
actors in :mod:`whexar.testing.actors` are importable from the wiring as
``whexar.testing:Pulse`` and so on: ``Pulse``, ``Relay`` and ``Sink``, the
misbehaving ``Flood`` (a tight-loop publisher) and ``Stubborn`` (a cleanup
that ignores the stop), ``Brake``, which stands for the servos in a safe
stop, and ``RealIO``, which waits on real I/O. One module per device adds
its graph and helpers: :mod:`~whexar.testing.bus` (the robot's emulated
servos, a goal source), :mod:`~whexar.testing.sensors`,
:mod:`~whexar.testing.imu`; :mod:`~whexar.testing.reflexes` makes the messages
a reflex's policy reads; :mod:`~whexar.testing.thesis` holds reference
values of the thesis. The emulators themselves belong to their device
packages (:mod:`whexar.bus.emulator`, :mod:`whexar.sensors.board_emulator`,
:mod:`whexar.sensors.imu_emulator`): the actors open them by name.

May import: everything of whexar. No module of whexar imports it: it is
for tests, whexar's and its users' (the import contracts say so).
"""

from whexar.runtime.harness import (
    HARNESS,
    Harness,
    LogEntry,
    MessageLog,
    RunResult,
    Scenario,
    run_actors,
)
from whexar.testing.actors import (
    Brake,
    Braked,
    Flood,
    InjectedFailure,
    Pulse,
    RealIO,
    Relay,
    Sink,
    Stubborn,
)
from whexar.testing.imu import imu_graph

__all__ = [
    "HARNESS",
    "Brake",
    "Braked",
    "Flood",
    "Harness",
    "InjectedFailure",
    "LogEntry",
    "MessageLog",
    "Pulse",
    "RealIO",
    "Relay",
    "RunResult",
    "Scenario",
    "Sink",
    "Stubborn",
    "imu_graph",
    "run_actors",
]
