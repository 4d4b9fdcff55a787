"""``whexar bench fieldbus``: a field log's servo bus played back by time, and what that costs.

What is measured (:mod:`whexar.bus.field`):

* a field log is made: ``config/graphs/bus.toml`` (the bus scheduler, ``default`` plan,
  and a goal source swaying every joint) on real time for :data:`SECONDS`, through
  dynamixel-sdk over a pseudo-terminal to ``whexar emulate`` in another process, its
  bus link recorded as a recording holds it — the robot's kind of log: the SDK's own
  reads, stamped on a real clock;
* **replay_realtime_factor** — the same graph on virtual time against that log played
  back by time (``emulator:NAME``), as fast as it goes: replayed seconds per wall
  second, the least of :data:`REPEATS` (target, issue 29: ≥ 10× for a whole field
  replay; this is its bus alone);
* **mover_us** — in that replay, the wall time of the chain's mover per transaction
  (:data:`~whexar.bus.emulator.chain.ServoChain.mover`: reading the log's events on,
  decoding them, setting the registers), timed around each call;
* **field_chain_us** — the field bus's whole cost per transaction, the mover, the
  write comparison and the pacing included, with every recorded packet sent to it at
  its recorded time (no scheduler, no SDK), against **emulator_us**: the emulator's
  own chain answering the same packets (its servos' dynamics instead of the mover).
  Its target: no more than the emulator the simulation runs on.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from typing import Any, Final, TypeVar

from whexar.bench import Figure, Progress, Report
from whexar.bench.bus import _graph, emulator_process
from whexar.bus.emulator.chain import SERVO_CHAIN, ServoChain
from whexar.bus.field import FieldBus
from whexar.config import RobotConfig
from whexar.runtime.clock import run as run_loop
from whexar.runtime.devices import DEVICES
from whexar.runtime.harness import run_actors
from whexar.runtime.supervisor import Runtime
from whexar.runtime.wiring import build_graph

SECONDS: Final = 5.0
"""Real time recorded."""
REPEATS: Final = 3
REPLAY_TARGET: Final = 10.0
"""Replayed seconds per wall second (issue 29, ``--fast``)."""
PLAN: Final = "default"

Events = list[tuple[str, float, bytes]]
F = TypeVar("F", bound=Callable[..., Any])


def record_field_log(seconds: float = SECONDS) -> Events:
    """The bus link of ``bus.toml`` run on real time over a pty (module docstring)."""
    events: Events = []

    def observe(link: str, direction: str, t: float, data: bytes) -> None:
        if link == "bus":
            events.append((direction, t, bytes(data)))

    async def main() -> None:
        runtime = Runtime(build_graph(_graph(path, PLAN)), link_observer=observe)
        await runtime.run(duration=seconds)

    with emulator_process() as path:
        run_loop(main)
    return events


class _Timer:
    """Wall time spent in the calls it wraps."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self.calls = 0

    def wrap(self, fn: F) -> F:
        clock = time.perf_counter

        def timed(*args: Any) -> Any:
            start = clock()
            try:
                return fn(*args)
            finally:
                self.seconds += clock() - start
                self.calls += 1

        return timed  # type: ignore[return-value]


def _field(events: Iterable[tuple[str, float, bytes]], cfg: RobotConfig) -> FieldBus:
    return FieldBus(events, models=cfg.servos(), baudrate=cfg.bus.baudrate)


def replay(events: Events, cfg: RobotConfig, seconds: float) -> tuple[float, float, int]:
    """The bus graph on virtual time against ``events`` played back by time: its wall
    time, the mover's, and how many transactions the chain made."""
    bus = _field(events, cfg)
    mover = _Timer()
    assert bus.chain.mover is not None
    bus.chain.mover = mover.wrap(bus.chain.mover)
    start = time.perf_counter()
    with DEVICES.registered(SERVO_CHAIN, "bench-field", bus.chain):
        result = run_actors(_graph("emulator:bench-field", PLAN), duration=seconds, keep_log=False)
    wall = time.perf_counter() - start
    if result.exit_code != 0:
        raise RuntimeError(f"the bench's replay failed: {result.stop_reason}")
    return wall, mover.seconds, mover.calls


def per_transaction(chain: ServoChain, requests: list[tuple[float, bytes]]) -> float:
    """Seconds per transaction of ``chain`` answering ``requests`` at their times."""
    start = time.perf_counter()
    for t, data in requests:
        chain.transact(data, t)
    return (time.perf_counter() - start) / max(1, len(requests))


def measure(
    seconds: float = SECONDS, repeats: int = REPEATS, progress: Progress = None
) -> dict[str, Any]:
    """The figures of the module docstring, the least of ``repeats`` each."""
    say = progress or (lambda _: None)
    cfg = RobotConfig()
    say(f"recording {seconds:g} s of the bus on real time over a pty to `whexar emulate`…")
    events = record_field_log(seconds)
    requests = [(t, data) for direction, t, data in events if direction == "tx"]
    walls, movers, chains, emulators = [], [], [], []
    for k in range(repeats):
        say(f"replay {k + 1}/{repeats} against the log played back by time…")
        wall, mover_s, calls = replay(events, cfg, seconds)
        walls.append(wall)
        movers.append(mover_s / max(1, calls))
        chains.append(per_transaction(_field(events, cfg).chain, requests))
        emulator = ServoChain.for_models(cfg.servos(), baudrate=cfg.bus.baudrate)
        emulators.append(per_transaction(emulator, requests))
    return {
        "replay_realtime_factor": round(seconds / min(walls), 2),
        "mover_us": round(1e6 * min(movers), 1),
        "field_chain_us": round(1e6 * min(chains), 1),
        "emulator_us": round(1e6 * min(emulators), 1),
        "recorded_packets": len(requests),
        "recorded_events": len(events),
        "recorded_s": seconds,
    }


def run(progress: Progress = None) -> Report:
    """Measure (module docstring); ``progress`` receives a line per step."""
    figures = measure(progress=progress)
    return Report(
        "fieldbus",
        [
            Figure(
                "replay_realtime_factor",
                "bus of a field log, replayed --fast",
                figures["replay_realtime_factor"],
                "×",
                REPLAY_TARGET,
                at_least=True,
            ),
            Figure(
                "field_chain_us",
                "field bus per transaction",
                figures["field_chain_us"],
                "µs",
                figures["emulator_us"],
            ),
        ],
        notes=[
            f"the mover per transaction in the replay: {figures['mover_us']:.1f} µs "
            "(reading and decoding the log included)",
            f"the emulator's own chain on the same packets: {figures['emulator_us']:.1f} µs "
            "per transaction (the target above)",
            f"log: {figures['recorded_packets']} packets written, "
            f"{figures['recorded_events']} link events, {figures['recorded_s']:g} s on real time",
        ],
        data=figures,
    )


__all__ = ["measure", "record_field_log", "run"]
