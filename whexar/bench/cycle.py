"""``whexar bench cycle``: CPU per control cycle of the locomotion stack.

Target: the median CPU time of one control cycle of steady walking, for the six
:class:`~whexar.actors.locomotion.leg.LegActor` and the
:class:`~whexar.actors.locomotion.coordinator.Coordinator` together, is at most **1.0 ms**
on the machine that runs the bench.

What is measured
----------------
The robot's graph (:func:`~whexar.actors.graph.robot_graph`) without its bus
and sensor actors runs on virtual time, the real actor classes under the real runtime (wiring,
ports, channels, the actors' tasks). The bench stands in for the bus as a
*perfect servo chain*: every cycle it publishes one :class:`ServoStates` on
``servo-state`` (42 :class:`JointState`, each joint where its last goal put it,
the wheels at their goal speed), then lets virtual time run to the middle of
the cycle, which the loop only does once every actor waits again: the six
legs have sent their :class:`JointGoals`, the coordinator its
:class:`BodyMotion`, :class:`StepCommand` and :class:`LocomotionState`.

* **cpu_ms_per_cycle** — the thread CPU time (``time.thread_time_ns``) from
  publishing the states until then: the legs' and the coordinator's work of
  the cycle (inputs, trajectories, IK, wheels, making and passing every
  message, the tasks' wake-ups), less the bench's own share. That share — the
  clock sleep and wake-up of the bench's task and one pass of the loop — is
  measured every cycle in the second half of the cycle, when every actor is
  idle, and its median is subtracted. Making the states message is not in
  the window. Median over 1000 cycles of steady tripod walking at 0.1 m/s,
  after the stand-up and the speed ramp; the whole scenario runs three
  times and the figure is the median of the three runs' medians, so a burst
  of load from another process during one run does not move it.
* **p99_ms** — the 99th percentile of the same samples, median of the runs'
  (garbage-collector passes and the machine's noise land here).
* the same two for riding (0.1 m/s on the wheels) and for the hybrid gait
  (0.1 m/s, ripple, half of it on the wheels), so every steady engine of the
  coordinator is covered; the transitions between them are run, not measured.
* a breakdown from one more run of the same scenario in which each actor's
  policy is timed (its pure core's cycle: :class:`LegController`,
  :class:`LocomotionPlanner`): the six legs, the coordinator, and the rest of
  the window (receiving, publishing, task switches). That run's timers stay out of the headline run.

The control cycle runs at :data:`RATE_HZ`, 100 Hz: between the thesis's 80 Hz
main loop and the 110 Hz the bus's ``positioning`` plan aims at. On virtual
time the rate changes what the gait does per cycle, not what a cycle costs.
No message log is kept: its garbage-collector passes would be billed to the
cycles.
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar

import anyio

from whexar.actors.graph import robot_graph
from whexar.actors.locomotion.coordinator import Coordinator
from whexar.actors.locomotion.leg import LegActor
from whexar.actors.locomotion.leg_controller import LegController
from whexar.actors.locomotion.planner import LocomotionPlanner
from whexar.actors.messages import (
    JointGoals,
    JointState,
    LegState,
    LocomotionState,
    MotionCommand,
    ServoStates,
)
from whexar.bench import Figure, Progress, Report, percentile
from whexar.config import RobotConfig
from whexar.robot import N_JOINTS, N_LEGS
from whexar.runtime.clock import run as run_loop
from whexar.runtime.messages import Message
from whexar.runtime.supervisor import Runtime
from whexar.runtime.wiring import build_graph

CYCLE_TARGET_MS = 1.0
"""Target: median CPU of one control cycle of the six legs and the coordinator."""
RATE_HZ = 100.0
"""Control cycles per second of virtual time."""
CYCLES = 1000
"""Measured cycles per steady engine and run."""
REPEATS = 3
"""Runs of the whole scenario for the headline figures (medians of the runs' figures)."""
SPEED_M_S = 0.1
SETTLE_S = 1.0
"""Virtual time run, not measured, after an engine is steady and before measuring it."""
REACH_S = 20.0
"""Virtual time an engine may take to become steady before the bench gives up."""
FEEDER = "bench"
_WHEEL = 6


@dataclass(frozen=True)
class Engine:
    """One steady engine of the coordinator: the command that starts it, the activity."""

    name: str
    label: str
    command: MotionCommand
    activity: str


def command(**fields: Any) -> MotionCommand:
    """A :class:`MotionCommand` from the bench, at time 0."""
    return MotionCommand(t=0.0, source="bench", **fields)


ENGINES: tuple[Engine, ...] = (
    Engine("walk", "tripod walk", command(vx_m_s=SPEED_M_S), "walking"),
    Engine("ride", "riding", command(mode="ride", vx_m_s=SPEED_M_S), "riding"),
    Engine("hybrid", "hybrid gait", command(mode="hybrid", vx_m_s=SPEED_M_S), "hybrid"),
)


def stack_graph() -> dict[str, Any]:
    """The robot's graph without the bus and the sensors: ``servo-state`` and ``commands``
    fed by the bench, the legs sensing no contact (the perfect servos have no ground)."""
    return robot_graph(
        params={"leg-*": {"contact": "none"}},
        leave_out=("bus", "sensors", "imu"),
        feeds=["servo-state", "commands"],
    )


class PerfectServos:
    """42 servos that are where their last goal put them, one bus cycle later."""

    def __init__(self, cfg: RobotConfig) -> None:
        self.ids = [
            (leg, joint, sid)
            for leg, spec in enumerate(cfg.legs)
            for joint, sid in enumerate(spec.servo_ids)
        ]
        n = len(self.ids)
        self.position = [0.0] * n
        self.velocity = [0.0] * n
        self.goal = [0.0] * n
        self.wheel_speed = [0.0] * n

    def take(self, msg: JointGoals) -> None:
        """Latest goal per joint wins, as on the bus."""
        for g in msg.goals:
            k = g.leg * N_JOINTS + g.joint
            if g.position_rad is not None:
                self.goal[k] = g.position_rad
            if g.velocity_rad_s is not None:
                self.wheel_speed[k] = g.velocity_rad_s

    def states(self, t: float, cycle: int, dt: float) -> ServoStates:
        """The reading of cycle ``cycle`` at ``t``: every goal reached ``dt`` after the last."""
        joints = []
        for k, (leg, joint, sid) in enumerate(self.ids):
            if joint == _WHEEL:
                v = self.wheel_speed[k]
                p = self.position[k] + v * dt
            else:
                p = self.goal[k]
                v = (p - self.position[k]) / dt if dt > 0 else 0.0
            self.position[k] = p
            self.velocity[k] = v
            joints.append(JointState(leg, joint, sid, p, v, 0.0))
        return ServoStates(t=t, source=FEEDER, cycle=cycle, joints=tuple(joints))


def _stopwatch(core: type[Any]) -> Any:
    """``core`` (a policy class) with a CPU stopwatch on its cycle: ``spent[0]``, ns."""

    class Timed(core):  # type: ignore[misc]  # a class made at run time
        spent: ClassVar[list[int]] = [0]

        def cycle(self, *args: Any, **kwargs: Any) -> list[Message]:
            start = time.thread_time_ns()
            try:
                return super().cycle(*args, **kwargs)  # type: ignore[no-any-return]
            finally:
                self.spent[0] += time.thread_time_ns() - start

    Timed.__name__ = Timed.__qualname__ = f"Timed{core.__name__}"
    return Timed


_TimedLeg = _stopwatch(LegController)
_TimedPlanner = _stopwatch(LocomotionPlanner)


class TimedLegActor(LegActor):
    """A leg actor whose policy's cycles are timed (``spent[0]``, ns)."""

    controller = _TimedLeg
    spent = _TimedLeg.spent


class TimedCoordinator(Coordinator):
    """A coordinator whose policy's cycles are timed (``spent[0]``, ns)."""

    policy = _TimedPlanner
    spent = _TimedPlanner.spent


@dataclass
class Samples:
    """Per-cycle CPU of one engine, in nanoseconds."""

    window: list[int] = field(default_factory=list)
    """From publishing the states until every actor waits again."""
    idle: list[int] = field(default_factory=list)
    """The same stretch of the bench's own loop with every actor idle."""
    legs: list[int] = field(default_factory=list)
    coordinator: list[int] = field(default_factory=list)
    off_activity: int = 0
    """Cycles whose published activity was not the engine's."""
    missing_goals: int = 0
    """Cycles in which not every leg answered (a LegState for the cycle's time)."""
    swing_cycles: int = 0
    """Cycles with a leg in swing (the coordinator's :class:`LocomotionState`)."""
    rolling_cycles: int = 0
    """Cycles with a wheel goal other than zero."""


@dataclass(frozen=True)
class EngineFigures:
    """Milliseconds per cycle of one engine."""

    name: str
    label: str
    cycles: int
    """Measured cycles per run."""
    runs: int
    median_ms: float
    p99_ms: float
    mean_ms: float
    max_ms: float
    idle_ms: float
    run_medians_ms: tuple[float, ...]
    off_activity: int
    missing_goals: int
    swing_cycles: int
    rolling_cycles: int
    legs_ms: float | None = None
    coordinator_ms: float | None = None
    window_ms: float | None = None
    """Median window of the timed run (legs + coordinator + the rest), less the idle share."""


def _rounded(value: object) -> object:
    if isinstance(value, float):
        return round(value, 4)
    if isinstance(value, tuple):
        return [_rounded(v) for v in value]
    return value


def measure(
    cycles: int = CYCLES,
    *,
    rate_hz: float = RATE_HZ,
    timed: bool = False,
    engines: tuple[Engine, ...] = ENGINES,
    say: Callable[[str], None] = lambda _line: None,
) -> dict[str, Samples]:
    """Run the stack on virtual time and time ``cycles`` cycles of each engine.

    With ``timed`` the legs and the coordinator are their stopwatch subclasses
    and the per-cycle ticks are kept as well.
    """
    doc = stack_graph()
    if timed:
        for actor in doc["actors"]:
            if actor["class"].endswith(":LegActor"):
                actor["class"] = "whexar.bench.cycle:TimedLegActor"
            elif actor["class"].endswith(":Coordinator"):
                actor["class"] = "whexar.bench.cycle:TimedCoordinator"
    graph = build_graph(doc, external={"servo-state": FEEDER, "commands": FEEDER})
    period = 1.0 / rate_hz
    servos = PerfectServos(RobotConfig())
    legs_spent, coord_spent = TimedLegActor.spent, TimedCoordinator.spent
    out: dict[str, Samples] = {}

    async def main() -> None:
        runtime = Runtime(graph)
        async with anyio.create_task_group() as tg:
            await tg.start(runtime.run)
            clock = runtime.clock
            states_channel = runtime.channel("servo-state")
            commands = runtime.channel("commands")
            goals = runtime.channel("goals").subscribe(FEEDER)
            legs = runtime.channel("legs").subscribe(FEEDER)
            loco = runtime.channel("locomotion").subscribe(FEEDER)
            cpu = time.thread_time_ns
            t0 = clock.now()
            cycle = 0
            activity = ""

            async def step(samples: Samples | None) -> None:
                nonlocal cycle, activity
                t = t0 + cycle * period
                msg = servos.states(t, cycle, period if cycle else 0.0)
                legs0, coord0 = legs_spent[0], coord_spent[0]
                start = cpu()
                await states_channel.send(msg)
                await clock.sleep_until(t + 0.5 * period)
                mid = cpu()
                idle_start = cpu()
                await clock.sleep_until(t + period)
                end = cpu()
                cycle += 1
                while not goals.empty():
                    goal: JointGoals = goals.get_nowait()
                    servos.take(goal)  # legs send the goals that changed; the rest stand
                rolling = any(servos.wheel_speed)
                answered = set()
                while not legs.empty():
                    leg_state: LegState = legs.get_nowait()
                    if leg_state.t == t:
                        answered.add(leg_state.leg)
                sent = len(answered)
                swinging = False
                while not loco.empty():
                    state: LocomotionState = loco.get_nowait()
                    activity = state.activity
                    swinging = bool(state.swing_legs)
                if samples is not None:
                    samples.window.append(mid - start)
                    samples.idle.append(end - idle_start)
                    samples.legs.append(legs_spent[0] - legs0)
                    samples.coordinator.append(coord_spent[0] - coord0)
                    samples.missing_goals += sent != N_LEGS
                    samples.swing_cycles += swinging
                    samples.rolling_cycles += rolling

            async def until(wanted: str, what: str) -> None:
                deadline = cycle + math.ceil(REACH_S * rate_hz)
                while activity != wanted:
                    if cycle >= deadline:
                        raise RuntimeError(
                            f"{what}: the coordinator did not reach {wanted!r} in {REACH_S:g} s "
                            f"of virtual time (activity {activity!r})"
                        )
                    await step(None)

            say("standing up (not measured)…")
            await until("standing", "stand-up")
            for engine in engines:
                say(f"{engine.label} at {SPEED_M_S:g} m/s: {cycles} cycles at {rate_hz:g} Hz…")
                await commands.send(engine.command)
                await until(engine.activity, engine.name)
                for _ in range(math.ceil(SETTLE_S * rate_hz)):
                    await step(None)
                samples = out[engine.name] = Samples()
                for _ in range(cycles):
                    await step(samples)
                    if activity != engine.activity:
                        samples.off_activity += 1
            runtime.request_stop("bench done")

    run_loop(main, virtual=True)
    return out


def figures(engine: Engine, runs: list[Samples], timed: Samples | None = None) -> EngineFigures:
    """Milliseconds per cycle of one engine from its runs (and its timed run).

    Median and p99 are the medians of the runs' own: a burst of load from
    another process that spoils one run does not move them.
    """
    medians: list[float] = []
    p99s: list[float] = []
    idles: list[float] = []
    pooled: list[float] = []
    for samples in runs:
        idle = statistics.median(samples.idle)
        net = [(w - idle) / 1e6 for w in samples.window]
        medians.append(statistics.median(net))
        p99s.append(percentile(net, 0.99))
        idles.append(idle / 1e6)
        pooled += net
    extra: dict[str, float] = {}
    if timed is not None:
        timed_idle = statistics.median(timed.idle)
        extra = {
            "legs_ms": statistics.median(timed.legs) / 1e6,
            "coordinator_ms": statistics.median(timed.coordinator) / 1e6,
            "window_ms": (statistics.median(timed.window) - timed_idle) / 1e6,
        }
    return EngineFigures(
        name=engine.name,
        label=engine.label,
        cycles=len(runs[0].window),
        runs=len(runs),
        median_ms=statistics.median(medians),
        p99_ms=statistics.median(p99s),
        mean_ms=statistics.fmean(pooled),
        max_ms=max(pooled),
        idle_ms=statistics.median(idles),
        run_medians_ms=tuple(medians),
        off_activity=sum(s.off_activity for s in runs),
        missing_goals=sum(s.missing_goals for s in runs),
        swing_cycles=sum(s.swing_cycles for s in runs),
        rolling_cycles=sum(s.rolling_cycles for s in runs),
        **extra,
    )


def run(
    progress: Progress = None,
    *,
    cycles: int = CYCLES,
    repeats: int = REPEATS,
    breakdown: bool = True,
) -> Report:
    """Measure every steady engine, ``cycles`` cycles in each of ``repeats`` runs;
    ``progress`` receives a line per step. ``breakdown`` adds a run with a stopwatch on
    every actor's tick."""
    say = progress or (lambda _line: None)
    say(f"six legs and the coordinator, virtual time, a perfect servo chain at {RATE_HZ:g} Hz")
    plain: list[dict[str, Samples]] = []
    for k in range(repeats):
        say(f"run {k + 1} of {repeats}…")
        plain.append(measure(cycles, say=say))
    timed: dict[str, Samples] = {}
    if breakdown:
        say("the same again with a stopwatch on every actor's tick (the breakdown)…")
        timed = measure(cycles, timed=True, say=say)
    results = [figures(e, [p[e.name] for p in plain], timed.get(e.name)) for e in ENGINES]
    walk = results[0]
    items = [
        Figure(
            "cpu_ms_per_cycle" if r.name == "walk" else f"{r.name}_cpu_ms_per_cycle",
            f"CPU per cycle, {r.label} (median)",
            r.median_ms,
            "ms",
            CYCLE_TARGET_MS,
        )
        for r in results
    ]
    notes = [
        f"{r.label}: p99 {r.p99_ms:.3f} ms, mean {r.mean_ms:.3f} ms, max {r.max_ms:.3f} ms; "
        f"runs' medians {', '.join(f'{m:.3f}' for m in r.run_medians_ms)} ms "
        f"({r.runs} × {r.cycles} cycles: {r.swing_cycles} with a leg in swing, "
        f"{r.rolling_cycles} with wheels turning)"
        for r in results
    ]
    for r in results:
        if r.legs_ms is not None and r.coordinator_ms is not None and r.window_ms is not None:
            rest = r.window_ms - r.legs_ms - r.coordinator_ms
            notes.append(
                f"{r.label}, where it goes (medians, timed run): six legs {r.legs_ms:.3f} ms, "
                f"coordinator {r.coordinator_ms:.3f} ms, the rest {rest:.3f} ms"
            )
    notes.append(
        f"thread CPU time from publishing the servo states until every actor waits, less "
        f"the bench's own wake-up ({walk.idle_ms * 1e3:.1f} µs, measured with the actors idle)"
    )
    notes.append(
        "CPU time grows with the load beside it (a busy process on a shared core can double "
        "it): runs' medians far apart mean the machine was busy"
    )
    notes.extend(
        f"{r.label}: {r.off_activity} cycles of another activity, "
        f"{r.missing_goals} without all six legs answering (the figures may not be what they say)"
        for r in results
        if r.off_activity or r.missing_goals
    )
    data: dict[str, Any] = {
        "cpu_ms_per_cycle": round(walk.median_ms, 4),
        "p99_ms": round(walk.p99_ms, 4),
        "target_ms": CYCLE_TARGET_MS,
        "rate_hz": RATE_HZ,
        "cycles": walk.cycles,
        "runs": walk.runs,
        "engines": {
            r.name: {k: _rounded(v) for k, v in vars(r).items() if k != "name" and v is not None}
            for r in results
        },
    }
    return Report("cycle", items, notes=notes, data=data)
