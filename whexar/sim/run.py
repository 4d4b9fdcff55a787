"""One simulated run: the full runtime driving the simulated WHexaR on virtual time.

Theory of operation
-------------------
:func:`simulate` builds the world (:mod:`whexar.sim.model` on a terrain) and
the three emulated devices it backs — the servo chain, the sensor board and
the IMU — registers them under a name of their own, and runs the robot's
actor graph against them: the bus scheduler (through dynamixel-sdk), the
sensor and IMU readers, the six legs, the coordinator. Only the two edges
are emulated; every actor is the one the robot runs. A scenario feeds the
commands at their times and samples the world every
:data:`SAMPLE_PERIOD_S` for the summary (path, tilt, electric power).

The robot starts seated on the ground with the torque off, as it is when
switched on: the bus scheduler finds the servos where the world put them,
and the coordinator stands the robot up from there.

A world whose physics diverges holds still (:class:`~whexar.sim.world.SimWorld`):
the scenario says so, a :class:`WorldDiverged` event, at its next sample and
stops the run there (the summary's ``stopped_by``).
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import json
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

import anyio

from whexar.actors.graph import robot_graph
from whexar.actors.messages import (
    AccelImplausible,
    AccelPlausible,
    GaitSelected,
    LocomotionChanged,
    MotionCommand,
    WorldDiverged,
    WorldFault,
)
from whexar.bus.emulator.chain import SERVO_CHAIN, ServoChain
from whexar.bus.emulator.faults import FaultInjector, load_fault_plan
from whexar.config import RobotConfig, load_config
from whexar.kinematics.body import Stance, quat_rpy, stance_feet
from whexar.kinematics.leg import ik
from whexar.robot import JOINT_NAMES, LEG_NAMES
from whexar.runtime.clock import monotonic
from whexar.runtime.devices import DEVICES
from whexar.runtime.harness import Harness, RunResult, run_actors
from whexar.runtime.messages import ActorReady, ActorStarting, Event
from whexar.sensors.board_emulator import SENSOR_BOARD, SensorBoardEmulator
from whexar.sensors.imu_emulator import I2C_BUS, FakeLsm9ds1, FakeSMBus
from whexar.sim.faults import (
    LimpFault,
    PushFault,
    SensorFault,
    SlipperyFault,
    WorldFaultSpec,
)
from whexar.sim.model import TIMESTEP_S, load_model
from whexar.sim.motors import DEFAULT_MOTORS, MotorSource
from whexar.sim.power import Supply
from whexar.sim.series import NoMessageLog, RunSeries
from whexar.sim.spread import Spread
from whexar.sim.spread import apply as apply_spread
from whexar.sim.terrain import Floor, Terrain
from whexar.sim.tilt import BoardTilt
from whexar.sim.world import Patch, SimWorld

if TYPE_CHECKING:
    from whexar.record.sidecar import AnyRecorder
    from whexar.record.writer import LiveSink, RecorderStats

Quiet = (ActorStarting, ActorReady, AccelImplausible, AccelPlausible)
"""Events too routine for the progress line."""
SAMPLE_PERIOD_S: Final = 0.05
"""How often the world is sampled for the summary and the plots."""
FALLEN_TILT_RAD: Final = math.radians(60.0)
"""A body tilted further than this has fallen."""
IMU_ADDRESS: Final = 0x6B
DEVICE_NAME: Final = "sim"
"""The name the run's servo chain, board and IMU bus are registered under."""
WORLD_SOURCE: Final = "world"
"""The ``source`` of the :class:`WorldFault` and :class:`WorldDiverged` events the run
says."""


@dataclass(frozen=True)
class Sample:
    """The world at one time: body centre (m), tilt (rad), electric power (W)."""

    t: float
    x: float
    y: float
    z: float
    roll: float
    pitch: float
    yaw: float
    power_w: float
    activity: str = ""
    """What the coordinator does (its latest :class:`LocomotionState`), gait or mode."""
    event: str = ""
    """The latest event of the run, as a short line (empty until there is one)."""
    supply_a: float = 0.0
    """The supply's current, A: its mean since the sample before (:mod:`whexar.sim.power`:
    the servos' bridges, their standby currents and the electronics; thesis Table 6.7)."""
    supply_v: float = 0.0
    """The supply's voltage at the servos, V."""

    @property
    def tilt(self) -> float:
        """The body's tilt (rad): the larger of |roll| and |pitch|."""
        return max(abs(self.roll), abs(self.pitch))


TRAVEL_STEP_S: Final = 1.0
"""The path is measured between points this far apart: a gait sways the body sideways and
back once a cycle, and that sway is not distance travelled."""


def energy_j(samples: Sequence[Sample]) -> float:
    """Electric energy (J) over the samples: their power integrated by the trapezoid rule."""
    return sum(0.5 * (a.power_w + b.power_w) * (b.t - a.t) for a, b in itertools.pairwise(samples))


MIN_PROGRESS_M: Final = 0.01
"""Less net progress than this over a run: no cost of transport (it went nowhere)."""


def travelled(samples: Sequence[Sample]) -> float:
    """Length (m) of the body centre's path, sampled every :data:`TRAVEL_STEP_S`.

    A path length, not progress: a robot that treads in place still sways a few cm a
    second, and that adds up (:func:`progress` is how far it got)."""
    if not samples:
        return 0.0
    points = [samples[0]]
    for s in samples[1:]:
        if s.t - points[-1].t >= TRAVEL_STEP_S - 1e-9:
            points.append(s)
    if points[-1] is not samples[-1]:
        points.append(samples[-1])
    return sum(math.hypot(b.x - a.x, b.y - a.y) for a, b in itertools.pairwise(points))


def progress(samples: Sequence[Sample]) -> float:
    """Net progress (m): the body centre's horizontal displacement from the first sample to
    the last, whatever the path between; 0 for no samples."""
    if not samples:
        return 0.0
    a, b = samples[0], samples[-1]
    return math.hypot(b.x - a.x, b.y - a.y)


def progress_along(samples: Sequence[Sample], heading_rad: float) -> float:
    """Net progress (m) along the direction ``heading_rad`` (yaw, from +x): the horizontal
    displacement from the first sample to the last projected on it; negative when the body
    ended behind where it started."""
    if not samples:
        return 0.0
    a, b = samples[0], samples[-1]
    return (b.x - a.x) * math.cos(heading_rad) + (b.y - a.y) * math.sin(heading_rad)


@dataclass
class SimResult:
    """What a run did: the samples, the compact series of its messages, the world at the end.

    ``run`` is the runtime's result; its message log is empty (reading it raises) unless
    the run was made with ``simulate(keep_log=True)``: :attr:`series` has what the summary,
    the report and the campaign metrics read."""

    samples: list[Sample]
    run: RunResult
    world: SimWorld
    wall_s: float
    duration_s: float
    mass_kg: float
    events: list[Event] = field(default_factory=list)
    recording: Path | None = None
    """The MCAP file the run was recorded into, if it was."""
    recorder_stats: RecorderStats | None = None
    """What the recorder did (its costs, what it dropped), if the run was recorded."""
    series: RunSeries = field(default_factory=RunSeries)
    """The run's messages as compact series (:mod:`whexar.sim.series`)."""
    heading_rad: float = 0.0
    """The course's direction: the body's heading (yaw) at the start, 0 = +x; what
    ``progress_along_m`` is measured along."""
    _summary: dict[str, Any] | None = field(default=None, init=False, repr=False, compare=False)

    def summary(self) -> dict[str, Any]:
        """The figures of ``whexar sim --json`` (worked out once: a campaign's metrics ask
        for several, and each pass walks the run's series and hashes the world).

        ``progress_m`` is the body's net displacement from start to end and
        ``progress_along_m`` its part along :attr:`heading_rad` (how far it got);
        ``distance_m`` is the length of its path, sway included (:func:`travelled`);
        ``mean_speed_mps`` and ``cost_of_transport`` divide by the progress, so that a robot
        treading in place is slow and costly, not flattered by its sway. ``sim_seconds`` is
        how long it ran, and ``stopped_by`` why it stopped before its duration (the battery
        reflex's shut-down), ``None`` when it ran its course."""
        if self._summary is None:
            self._summary = self._figures()
        return dict(self._summary)

    def _figures(self) -> dict[str, Any]:
        s = self.samples
        distance = travelled(s)
        net = progress(s)
        energy = energy_j(s)
        states = self.series.locomotion
        moving = [x for x in states if x.activity in ("walking", "riding", "hybrid")]
        moving_s = len(moving) * (states[1].t - states[0].t) if len(states) > 1 else 0.0
        margins = [x.margin_m for x in states if x.activity in ("walking", "standing", "hybrid")]
        changes = [e for e in self.events if isinstance(e, LocomotionChanged)]
        falls = 0
        fallen = False
        for x in s:
            tilted = x.tilt > FALLEN_TILT_RAD
            if tilted and not fallen:
                falls += 1
            fallen = tilted
        g = 9.81
        ran = min(self.duration_s, self.run.end_time)  # a reflex may end the run early
        return {
            "progress_m": net,
            "progress_along_m": progress_along(s, self.heading_rad),
            "distance_m": distance,
            "mean_speed_mps": net / moving_s if moving_s > 0 else 0.0,
            "energy_j": energy,
            "cost_of_transport": energy / (self.mass_kg * g * net)
            if net > MIN_PROGRESS_M
            else None,
            "min_stability_margin_m": min(margins) if margins else None,
            "gait_changes": sum(1 for c in changes if c.what == "gait"),
            "gait_selections": sum(1 for e in self.events if isinstance(e, GaitSelected)),
            "reflex_activations": sum(len(v) for v in self.series.reflex_intervals().values()),
            "falls": falls,
            "sim_seconds": ran,
            "stopped_by": self.run.stop_reason if ran < self.duration_s - 1e-6 else None,
            "wall_seconds": self.wall_s,
            "realtime_factor": ran / self.wall_s if self.wall_s > 0 else None,
            "state_hash": self.world.state_hash(),
            **self.world.supply_summary(),
        }


def seated_angles(cfg: RobotConfig) -> dict[tuple[int, int], float]:
    """Joint angles of the seated pose: the stance's reach, the coxa joints at sit height."""
    stance = cfg.stance(cfg.locomotion.stance)
    seated = Stance(stance.reach, cfg.locomotion.sit_height_mm / 1000, stance.front_rear_yaw)
    angles = ik(stance_feet(seated), cfg.leg_geometry(), target="contact").angles
    return {(leg, j): float(angles[leg, j]) for leg in range(len(LEG_NAMES)) for j in range(5)}


def sim_graph(name: str, *, config: str | None = None) -> dict[str, Any]:
    """The robot's actor graph (:func:`~whexar.actors.graph.robot_graph`) on the devices
    registered as ``name``, the commands fed by the scenario.

    ``config`` is the robot configuration file every actor reads (default: the built-in).
    A bus fault plan acts on the registered chain (:func:`simulate` attaches it), not on
    the bus scheduler."""
    return robot_graph(
        bus=f"emulator:{name}",
        sensors=f"emulator:{name}",
        imu=f"fake:{name}",
        config=config,
        feeds=["commands"],
    )


def simulate(
    *,
    terrain: Terrain | None = None,
    commands: Sequence[tuple[float, MotionCommand]] = (),
    duration: float,
    config: str | Path | None = None,
    faults: str | Path | None = None,
    start: tuple[float, float, float] = (0.0, 0.0, 0.0),
    on_sample: Callable[[Sample, SimWorld], None] | None = None,
    timestep: float = TIMESTEP_S,
    sensor_faults: Sequence[SensorFault] = (),
    record: str | Path | None = None,
    record_metadata: Mapping[str, str] | None = None,
    live: LiveSink | None = None,
    tilt: BoardTilt | None = None,
    keep_log: bool = False,
    supply: Supply | None = None,
    motor_source: MotorSource = DEFAULT_MOTORS,
    spread: int | None = None,
    world_faults: Sequence[WorldFaultSpec] = (),
) -> SimResult:
    """Run the robot for ``duration`` s of simulated time; see the module docstring.

    ``config`` is the robot configuration file (the world and every actor read it);
    ``faults`` a bus fault plan and ``sensor_faults`` the sensors' (:mod:`whexar.sim.faults`);
    ``start`` is (x, y, yaw) of the body on the ground; ``on_sample`` is called with every
    sample (progress lines, video frames); ``tilt`` raises the board the robot is on
    (:mod:`whexar.sim.tilt`).

    ``supply`` feeds the servos (:mod:`whexar.sim.power`; default: the 12 V bench supply)
    and ``motor_source`` picks their motors (:func:`whexar.sim.motors.motors`).

    ``record`` is an MCAP file to record the run into (:mod:`whexar.record`): every
    message, the bytes of the servo bus and the sensor link, the body's pose on ``/tf``,
    the configuration, the wiring and the URDF; ``record_metadata`` goes into its
    ``run`` metadata (a scenario's name, the command line). ``live`` (a live view,
    :class:`whexar.record.live.LiveView`) gets everything the recorder writes; with no
    ``record`` it then records to nowhere.

    The result keeps compact series of the messages (:class:`~whexar.sim.series.RunSeries`),
    so a run's memory does not grow with every message; ``keep_log=True`` keeps every
    message in ``result.run.log`` too (tests that look at messages).
    ``spread`` is the seed of the robot's parts (:mod:`whexar.sim.spread`); ``None``: the
    perfect world. ``world_faults`` are the world's physical faults (:mod:`whexar.sim.faults`):
    each begins and ends at its time on the runtime's clock, said by a :class:`WorldFault`
    event.
    """
    cfg = load_config(config) if config else RobotConfig()
    model = load_model(cfg, terrain=terrain, timestep=timestep)
    chain = ServoChain.for_models(cfg.servos(), baudrate=cfg.bus.baudrate)
    board = SensorBoardEmulator(
        frame_rate_hz=cfg.sensor_board.frame_rate_hz, baudrate=cfg.sensor_board.baudrate
    )
    if faults is not None:  # the chain is the run's: its faults are attached here
        FaultInjector(load_fault_plan(faults)).attach(chain)
    chip = FakeLsm9ds1()
    i2c = FakeSMBus(cfg.imu.i2c_bus)
    i2c.attach(cfg.imu.address, chip)
    world = SimWorld(
        model,
        chain,
        cfg=cfg,
        board=board,
        imu=chip,
        supply=supply,
        motor_source=motor_source,
        tilt=tilt,
    )
    if spread is not None:
        apply_spread(Spread.draw(spread, model, len(world.joints)), world)
    x0, y0, yaw0 = start
    seat = cfg.locomotion.sit_height_mm / 1000 + 0.002
    # Seated on the ground where the start is: parallel to a slope, turned by the yaw.
    (bx, by, bz), (qw, qx, qy, qz) = (terrain.ground if terrain else Floor()).start_pose(seat)
    cy, sy = math.cos(yaw0 / 2), math.sin(yaw0 / 2)
    world.set_pose(
        seated_angles(cfg),
        base_xyz=(bx + x0, by + y0, bz),
        # q_yaw ⊗ q_floor: the floor's tilt, then the turn about the world's vertical.
        base_quat=(cy * qw - sy * qz, cy * qx - sy * qy, cy * qy + sy * qx, cy * qz + sy * qw),
    )
    name = DEVICE_NAME  # one run per process at a time; the same name keeps logs comparable
    samples: list[Sample] = []
    series = RunSeries(quiet=Quiet)

    last_draw = [0.0, 0.0]  # the supply's charge drawn (C) and the time, at the last sample

    def sample() -> None:
        roll, pitch, yaw = quat_rpy(*world.base_quat)
        x, y, z = world.base_position
        # The supply current since the sample before (none before the first: the latest).
        drawn, span = world.supply.drawn_c, world.time - last_draw[1]
        supply_a = (drawn - last_draw[0]) / span if span > 0 else world.supply_a
        last_draw[:] = drawn, world.time
        s = Sample(
            world.time,
            x,
            y,
            z,
            roll,
            pitch,
            yaw,
            world.electric_power(),
            series.latest_activity,
            series.latest_event,
            supply_a=supply_a,
            supply_v=world.supply.terminal_volts,
        )
        samples.append(s)
        if on_sample is not None:
            on_sample(s, world)

    def fault(f: SensorFault, *, ending: bool = False) -> None:
        if f.kind == "unplug":
            if f.device == "board":
                board.replug() if ending else board.unplug()
            else:
                chip.replug() if ending else chip.unplug()
        elif f.kind == "freeze":
            chip.thaw() if ending else chip.freeze()
        elif f.kind == "corrupt":
            board.corrupt(f.frames)
        elif f.kind == "drop":
            board.drop(f.frames)
        elif f.kind == "dead_fsr":
            world.dead_fsr.add(f.leg)
        else:
            world.dead_ir.add(f.sensor)

    timeline = sorted(
        [(f.at_s, f, False) for f in sensor_faults]
        + [
            (f.at_s + f.duration_s, f, True)
            for f in sensor_faults
            if f.kind in ("unplug", "freeze") and f.duration_s > 0
        ],
        key=lambda e: e[0],
    )

    changes = _world_timeline(world_faults)

    def world_fault(h: Harness, k: int, f: WorldFaultSpec, ending: bool) -> None:
        _apply_world_fault(world, cfg, k, f, ending, h.now())
        target, detail = f.describe(cfg)
        h.runtime.emit(
            WorldFault(
                t=h.now(),
                source=WORLD_SOURCE,
                kind=f.kind,
                target=target,
                detail=detail,
                active=not ending,
            )
        )

    async def world_until(h: Harness, t: float) -> None:
        """The world's faults due up to ``t``, each at its own time (not the samples')."""
        while changes and changes[0][0] <= t + 1e-9:
            at, k, f, ending = changes.pop(0)
            if at > h.now():
                await h.sleep_until(at)
            world_fault(h, k, f, ending)

    async def scenario(h: Harness) -> None:
        if recorder is None:
            await timeline_and_samples(h)
            return
        async with anyio.create_task_group() as tg:
            # The recorder writes as on the robot: between cycles, a bounded time at once.
            tg.start_soon(functools.partial(recorder.run, h.sleep, runtime=h.runtime))
            await timeline_and_samples(h)

    async def timeline_and_samples(h: Harness) -> None:
        pending = sorted(commands, key=lambda c: c[0])
        k = j = 0
        t = 0.0
        await world_until(h, t)
        while True:
            while k < len(pending) and pending[k][0] <= t + 1e-9:
                cmd = pending[k][1]
                now = h.now()
                # Stamped when it is published: a replay feeds it again at that time.
                await h.feed("commands", cmd if cmd.t == now else dataclasses.replace(cmd, t=now))
                k += 1
            while j < len(timeline) and timeline[j][0] <= t + 1e-9:
                fault(timeline[j][1], ending=timeline[j][2])
                j += 1
            sample()
            if recorder is not None:  # the body's pose, for Foxglove's 3D panel
                x, y, z = world.base_position
                qw, qx, qy, qz = world.base_quat
                recorder.transform(h.now(), "world", "base", (x, y, z), (qx, qy, qz, qw))
            if world.diverged_at is not None and not h.runtime.stopping:  # said once
                said = f"{world.divergence} (at {world.diverged_at:.3f} s)"
                h.runtime.emit(WorldDiverged(t=h.now(), source=WORLD_SOURCE, detail=said))
                h.runtime.request_stop(f"the simulated physics diverged: {said}")
            t += SAMPLE_PERIOD_S
            await world_until(h, t)
            await h.sleep_until(t)

    graph = sim_graph(name, config=str(config) if config else None)
    if record is None and live is not None:
        record = os.devnull  # the live view is fed by the recorder
    metadata = {"duration_s": repr(float(duration)), **(record_metadata or {})}
    recorder = _recorder(record, cfg, config, graph, metadata, live) if record else None
    observers = (series,) if recorder is None else (series, recorder)
    wall = monotonic()  # the real-time factor's denominator
    with (
        DEVICES.registered(SERVO_CHAIN, name, chain),
        DEVICES.registered(SENSOR_BOARD, name, board),
        DEVICES.registered(I2C_BUS, name, i2c),
    ):
        try:
            result = run_actors(
                graph,
                duration=duration,
                scenario=scenario,
                feeds=["commands"],
                observers=observers,
                link_observer=None if recorder is None else recorder.link_bytes,
                keep_log=keep_log,
            )
        finally:
            if recorder is not None:
                recorder.close()
    if not keep_log:  # reading an empty log would answer wrong, not fail
        result = dataclasses.replace(result, log=NoMessageLog())
    events = series.events
    if recorder is not None:  # what the budget did after the runtime's last look at it
        seen = {id(e) for e in events}
        events = [*events, *(e for e in recorder.events if id(e) not in seen)]
    return SimResult(
        samples=samples,
        run=result,
        world=world,
        wall_s=monotonic() - wall,
        duration_s=duration,
        mass_kg=cfg.robot.mass_kg,
        events=events,
        recording=None if recorder is None else recorder.path,
        recorder_stats=None if recorder is None else recorder.stats,
        series=series,
        heading_rad=yaw0,
    )


def _world_timeline(
    faults: Sequence[WorldFaultSpec],
) -> list[tuple[float, int, WorldFaultSpec, bool]]:
    """(time, index, fault, ending) of every beginning and end, in time order (at one
    time, ends before beginnings, each in the order of the file)."""
    out = [(f.at_s, k, f, False) for k, f in enumerate(faults)]
    out += [(end, k, f, True) for k, f in enumerate(faults) if (end := f.ends_at) is not None]
    return sorted(out, key=lambda e: (e[0], not e[3], e[1]))


def _apply_world_fault(
    world: SimWorld, cfg: RobotConfig, key: int, f: WorldFaultSpec, ending: bool, t: float
) -> None:
    """Begin (or end) fault ``key`` of the run's physical faults in ``world`` at ``t``."""
    if isinstance(f, PushFault):
        world.push(key, None if ending else f.force())
    elif isinstance(f, SlipperyFault):
        patch = Patch(f.friction, f.leg, f.x_m, f.y_m)
        world.slip(key, None if ending else patch)
    elif isinstance(f, LimpFault):
        world.limp(key, None if ending else f.servo_ids(cfg), t)
    else:
        joint = world.by_servo[cfg.legs[f.leg].servo_ids[JOINT_NAMES.index(f.joint)]].index
        world.snag(key, None if ending else joint)


def _recorder(
    path: str | Path,
    cfg: RobotConfig,
    config: str | Path | None,
    graph: Mapping[str, Any],
    metadata: Mapping[str, str] | None,
    live: LiveSink | None = None,
) -> AnyRecorder:
    """The recorder of a simulated run: its wiring and URDF attached too."""
    from whexar.record.runs import run_recorder
    from whexar.sim.urdf import build_urdf

    return run_recorder(
        path,
        cfg,
        config,
        {"wiring.json": json.dumps(graph, indent=1)},
        {"robot": cfg.robot.name, "kind": "simulation", "clock": "virtual", **(metadata or {})},
        live,
        urdf=build_urdf(cfg),
    )


__all__ = [
    "SAMPLE_PERIOD_S",
    "Sample",
    "SimResult",
    "energy_j",
    "progress",
    "progress_along",
    "seated_angles",
    "sim_graph",
    "simulate",
    "travelled",
]
