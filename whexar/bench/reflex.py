"""``whexar bench reflex``: a reflex's latency to the wire, and what the reactive layer costs.

Targets (issue "The reactive layer", Performance): from the sensor message that
triggers a reflex to its corrective goal on the wire, on virtual time, **p99 ≤ 1
control cycle**; the whole reactive layer adds **≤ 0.3 ms of CPU per control
cycle**.

What is measured
----------------
The robot's graph (:func:`~whexar.actors.graph.robot_graph`) on the emulators —
the in-process servo chain behind the real bus scheduler, the sensor board, the
IMU — on virtual time, walking the tripod gait at 0.1 m/s from 3 s. The legs
sense no contact (``contact = "none"``): the emulators have no ground, so every
swing would end with no contact and the searching reflex would step every leg
again; without it the walk is a nominal one, nothing to react to, and each
swing ends ``completed``.

* **latency** — the graph also runs :class:`Probe`, a reflex that answers every
  swing end (:class:`SwingEnded`, the legs' typed signal) with a femur override of
  its own, a distinct angle each time. For each, the latency runs from the swing
  end's publication to the first Sync Write of Goal Position on the servo link
  (the bytes the bus scheduler writes, seen through the runtime's link
  observer) after the leg has sent the bus that angle. In control cycles:
  divided by the median interval between two servo readings (``ServoStates``).
  p50 and p99 over every swing end from 5 to 20 s. The same from the swing
  end's own time — the servo reading it came from, a bus job earlier — is
  given beside it (``latency_from_reading_cycles_p99``).
* **cpu_ms_per_cycle** — the process CPU time from 5 to 20 s of the same walk
  with the whole reactive layer (the shipped reflexes — battery, elevator,
  heading hold, obstacle, searching, stepping, trochanter — the terrain estimator
  and the gait selector) less the same without any of it, divided by the control cycles in
  the window. Medians of :data:`REPEATS` runs each, taken in turn, so that a
  burst of load beside the bench moves both. One more run times the reflexes'
  policies alone (every ``react`` and ``tick``): the part of it that is theirs
  and not the runtime's (``policies_ms_per_cycle``). The legs' contact
  estimate runs inside the legs, with or without the layer: its cost is timed
  apart, six estimates a cycle (``contact_ms_per_cycle``).

No message log is kept: its garbage-collector passes would be billed to the
runs.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any, Final

from whexar.actors.graph import robot_graph
from whexar.actors.messages import JointGoals, MotionCommand, ServoStates, SwingEnded
from whexar.actors.reactive import ACTIVITY, OVERRIDES, REQUESTS, Reflex, add_reflexes
from whexar.actors.reactive import parse_entries as reflex_entries
from whexar.actors.reactive.battery import Battery
from whexar.actors.reactive.elevator import Elevator
from whexar.actors.reactive.heading import HeadingHold
from whexar.actors.reactive.layer import LEG_ACTOR, REFLEX_ACTOR
from whexar.actors.reactive.obstacle import ObstacleReflex
from whexar.actors.reactive.searching import Searching
from whexar.actors.reactive.stepping import Stepping
from whexar.actors.reactive.trochanter import Trochanter
from whexar.bench import Figure, Progress, Report, percentile
from whexar.bus import control_table as ct
from whexar.bus.protocol import Instruction, PacketDecoder, parse_sync_write_params
from whexar.runtime.harness import Harness, run_actors
from whexar.runtime.messages import Message

LATENCY_TARGET_CYCLES: Final = 1.0
CPU_TARGET_MS: Final = 0.3
REPEATS: Final = 3
START_S: Final = 5.0
"""Measured from here: stood up by 2.4 s, walking from 3 s, the speed ramped."""
END_S: Final = 20.0
FEMUR: Final = 2
PROBE_BASE_RAD: Final = -0.30
PROBE_STEP_RAD: Final = 0.02
PROBE_VALUES: Final = 8
"""The probe's angles: −0.30, −0.28 … −0.16 rad, in turn (within the femur's ±120°)."""
SHIPPED: Final = ("elevator", "heading-hold", "obstacle", "searching", "stepping", "trochanter")
"""The shipped reflexes beside the robot graph's own (the battery's)."""
LAYER_ACTORS: Final = (
    "whexar.actors.reactive:TerrainEstimatorActor",
    "whexar.actors.reactive:GaitSelectorActor",
)
"""The reactive layer's actors beside the reflexes: the terrain estimator, the selector."""
LAYER_CHANNELS: Final = ("terrain", "gait-choice", "imu")
_GOAL_POSITION: Final = ct.model("MX-64").register("goal_position").address


class Probe(Reflex):
    """Answers every swing end with a femur override of a distinct angle (module docstring)."""

    inputs = ("swings",)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.count = 0

    def react(self, t: float, msg: Message) -> Iterable[JointGoals]:
        if not isinstance(msg, SwingEnded):
            return ()
        angle = PROBE_BASE_RAD + (self.count % PROBE_VALUES) * PROBE_STEP_RAD
        self.count += 1
        return (self.override(t, msg.leg, {FEMUR: angle}),)


SPENT: Final[list[int]] = [0]
"""CPU (thread time, ns) inside the timed reflexes' ``react`` and ``tick``."""


def _timed(cls: type[Reflex]) -> type[Reflex]:
    """``cls`` with a CPU stopwatch on its ``react`` and ``tick`` (into :data:`SPENT`)."""

    class Timed(cls):  # type: ignore[misc,valid-type]  # a class made at run time
        def react(self, t: float, msg: Message) -> Any:
            start = time.thread_time_ns()
            try:
                return list(super().react(t, msg))
            finally:
                SPENT[0] += time.thread_time_ns() - start

        def tick(self, t: float) -> Any:
            start = time.thread_time_ns()
            try:
                return list(super().tick(t))
            finally:
                SPENT[0] += time.thread_time_ns() - start

    Timed.__name__ = Timed.__qualname__ = f"Timed{cls.__name__}"
    return Timed


TimedBattery = _timed(Battery)
TimedElevator = _timed(Elevator)
TimedHeadingHold = _timed(HeadingHold)
TimedObstacle = _timed(ObstacleReflex)
TimedSearching = _timed(Searching)
TimedStepping = _timed(Stepping)
TimedTrochanter = _timed(Trochanter)
TIMED: Final = {
    "battery": "whexar.bench.reflex:TimedBattery",
    "elevator": "whexar.bench.reflex:TimedElevator",
    "heading-hold": "whexar.bench.reflex:TimedHeadingHold",
    "obstacle": "whexar.bench.reflex:TimedObstacle",
    "searching": "whexar.bench.reflex:TimedSearching",
    "stepping": "whexar.bench.reflex:TimedStepping",
    "trochanter": "whexar.bench.reflex:TimedTrochanter",
}


def contact_cost_ms(cycles: int = 20_000) -> float:
    """CPU of six contact estimates (one control cycle's), ms: a stance and a swing a
    second, the FSR and the current read every cycle."""
    from whexar.config import RobotConfig
    from whexar.kinematics.contact import ContactEstimator

    cfg = RobotConfig()
    est = ContactEstimator(cfg.contact.model(cfg.locomotion.contact_current_a))
    start = time.thread_time_ns()
    for k in range(cycles):
        t = k * 0.01
        stance = (k // 50) % 2 == 0
        est.estimate(
            t,
            "stance" if stance else "swing",
            fsr=stance,
            fsr_t=t,
            current_a=-1.2 if stance else 0.2,
            current_t=t,
        )
    return 6 * (time.thread_time_ns() - start) / 1e6 / cycles


def bench_graph(*, reflexes: bool, probe: bool, timed: bool = False) -> dict[str, Any]:
    """The robot on the emulators, commands fed; with the shipped reflexes (and the probe),
    or with none."""
    doc = robot_graph(feeds=["commands"])
    for a in doc["actors"]:  # no ground on the emulators: a walk with nothing to react to
        if a.get("class") == LEG_ACTOR:
            a.setdefault("params", {})["contact"] = "none"
    if not reflexes:
        gone = (REFLEX_ACTOR, *LAYER_ACTORS)
        doc["actors"] = [a for a in doc["actors"] if a.get("class") not in gone]
        for name in (OVERRIDES, REQUESTS, ACTIVITY, *LAYER_CHANNELS):
            doc["channels"].pop(name, None)
        for a in doc["actors"]:
            for port in ("reflex", "requests", "gait_choice"):
                a.get("inputs", {}).pop(port, None)
            if a.get("outputs", {}).get("samples") == "imu":
                del a["outputs"]["samples"]
        return doc
    tables: list[dict[str, Any]] = [
        {"type": TIMED[name] if timed else name, "name": name} for name in SHIPPED
    ]
    if timed:
        for a in doc["actors"]:
            if a["name"] == "reflex-battery":
                a["params"]["reflex"] = TIMED["battery"]
    if probe:
        tables.append({"type": "whexar.bench.reflex:Probe", "name": "probe"})
    add_reflexes(doc, reflex_entries(tables, "reflexes", "bench"), source="bench")
    return doc


@dataclass
class Watch:
    """What one run saw: swing ends, the legs' probe goals, the bus's goal writes."""

    swings: list[tuple[float, float, int]] = field(default_factory=list)
    """(its time, when it was published, leg) of each swing end."""
    now: Any = None
    """The runtime clock's ``now``, once the run is under way."""
    probe_goals: list[tuple[float, int, float]] = field(default_factory=list)
    """(time, leg, angle) of each leg's goal message carrying a probe angle."""
    writes: list[float] = field(default_factory=list)
    """Times of the Sync Writes of Goal Position."""
    readings: list[float] = field(default_factory=list)
    """Times of the servo readings (ServoStates)."""
    decoder: PacketDecoder = field(default_factory=PacketDecoder)

    def message(self, channel: str, msg: Message) -> None:
        if isinstance(msg, ServoStates):
            self.readings.append(msg.t)
        elif isinstance(msg, SwingEnded) and self.now is not None:
            self.swings.append((msg.t, self.now(), msg.leg))
        elif channel == "goals" and isinstance(msg, JointGoals) and not msg.reflex:
            for g in msg.goals:
                if g.joint == FEMUR and g.position_rad is not None and _is_probe(g.position_rad):
                    self.probe_goals.append((msg.t, g.leg, g.position_rad))

    def link(self, link: str, direction: str, t: float, data: bytes) -> None:
        if link != "bus" or direction != "tx":
            return
        for packet in self.decoder.feed(data):
            if packet.instruction == Instruction.SYNC_WRITE:
                start, _, _ = parse_sync_write_params(packet.params)
                if start == _GOAL_POSITION:
                    self.writes.append(t)


def _is_probe(angle: float) -> bool:
    k = (angle - PROBE_BASE_RAD) / PROBE_STEP_RAD
    return abs(k - round(k)) < 1e-9 and 0 <= round(k) < PROBE_VALUES


def one_run(
    doc: dict[str, Any], watch: Watch | None = None, *, end_s: float = END_S
) -> tuple[float, int, float]:
    """Run ``doc`` to ``end_s``: the process CPU from :data:`START_S` to the end, s, the
    control cycles in that window, and the timed reflexes' CPU in it, s."""
    marks: dict[str, float] = {}
    cycles = [0]

    def count(channel: str, msg: Message) -> None:
        if isinstance(msg, ServoStates) and msg.t >= START_S:
            cycles[0] += 1
        if watch is not None:
            watch.message(channel, msg)

    async def scenario(h: Harness) -> None:
        if watch is not None:
            watch.now = h.now
        await h.sleep_until(3.0)
        await h.feed("commands", MotionCommand(t=3.0, source="bench", vx_m_s=0.1))
        await h.sleep_until(START_S)
        marks["start"], marks["spent0"] = time.process_time(), SPENT[0] * 1e-9
        await h.sleep_until(end_s)
        marks["end"], marks["spent1"] = time.process_time(), SPENT[0] * 1e-9

    run_actors(
        doc,
        duration=end_s + 0.5,
        scenario=scenario,
        feeds=["commands"],
        keep_log=False,
        observers=[count],
        link_observer=watch.link if watch is not None else None,
    )
    return marks["end"] - marks["start"], cycles[0], marks["spent1"] - marks["spent0"]


def latencies(w: Watch, end_s: float = END_S) -> tuple[list[float], list[float], float]:
    """Each probed swing end's latency to the wire, s — from its publication and from its
    time (the servo reading it came from) — and the median cycle period, s."""
    period = statistics.median(b - a for a, b in zip(w.readings, w.readings[1:], strict=False))
    published, read = [], []
    goals = sorted(w.probe_goals)
    writes = sorted(w.writes)
    for t, at, leg in w.swings:
        if not START_S <= t <= end_s:
            continue
        sent = next((g for g in goals if g[0] >= at and g[1] == leg), None)
        if sent is None:
            continue
        wire = next((x for x in writes if x >= sent[0]), None)
        if wire is not None:
            published.append(wire - at)
            read.append(wire - t)
    return published, read, period


def run(progress: Progress = None, *, repeats: int = REPEATS, end_s: float = END_S) -> Report:
    """Measure the latency and the reactive layer's CPU (module docstring); ``repeats`` runs
    of each kind, each measured from :data:`START_S` to ``end_s``."""
    say = progress or (lambda _line: None)
    say("the robot on the emulators, virtual time, a tripod walk: the probe's latency…")
    watch = Watch()
    one_run(bench_graph(reflexes=True, probe=True), watch, end_s=end_s)
    lat, from_read, period = latencies(watch, end_s)
    if not lat:
        raise RuntimeError("no swing end reached the wire: the bench measured nothing")
    in_cycles = [x / period for x in lat]
    p50, p99 = percentile(in_cycles, 0.5), percentile(in_cycles, 0.99)
    read_p99 = percentile([x / period for x in from_read], 0.99)
    with_ms: list[float] = []
    without_ms: list[float] = []
    for k in range(repeats):
        say(f"CPU, run {k + 1} of {repeats}: with the reflexes, then without…")
        for reflexes, out in ((True, with_ms), (False, without_ms)):
            cpu_s, cycles, _ = one_run(bench_graph(reflexes=reflexes, probe=False), end_s=end_s)
            out.append(cpu_s * 1e3 / max(1, cycles))
    say("the policies alone, each react and tick timed…")
    _, cycles, spent_s = one_run(bench_graph(reflexes=True, probe=False, timed=True), end_s=end_s)
    policies_ms = spent_s * 1e3 / max(1, cycles)
    added = statistics.median(with_ms) - statistics.median(without_ms)
    contact_ms = contact_cost_ms()
    pairs = [a - b for a, b in zip(with_ms, without_ms, strict=True)]
    items = [
        Figure("latency_cycles_p50", "swing end → goal on the wire, p50", p50, "cycles", 1.0),
        Figure(
            "latency_cycles_p99",
            "swing end → goal on the wire, p99",
            p99,
            "cycles",
            LATENCY_TARGET_CYCLES,
        ),
        Figure(
            "cpu_ms_per_cycle",
            "CPU the reactive layer adds per control cycle",
            added,
            "ms",
            CPU_TARGET_MS,
        ),
    ]
    notes = [
        f"{len(lat)} swing ends from {START_S:g} to {end_s:g} s; control cycle "
        f"{period * 1e3:.2f} ms (median interval of the servo readings); latency from the "
        f"swing end's publication {min(lat) * 1e3:.1f}–{max(lat) * 1e3:.1f} ms",
        f"from the servo reading the swing end came from: p99 {read_p99:.3f} cycles — the bus "
        "reads, then writes, in one job, so an answer to cycle k's reading goes out with "
        "cycle k+1's writes",
        f"CPU per cycle with the reflexes {', '.join(f'{x:.3f}' for x in with_ms)} ms, "
        f"without {', '.join(f'{x:.3f}' for x in without_ms)} ms; pair by pair "
        f"{', '.join(f'{x:+.3f}' for x in pairs)} ms",
        f"the reflexes' policies alone (every react and tick timed, one more run): "
        f"{policies_ms * 1e3:.1f} µs per cycle; the rest of what they add is receiving and "
        "sending, below the noise of the runs' difference",
        "the layer: the reflexes battery (the robot graph's), elevator, heading hold, "
        "obstacle, searching, stepping, trochanter; the terrain estimator and the gait "
        "selector (with the IMU's samples they read)",
        f"the legs' contact estimate, in the legs whichever run: {contact_ms * 1e3:.1f} µs "
        "per cycle (six estimates)",
    ]
    data = {
        "latency_cycles_p50": round(p50, 3),
        "latency_cycles_p99": round(p99, 3),
        "cpu_ms_per_cycle": round(added, 4),
        "latency_from_reading_cycles_p99": round(read_p99, 3),
        "policies_ms_per_cycle": round(policies_ms, 4),
        "contact_ms_per_cycle": round(contact_ms, 4),
    }
    return Report("reflex", items, notes, data=data)
