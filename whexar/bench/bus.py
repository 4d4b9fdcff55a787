"""``whexar bench bus``: the servo bus against the emulator's bus limit for each read plan.

What each figure runs (42 servos, 1 Mbps, Return Delay Time 20 µs):

* **hz** — the whole runtime (a :class:`~whexar.actors.bus.BusScheduler` and
  a :class:`~whexar.actors.bus.GoalWiggle` that changes all 42 goals every
  cycle) on virtual time against the in-process emulator, through the real
  dynamixel-sdk; cycles per second of runtime time.
* **limit_hz** — the same cycle costed by the emulator's timing model alone:
  the plan's reads, then the Sync Writes of 36 positions and 6 wheel speeds,
  with the slow round-robin reads spread at their rates. No scheduler can
  beat it on this bus.
* **cpu_ms_per_cycle** — the same graph on *real* time with the in-process
  emulator: process CPU time per cycle minus the time spent inside the
  emulator, so it is the bus path (scheduler, SDK codec, conversions) plus
  the runtime's message passing and the goal source.
* **realtime** — ``full_feedback`` and ``positioning`` on real time over a
  pseudo-terminal, against ``whexar emulate`` in another process waiting out
  each transaction's wire time: the path a U2D2 takes, with the emulator
  standing in for the servos. Each plan runs five ways, one after the other:

  - ``native`` — the runtime, the cycle's transactions on the compiled path
    (:mod:`whexar.bus.wire`);
  - ``sdk`` — the runtime, dynamixel-sdk's path for everything;
  - ``loop`` / ``loop_sdk`` — whexar's bus path alone, compiled or the SDK's: a
    plain loop of the plan's reads with the goals riding on them, no runtime;
  - ``baseline`` — the same cycle as a plain dynamixel-sdk loop
    (``GroupSyncRead`` then ``GroupSyncWrite``, as users write it): the
    runtime must not be slower than that.
* **realtime_cpu_ms_per_cycle** — in those runs, the process's CPU time (all
  threads) per cycle: what is left of a Raspberry Pi's cores. When no cycle
  came through after the warm-up (``realtime_hz`` 0), it is infinite:
  ``null`` in ``--json``.
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import signal
import statistics
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, ClassVar, TypeVar

from whexar.actors.bus import BusScheduler
from whexar.actors.graph import GRAPH_DIR, robot_graph
from whexar.actors.messages import ServoStates
from whexar.bench import Figure, Progress, Report
from whexar.bus.control_table import Block, block
from whexar.bus.emulator.chain import SERVO_CHAIN, ServoChain
from whexar.bus.emulator.timing import TimingModel
from whexar.bus.plan import PRESETS, ReadPlan
from whexar.bus.protocol import sync_read_bytes, sync_write_bytes
from whexar.bus.sdk import DxlBus, PortOwner, open_port
from whexar.config import RobotConfig
from whexar.robot import JOINT_NAMES, LEG_NAMES
from whexar.runtime.clock import run as run_loop
from whexar.runtime.devices import DEVICES
from whexar.runtime.harness import run_actors
from whexar.runtime.supervisor import Runtime
from whexar.runtime.wiring import build_graph

PLANS = ("thesis", "full_feedback", "fast_full_feedback", "positioning", "default")
SHARE_OF_LIMIT = 0.95
"""Target: the virtual-time cycle rate reaches 95 % of the bus limit."""
REALTIME_SHARE = 0.99
"""Target: on real time over a pty, the compiled path reaches 99 % of the bus limit."""
REALTIME_PLANS = ("full_feedback", "positioning")
REALTIME_CPU_TARGET_MS = {"full_feedback": 0.6, "positioning": 0.5}
"""Target: the process's CPU per real-time cycle (all threads), on the compiled path."""
FULL_FEEDBACK_HZ = 64.0
"""Target: the thesis's position + current reading ran at 47–48 Hz (6.1.1, 6.1.4)."""
POSITIONING_HZ = 110.0
"""Target: the thesis's trimmed main loop ran at 80 Hz (6.1.4)."""
CPU_TARGET_MS = 1.5
T = TypeVar("T")


@dataclass(frozen=True)
class PlanFigures:
    name: str
    hz: float
    limit_hz: float
    bytes_per_cycle: float
    realtime: dict[str, Realtime] = field(default_factory=dict)
    """Real-time runs by :data:`REALTIME_PATHS`."""


def plan_limit(
    plan: ReadPlan, cfg: RobotConfig, timing: TimingModel, *, write_bytes: float | None = None
) -> tuple[float, float]:
    """(cycles/s, bytes per cycle) of ``plan`` on a bus that does nothing else.

    Each cycle writes every goal (36 positions, 6 wheel speeds), unless ``write_bytes``
    says how many bytes of Sync Write a cycle sends on average: the scheduler writes only
    the goals that changed (a Sync Write is pure wire time).
    """
    rdt = cfg.bus.return_delay_time_us * 1e-6
    fast = plan.fast_sync_read == "on"
    n_servos = len(LEG_NAMES) * len(JOINT_NAMES)
    wheels = len(LEG_NAMES)
    if write_bytes is None:
        write_bytes = sync_write_bytes(n_servos - wheels, 4) + sync_write_bytes(wheels, 4)
    base = write_bytes * timing.bits_per_byte / timing.baudrate
    nbytes = float(write_bytes)
    busy_per_s = 0.0
    slow_bytes_per_s = 0.0
    for read in plan.reads:
        n = len(read.joints) * len(read.legs)
        length = block(read.registers).length
        if read.rate_hz is None:
            base += timing.sync_read_s(n, length, rdt, fast)
            nbytes += sum(sync_read_bytes(n, length, fast=fast))
        else:
            k = min(n, read.chunk or n)
            busy_per_s += read.rate_hz * timing.sync_read_s(k, length, rdt, fast)
            slow_bytes_per_s += read.rate_hz * sum(sync_read_bytes(k, length, fast=fast))
    # Slow reads take their share of every second; the cycles share the rest.
    hz = (1.0 - busy_per_s) / base
    return hz, nbytes + slow_bytes_per_s / hz


def _graph(port: str, plan: str, *, native: bool = True) -> dict[str, Any]:
    """``config/graphs/bus.toml`` (the scheduler and a goal source that sways every
    joint) on ``port`` with read plan ``plan``, without its logging sinks; ``native``: the
    scheduler's parameter of that name."""
    return robot_graph(
        path=GRAPH_DIR / "bus.toml",
        bus=port,
        params={"bus": {"plan": plan, "native": native}},
        leave_out=("health-log", "stats-log"),
    )


def servo_chain(cfg: RobotConfig, **options: Any) -> ServoChain:
    """The emulated servos of ``cfg`` at its bus's baud rate."""
    return ServoChain.for_models(cfg.servos(), baudrate=cfg.bus.baudrate, **options)


def _rate(states: list[ServoStates], skip_s: float = 0.2) -> float:
    """Cycles per second of runtime time, after the first ``skip_s`` (start-up)."""
    kept = [s for s in states if s.t >= states[0].t + skip_s]
    if len(kept) < 2:
        return 0.0
    return (len(kept) - 1) / (kept[-1].t - kept[0].t)


def virtual_rate(plan: str, cfg: RobotConfig, seconds: float = 3.0) -> float:
    """Cycles/s of ``plan`` on virtual time against a fresh in-process emulator."""
    chain = servo_chain(cfg, fast_sync_read=PRESETS[plan].fast_sync_read == "on")
    DEVICES.register(SERVO_CHAIN, "bench", chain)
    try:
        result = run_actors(_graph("emulator:bench", plan), duration=seconds)
    finally:
        DEVICES.unregister(SERVO_CHAIN, "bench")
    return _rate(result.messages("state", of=ServoStates))


class _TimedOwner:
    """Wraps the scheduler's port owner: wall time spent waiting out bus time, per call."""

    def __init__(self, inner: PortOwner, waited: list[float]) -> None:
        self._inner = inner
        self._waited = waited

    async def call(self, job: Callable[[DxlBus], T]) -> T:
        box: list[float] = []

        def timed(bus: DxlBus) -> T:
            try:
                return job(bus)
            finally:
                box.append(time.perf_counter())

        try:
            return await self._inner.call(timed)
        finally:
            if box:  # from the job's end to now: the sleep of its bus time (and other tasks)
                self._waited[0] += time.perf_counter() - box[0]

    def close(self) -> None:
        self._inner.close()


class TimedBusScheduler(BusScheduler):
    """The scheduler with a stopwatch on its cycles: wall time less waits, per cycle."""

    busy: ClassVar[list[float]] = [0.0]
    waited: ClassVar[list[float]] = [0.0]
    inside: ClassVar[list[float]] = [0.0]
    """Time spent inside the emulator (the bench's timed ``transact`` adds to it)."""
    cycles: ClassVar[list[int]] = [0]

    def _open_owner(self) -> PortOwner:
        return _TimedOwner(super()._open_owner(), self.waited)

    async def _cycle(self, owner: PortOwner) -> None:
        start, waited, inside = time.perf_counter(), self.waited[0], self.inside[0]
        await super()._cycle(owner)
        elapsed = time.perf_counter() - start
        self.busy[0] += elapsed - (self.waited[0] - waited) - (self.inside[0] - inside)
        self.cycles[0] += 1


def cpu_per_cycle_ms(plan: str, cfg: RobotConfig, seconds: float = 2.0) -> float:
    """Real-time ms of the bus path per cycle: the scheduler's cycle, less its waits and the
    time spent inside the in-process emulator."""
    chain = servo_chain(cfg)
    inside = TimedBusScheduler.inside
    transact = chain.transact

    def timed(request: bytes, t: float) -> Any:
        start = time.perf_counter()
        try:
            return transact(request, t)
        finally:
            inside[0] += time.perf_counter() - start

    chain.transact = timed  # type: ignore[method-assign]
    DEVICES.register(SERVO_CHAIN, "bench", chain)
    TimedBusScheduler.busy[0] = 0.0
    TimedBusScheduler.cycles[0] = 0
    graph = _graph("emulator:bench", plan)
    graph["actors"][0]["class"] = "whexar.bench.bus:TimedBusScheduler"

    async def main() -> None:
        # No message log: a log keeping every message grows the heap, and the
        # garbage collector's passes over it would be billed to the cycles.
        await Runtime(build_graph(graph)).run(duration=seconds)

    try:
        run_loop(main)
    finally:
        DEVICES.unregister(SERVO_CHAIN, "bench")
    t = TimedBusScheduler
    return t.busy[0] / max(1, t.cycles[0]) * 1e3


@contextlib.contextmanager
def emulator_process() -> Iterator[str]:
    """``whexar emulate`` in real-time mode in another process; yields its pty path."""
    with emulators_process(board=False) as ptys:
        yield ptys[0]


@contextlib.contextmanager
def emulators_process(*, board: bool = True) -> Iterator[tuple[str, str | None]]:
    """``whexar emulate [--board]`` in real-time mode in another process; yields the servo
    pty and the sensor board's (``None`` without ``board``)."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "whexar.cli", "emulate", *(["--board"] if board else [])],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        ptys: list[str] = []
        for _ in range(2 if board else 1):
            line = proc.stdout.readline()
            found = re.search(r" on (/dev/\S+)", line)
            if not found:
                err = proc.stderr.read() if proc.stderr else ""
                raise RuntimeError(f"whexar emulate did not print its pty: {line!r} {err}")
            ptys.append(found.group(1))
        yield ptys[0], (ptys[1] if board else None)
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()


@dataclass(frozen=True)
class Realtime:
    """One real-time run over a pty: cycles per second and process CPU per cycle."""

    hz: float
    cpu_ms: float
    port_thread_ms: float | None = None
    """Of ``cpu_ms``, the share of the thread that owns the port (the bus's transactions);
    the rest is the event loop's (the runtime, the scheduler, the goal source)."""


def realtime_run(
    plan: str, seconds: float = 3.0, warm_s: float = 0.5, *, native: bool = True
) -> Realtime:
    """``plan`` on real time through the SDK over a pty to ``whexar emulate``; ``native``:
    the cycle's transactions on the compiled path (:mod:`whexar.bus.wire`), else the SDK's.

    CPU is the runtime process's CPU time, all threads, per cycle, over the cycles after
    ``warm_s``; the messages are counted by an observer, not logged (a log's garbage
    collection would be billed to the cycles).
    """
    marks: list[tuple[float, float]] = []
    port_cpu: list[float] = []
    clock: list[int] = []

    def observe(channel: str, msg: object) -> None:
        if channel == "state":
            marks.append((time.perf_counter(), time.process_time()))
            if not clock:
                clock.extend(_port_thread_clock())
            port_cpu.append(time.clock_gettime(clock[0]) if clock else math.nan)

    async def main() -> None:
        graph = _graph(path, plan, native=native)
        runtime = Runtime(build_graph(graph), observer=observe)
        await runtime.run(duration=seconds + warm_s)

    with emulator_process() as path:
        run_loop(main)
    start = next((k for k, m in enumerate(marks) if m[0] >= marks[0][0] + warm_s), len(marks))
    out = _per_cycle(marks[start:])
    if len(marks) - start < 2 or not clock:
        return out
    port_ms = (port_cpu[-1] - port_cpu[start]) / (len(marks) - start - 1) * 1e3
    return Realtime(out.hz, out.cpu_ms, port_ms)


def _port_thread_clock() -> list[int]:
    """The CPU clock of the thread that owns the servo port, when there is one."""
    for thread in threading.enumerate():
        if thread.name == "servo-port" and thread.ident is not None:
            return [time.pthread_getcpuclockid(thread.ident)]
    return []


def _per_cycle(marks: list[tuple[float, float]]) -> Realtime:
    """Cycles per second and CPU ms per cycle from (wall, CPU) marks, one per cycle."""
    if len(marks) < 2:
        return Realtime(0.0, math.inf)
    (t0, c0), (t1, c1) = marks[0], marks[-1]
    cycles = len(marks) - 1
    return Realtime(cycles / (t1 - t0), (c1 - c0) / cycles * 1e3)


@dataclass(frozen=True)
class _Cycle:
    """A plan's every-cycle reads (register span, servo IDs) and the goals it writes."""

    reads: list[tuple[Block, list[int]]]
    positions: list[int]
    wheels: list[int]


def _cycle(plan: str) -> _Cycle:
    cfg = RobotConfig()
    wheel = JOINT_NAMES.index("wheel")
    reads = []
    for read in PRESETS[plan].reads:
        if read.rate_hz is not None:
            continue
        ids = [
            sid
            for leg in cfg.legs
            if leg.name in read.legs
            for j, sid in enumerate(leg.servo_ids)
            if JOINT_NAMES[j] in read.joints
        ]
        reads.append((block(read.registers), ids))
    return _Cycle(
        reads,
        [sid for leg in cfg.legs for j, sid in enumerate(leg.servo_ids) if j != wheel],
        [leg.servo_ids[wheel] for leg in cfg.legs],
    )


def bus_loop(plan: str, seconds: float = 3.0, *, native: bool = True) -> Realtime:
    """The bus path alone: ``plan``'s cycle as a plain loop through whexar's
    :class:`~whexar.bus.sdk.DxlBus` over a pty to ``whexar emulate`` — the reads, the 36
    positions and 6 wheel speeds riding on the last one — with no runtime around it: what
    the compiled path (``native``) costs against the SDK's own, like for like."""
    cycle = _cycle(plan)
    marks: list[tuple[float, float]] = []
    with emulator_process() as path:
        port = open_port(path, RobotConfig().bus.baudrate)
        try:
            bus = DxlBus(port, native=native)
            start = time.perf_counter()
            n = 0
            while (now := time.perf_counter()) - start < seconds + 0.5:
                if now - start >= 0.5:  # the warm-up, as the runtime's
                    marks.append((now, time.process_time()))
                goal = (2048 + n % 64).to_bytes(4, "little")
                goals = [
                    bus.prepare_sync_write(116, 4, dict.fromkeys(cycle.positions, goal)),
                    bus.prepare_sync_write(104, 4, dict.fromkeys(cycle.wheels, b"\x28\0\0\0")),
                ]
                for k, (span, ids) in enumerate(cycle.reads):
                    last = k == len(cycle.reads) - 1
                    bus.sync_read(ids, span.start, span.length, then=goals if last else ())
                n += 1
        finally:
            port.closePort()
    return _per_cycle(marks)


def baseline_rate(plan: str, seconds: float = 3.0) -> Realtime:
    """Cycles/s and CPU ms per cycle of a plain dynamixel-sdk loop doing ``plan``'s cycle on
    the same kind of pty.

    As users write it: the SDK's own ``PortHandler`` and, per cycle, a
    ``GroupSyncRead.txRxPacket()`` of each every-cycle read of the plan, then a
    ``GroupSyncWrite`` of 36 goal positions and one of 6 wheel speeds.
    """
    import dynamixel_sdk as dxl

    cfg = RobotConfig()
    cycle = _cycle(plan)
    with emulator_process() as path:
        port = dxl.PortHandler(path)
        port.openPort()
        port.setBaudRate(cfg.bus.baudrate)
        ph = dxl.PacketHandler(2.0)
        reads = []
        for span, ids in cycle.reads:
            group = dxl.GroupSyncRead(port, ph, span.start, span.length)
            for sid in ids:
                group.addParam(sid)
            reads.append(group)
        cycles = 0
        start, cpu = time.perf_counter(), time.process_time()
        try:
            while time.perf_counter() - start < seconds:
                for group in reads:
                    group.txRxPacket()
                goals = dxl.GroupSyncWrite(port, ph, 116, 4)
                for sid in cycle.positions:
                    goals.addParam(sid, list((2048 + cycles % 64).to_bytes(4, "little")))
                goals.txPacket()
                speeds = dxl.GroupSyncWrite(port, ph, 104, 4)
                for sid in cycle.wheels:
                    speeds.addParam(sid, list((40).to_bytes(4, "little")))
                speeds.txPacket()
                cycles += 1
            elapsed = time.perf_counter() - start
            return Realtime(cycles / elapsed, (time.process_time() - cpu) / max(1, cycles) * 1e3)
        finally:
            port.closePort()


def run(progress: Progress = None, *, seconds: float = 3.0) -> Report:
    """Measure every plan; ``progress`` receives a line per step."""
    say = progress or (lambda _line: None)
    cfg = RobotConfig()
    timing = TimingModel(baudrate=cfg.bus.baudrate)
    plans: list[PlanFigures] = []
    for name in PLANS:
        say(f"plan {name}: {seconds:g} s of virtual time against the emulator…")
        limit, nbytes = plan_limit(PRESETS[name], cfg, timing)
        hz = virtual_rate(name, cfg, seconds)
        realtime: dict[str, Realtime] = {}
        if name in REALTIME_PLANS and os.name == "posix":
            for path, what, measure in (
                ("native", "the runtime, compiled path", realtime_run),
                ("sdk", "the runtime, dynamixel-sdk's path", _sdk_realtime_run),
                ("loop", "the bus path alone, compiled", bus_loop),
                ("loop_sdk", "the bus path alone, dynamixel-sdk's", _sdk_bus_loop),
                ("baseline", "a plain dynamixel-sdk loop", baseline_rate),
            ):
                say(f"plan {name}: {what}, {seconds:g} s of real time over a pty…")
                realtime[path] = measure(name, seconds)
        plans.append(PlanFigures(name, hz, limit, nbytes, realtime))
    cpu: dict[str, float] = {}
    for name in ("full_feedback", "positioning"):
        say(f"plan {name}: CPU per cycle on real time, in-process emulator (3 runs)…")
        cpu[name] = statistics.median(cpu_per_cycle_ms(name, cfg) for _ in range(3))
    items: list[Figure] = []
    for p in plans:
        items.append(
            Figure(
                f"{p.name}_hz",
                f"{p.name} (limit {p.limit_hz:.1f} Hz)",
                p.hz,
                "Hz",
                SHARE_OF_LIMIT * p.limit_hz,
                at_least=True,
            )
        )
        items.extend(_realtime_figures(p))
    by_name = {p.name: p for p in plans}
    items.append(
        Figure(
            "full_feedback_target_hz",
            "full_feedback vs the thesis's 48 Hz",
            by_name["full_feedback"].hz,
            "Hz",
            FULL_FEEDBACK_HZ,
            at_least=True,
        )
    )
    items.append(
        Figure(
            "positioning_target_hz",
            "positioning vs the thesis's 80 Hz",
            by_name["positioning"].hz,
            "Hz",
            POSITIONING_HZ,
            at_least=True,
        )
    )
    items.append(
        Figure(
            "full_feedback_cpu_ms",
            "CPU per full_feedback cycle (median of 3 runs)",
            cpu["full_feedback"],
            "ms",
            CPU_TARGET_MS,
        )
    )
    data = {
        "plans": [
            {
                "name": p.name,
                "hz": round(p.hz, 2),
                "limit_hz": round(p.limit_hz, 2),
                "bytes_per_cycle": round(p.bytes_per_cycle, 1),
                **{f"{path}_realtime_hz": round(r.hz, 2) for path, r in p.realtime.items()},
            }
            for p in plans
        ],
        "cpu_ms_per_cycle": {k: round(v, 3) for k, v in cpu.items()},
        "realtime_cpu_ms_per_cycle": {
            path: {p.name: _ms(p.realtime[path].cpu_ms) for p in plans if path in p.realtime}
            for path in REALTIME_PATHS
            if any(path in p.realtime for p in plans)
        },
        "realtime_port_thread_ms_per_cycle": {
            path: {
                p.name: _ms(r.port_thread_ms)
                for p in plans
                if (r := p.realtime.get(path)) is not None and r.port_thread_ms is not None
            }
            for path in ("native", "sdk")
        },
    }
    return Report(
        "bus",
        items,
        notes=[
            "hz: virtual time, whole runtime, real SDK, in-process emulator; "
            "limit_hz: the emulator's timing model for the same cycle",
            "real time over a pty to `whexar emulate`: native / sdk, the runtime with the "
            "cycle's transactions compiled or dynamixel-sdk's; loop / loop_sdk, whexar's bus "
            "path alone (no runtime); baseline, a plain dynamixel-sdk loop as users write it",
            *_split_notes(plans),
        ],
        data=data,
    )


def _split_notes(plans: list[PlanFigures]) -> list[str]:
    """A line per real-time run of the runtime: its CPU, the port's thread's and the
    event loop's."""
    lines = []
    for p in plans:
        for path in ("native", "sdk"):
            r = p.realtime.get(path)
            if r is None or r.port_thread_ms is None or not math.isfinite(r.cpu_ms):
                continue
            lines.append(
                f"{p.name}, {path}: {r.cpu_ms:.2f} ms a cycle = port thread "
                f"{r.port_thread_ms:.2f} + event loop {r.cpu_ms - r.port_thread_ms:.2f}"
            )
    return lines


REALTIME_PATHS = ("native", "sdk", "loop", "loop_sdk", "baseline")
"""The real-time runs of a plan, by what they measure (:func:`run`)."""


def _ms(value: float) -> float | None:
    """CPU ms for ``--json``: ``None`` when no cycle was measured (infinite)."""
    return round(value, 3) if math.isfinite(value) else None


def _sdk_realtime_run(plan: str, seconds: float) -> Realtime:
    return realtime_run(plan, seconds, native=False)


def _sdk_bus_loop(plan: str, seconds: float) -> Realtime:
    return bus_loop(plan, seconds, native=False)


def _realtime_figures(p: PlanFigures) -> list[Figure]:
    """The real-time figures of one plan against their targets (issue targets in the
    module's constants)."""
    out: list[Figure] = []
    cpu_target = REALTIME_CPU_TARGET_MS.get(p.name, math.inf)
    labels = {
        "native": ("realtime", "real time over a pty", REALTIME_SHARE, cpu_target),
        "sdk": ("sdk_realtime", "real time, dynamixel-sdk's path", SHARE_OF_LIMIT, 2.0),
        "loop": ("loop", "the bus path alone", REALTIME_SHARE, cpu_target),
    }
    for path, (key, label, share, cpu_ms) in labels.items():
        r = p.realtime.get(path)
        if r is None:
            continue
        out.append(
            Figure(f"{p.name}_{key}_hz", f"{p.name}, {label}", r.hz, "Hz", share * p.limit_hz, True)
        )
        out.append(
            Figure(
                f"{p.name}_{key}_cpu_ms",
                f"{p.name}, {label}: process CPU per cycle",
                r.cpu_ms,
                "ms",
                cpu_ms,
            )
        )
    native, baseline = p.realtime.get("native"), p.realtime.get("baseline")
    if native is not None and baseline is not None:
        out.append(
            Figure(
                f"{p.name}_realtime_vs_baseline_hz",
                f"{p.name}, real time, vs a plain SDK loop",
                native.hz,
                "Hz",
                baseline.hz,
                at_least=True,
            )
        )
    return out
