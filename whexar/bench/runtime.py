"""``whexar bench runtime``: message passing and virtual time (targets of the runtime issue).

Every figure goes through the whole runtime (wiring, supervision, ports,
channels), built from the same kind of graph configuration the robot uses,
with the actors of :mod:`whexar.testing`:

* **messages_per_s** — one ``Pulse`` publishes a burst of heartbeats into one
  ``backpressure`` channel (capacity 256) that one ``Sink`` drains; the time
  runs from "every actor ready" until the sink has consumed the last one.
  Making each message is part of the cost. Target ≥ 200,000/s.
* **hop_us** — ten ``Relay`` actors in a ring pass one token; wall time over
  hops, real time. Target ≤ 20 µs.
* **virtual_60s_wall_s** — ten ``Pulse`` actors ticking at 100 Hz, each
  publishing every tick into a shared ``queue`` channel drained by a
  ``Sink``, run for 60 s of virtual time. Target ≤ 2 s of wall time.

Each figure is the median of several repeats.
"""

from __future__ import annotations

import functools
import statistics
import time
from collections.abc import Callable
from typing import Any

import anyio
from pydantic import BaseModel, ConfigDict

from whexar.bench import Figure, Progress, Report, median_seconds
from whexar.runtime.clock import run as run_loop
from whexar.runtime.messages import Heartbeat
from whexar.runtime.supervisor import Runtime
from whexar.runtime.wiring import Graph, build_graph

MESSAGES_TARGET_PER_S = 200_000.0
HOP_TARGET_US = 20.0
VIRTUAL_TARGET_S = 2.0
RING_SIZE = 10


def throughput_graph(count: int) -> Graph:
    """A ``Pulse`` bursting ``count`` heartbeats into a ``Sink`` over one command channel."""
    return build_graph(
        {
            "actors": [
                {
                    "name": "sink",
                    "class": "whexar.testing:Sink",
                    "params": {"stop_after": count},
                    "inputs": {"inp": "beats"},
                },
                {
                    "name": "source",
                    "class": "whexar.testing:Pulse",
                    "params": {"burst": count, "count": 1},
                    "outputs": {"out": "beats"},
                },
            ],
            "channels": {
                "beats": {"message": "Heartbeat", "policy": "backpressure", "capacity": 256}
            },
        }
    )


def ring_graph(hops: int, size: int = RING_SIZE) -> Graph:
    """``size`` relays in a ring; the last to start injects the token, ``hops`` ends the run."""
    actors: list[dict[str, Any]] = [
        {
            "name": f"relay{i}",
            "class": "whexar.testing:Relay",
            "params": {"limit": hops, "start": i == size - 1},
            "inputs": {"inp": f"link{i}"},
            "outputs": {"out": f"link{(i + 1) % size}"},
        }
        for i in range(size)
    ]
    channels = {f"link{i}": {"message": "Heartbeat", "policy": "backpressure"} for i in range(size)}
    return build_graph({"actors": actors, "channels": channels})


def ticking_graph(actors: int = 10, rate_hz: float = 100.0) -> Graph:
    """``actors`` pulses at ``rate_hz`` publishing into one queue drained by a sink."""
    specs: list[dict[str, Any]] = [
        {"name": "sink", "class": "whexar.testing:Sink", "inputs": {"inp": "beats"}}
    ]
    specs += [
        {
            "name": f"pulse{i}",
            "class": "whexar.testing:Pulse",
            "params": {"period_s": 1.0 / rate_hz},
            "outputs": {"out": "beats"},
        }
        for i in range(actors)
    ]
    channels = {"beats": {"message": "Heartbeat", "policy": "queue", "capacity": 64}}
    return build_graph({"actors": specs, "channels": channels})


def time_after_ready(
    graph: Graph, *, virtual: bool = False, duration: float | None = None
) -> float:
    """Wall seconds from "every actor ready" until the run has stopped."""

    async def main() -> float:
        runtime = Runtime(graph)
        async with anyio.create_task_group() as tg:
            await tg.start(functools.partial(runtime.run, duration=duration))
            start = time.perf_counter()
        return time.perf_counter() - start

    return run_loop(main, virtual=virtual)


def wall_time_of_run(graph: Graph, duration: float) -> float:
    """Wall seconds of a whole virtual-time run of ``duration`` runtime seconds."""

    async def main() -> None:
        await Runtime(graph).run(duration=duration)

    start = time.perf_counter()
    run_loop(main, virtual=True)
    return time.perf_counter() - start


def _median(fn: Callable[[], float], repeats: int) -> float:
    return statistics.median(fn() for _ in range(repeats))


class _PydanticHeartbeat(BaseModel):
    """The pydantic twin of :class:`Heartbeat`, only to show what the choice saves."""

    model_config = ConfigDict(frozen=True)
    t: float
    source: str
    seq: int


def message_costs(batch: int = 1_000, repeats: int = 100) -> tuple[float, float]:
    """Nanoseconds to make one message (median over batches): (frozen dataclass, pydantic)."""
    seqs = range(batch)
    dataclass_s = median_seconds(
        lambda: [Heartbeat(t=0.0, source="bench", seq=i) for i in seqs], repeats
    )
    pydantic_s = median_seconds(
        lambda: [_PydanticHeartbeat(t=0.0, source="bench", seq=i) for i in seqs], repeats
    )
    return dataclass_s / batch * 1e9, pydantic_s / batch * 1e9


def run(
    progress: Progress = None,
    *,
    messages: int = 100_000,
    hops: int = 10_000,
    virtual_s: float = 60.0,
    repeats: int = 5,
) -> Report:
    """Measure and return the figures; ``progress`` receives a line per step."""
    say = progress or (lambda _line: None)
    say(f"passing {messages:,} messages through one channel ({repeats} runs)…")
    graph = throughput_graph(messages)
    throughput = messages / _median(lambda: time_after_ready(graph), repeats)
    say(f"passing a token {hops:,} hops around a ring of {RING_SIZE} actors ({repeats} runs)…")
    ring = ring_graph(hops)
    hop = _median(lambda: time_after_ready(ring), repeats) / hops
    say(f"running 10 actors at 100 Hz for {virtual_s:g} s of virtual time (3 runs)…")
    ticking = ticking_graph()
    virtual = _median(lambda: wall_time_of_run(ticking, virtual_s), 3)
    say("timing message construction…")
    dataclass_ns, pydantic_ns = message_costs()
    return Report(
        "runtime",
        [
            Figure(
                "messages_per_s",
                "messages through one channel (median)",
                throughput,
                "msg/s",
                MESSAGES_TARGET_PER_S,
                at_least=True,
            ),
            Figure(
                "hop_us",
                f"token hop, ring of {RING_SIZE} actors (median)",
                hop * 1e6,
                "µs",
                HOP_TARGET_US,
            ),
            Figure(
                "virtual_60s_wall_s",
                f"{virtual_s:g} s virtual, 10 actors @ 100 Hz (median)",
                virtual,
                "s",
                VIRTUAL_TARGET_S * virtual_s / 60.0,
            ),
        ],
        notes=[
            f"making one message: frozen dataclass {dataclass_ns:.0f} ns, "
            f"pydantic model {pydantic_ns:.0f} ns (why messages are dataclasses)",
        ],
    )
