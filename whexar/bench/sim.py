"""``whexar bench sim``: the full runtime plus the physics, against real time.

Target: the default course runs at **≥ 5× real time** on the machine that runs
the bench (:data:`RTF_TARGET`).

What is measured
----------------
The first :data:`BENCH_SECONDS` of the ``course`` scenario (standing up,
the tripod gait, riding and the approach to the ramp: every engine of the
coordinator) run once through :meth:`whexar.sim.scenario.Scenario.run` —
the real actors, dynamixel-sdk, the servo emulator, the sensor-board codec,
the MuJoCo world — on virtual time, as fast as the machine goes.

* **realtime_factor** — simulated seconds per wall second of that run (the
  world's construction is not in it; the timers below are, a small cost:
  docs/sim.md, "Speed").
* **cpu_ms_per_cycle** — wall milliseconds per bus cycle (one
  :class:`~whexar.actors.messages.ServoStates` each), split four ways by
  timers installed for the run only, on the classes (not on any instance the
  run makes, which the bench never sees) and removed after it:

  - ``physics``: :meth:`SimWorld.advance_to <whexar.sim.world.SimWorld.advance_to>`
    — the servo firmware and motor model and ``mj_step`` — less the sensors
    refreshed inside it;
  - ``sensors``: ``SimWorld._sense`` — contact forces, ray casts, the IMU;
  - ``bus``: the bus scheduler's port jobs (:class:`~whexar.bus.sdk.InlinePortOwner`):
    dynamixel-sdk, the Protocol 2.0 codec and the servo emulator, less the
    physics and sensors they step;
  - ``actors``: the rest of the wall time — the runtime, the six legs, the
    coordinator, the sensor and IMU readers decoding the emulated devices, the
    message log and the run's sampling.

The process is single-threaded (virtual time), so wall time is CPU time here
up to what other processes take from it.
"""

from __future__ import annotations

import contextlib
import functools
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, Final, TypeVar

from whexar.bench import Figure, Progress, Report
from whexar.bus.sdk import DxlBus, InlinePortOwner
from whexar.sim.scenario import DEFAULT_SCENARIO, load_scenario
from whexar.sim.world import SimWorld

RTF_TARGET: Final = 5.0
BENCH_SECONDS: Final = 20.0
"""Simulated seconds of the course that are run."""

T = TypeVar("T")


@dataclass
class _Timers:
    """Seconds spent in each part, and whether a port job is running."""

    job: float = 0.0
    advance: float = 0.0
    advance_in_job: float = 0.0
    sense: float = 0.0
    in_job: int = 0


@contextlib.contextmanager
def timed_parts() -> Iterator[_Timers]:
    """Install the timers of the module docstring for the duration of the block."""
    timers = _Timers()
    advance = SimWorld.advance_to
    sense = SimWorld._sense
    call = InlinePortOwner.call

    @functools.wraps(advance)
    def timed_advance(self: SimWorld, t: float) -> None:
        start = time.perf_counter()
        try:
            advance(self, t)
        finally:
            spent = time.perf_counter() - start
            timers.advance += spent
            if timers.in_job:
                timers.advance_in_job += spent

    @functools.wraps(sense)
    def timed_sense(self: SimWorld) -> None:
        start = time.perf_counter()
        try:
            sense(self)
        finally:
            timers.sense += time.perf_counter() - start

    async def timed_call(self: InlinePortOwner, job: Callable[[DxlBus], T]) -> T:
        def timed_job(bus: DxlBus) -> T:
            timers.in_job += 1
            start = time.perf_counter()
            try:
                return job(bus)
            finally:
                timers.job += time.perf_counter() - start
                timers.in_job -= 1

        return await call(self, timed_job)

    SimWorld.advance_to = timed_advance  # type: ignore[method-assign]
    SimWorld._sense = timed_sense  # type: ignore[method-assign]
    InlinePortOwner.call = timed_call  # type: ignore[method-assign]
    try:
        yield timers
    finally:
        SimWorld.advance_to = advance  # type: ignore[method-assign]
        SimWorld._sense = sense  # type: ignore[method-assign]
        InlinePortOwner.call = call  # type: ignore[method-assign]


def measure(seconds: float = BENCH_SECONDS, scenario: str = DEFAULT_SCENARIO) -> dict[str, Any]:
    """Run ``seconds`` of ``scenario`` with the timers; the figures of ``--json``."""
    chosen = load_scenario(scenario).with_overrides(duration_s=seconds)
    with timed_parts() as timers:
        result = chosen.run()
    cycles = max(1, result.series.cycles)
    # The world is advanced by the servos' dynamics, inside the port jobs; whatever
    # advanced it outside a job (nothing, as wired today) still counts as physics.
    sensors = timers.sense
    physics = timers.advance - sensors
    bus = timers.job - timers.advance_in_job
    actors = result.wall_s - bus - physics - sensors
    per_cycle = {
        "bus": bus,
        "actors": actors,
        "physics": physics,
        "sensors": sensors,
    }
    # Virtual time runs on after the duration while the robot sits down: count it all.
    sim_seconds = max(result.run.end_time, seconds)
    return {
        "realtime_factor": round(sim_seconds / result.wall_s, 3),
        "cpu_ms_per_cycle": {k: round(1000 * v / cycles, 4) for k, v in per_cycle.items()},
        "cycles": cycles,
        "sim_seconds": round(sim_seconds, 3),
        "wall_seconds": round(result.wall_s, 3),
    }


def run(progress: Progress = None) -> Report:
    """The bench: see the module docstring."""
    say = progress or (lambda _: None)
    say(f"course, first {BENCH_SECONDS:g} s simulated, full runtime and physics…")
    found = measure()
    parts = found["cpu_ms_per_cycle"]
    items = [
        Figure(
            "realtime_factor",
            "simulated seconds per wall second",
            found["realtime_factor"],
            "x",
            RTF_TARGET,
            at_least=True,
        )
    ]
    notes = [
        f"{found['sim_seconds']:g} s simulated in {found['wall_seconds']:g} s, "
        f"{found['cycles']} bus cycles",
        "ms per bus cycle: "
        + ", ".join(f"{key} {value:.3f}" for key, value in parts.items())
        + f" (total {sum(parts.values()):.3f})",
    ]
    data = {"realtime_factor": found["realtime_factor"], "cpu_ms_per_cycle": parts}
    return Report("sim", items, notes, data=data)
