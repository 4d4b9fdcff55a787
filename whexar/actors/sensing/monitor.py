"""The sensor reader on its own: a one-actor graph for the monitor and the benchmark.

``whexar sensors`` and ``whexar bench sensors`` run the real
:class:`~whexar.actors.sensing.board.SensorReader` on a port, alone, with the outputs
they look at; the robot's own graph is ``config/graphs/walk.toml``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

SENSOR_CHANNELS: dict[str, dict[str, str]] = {
    "frames": {"message": "SensorFrame", "policy": "queue"},
    "ranges": {"message": "ObstacleRanges", "policy": "latest"},
    "loads": {"message": "LegLoads", "policy": "latest"},
    "tilt": {"message": "BodyTilt", "policy": "latest"},
    "stats": {"message": "SensorStats", "policy": "latest"},
}
"""The reader's channels: whole frames queue up (a monitor wants every one); state is latest."""


def sensor_graph(
    port: str,
    params: Mapping[str, Any] | None = None,
    *,
    outputs: Sequence[str] = ("frames", "ranges", "loads", "tilt", "stats"),
    sinks: bool = True,
) -> dict[str, Any]:
    """A wiring document: a ``SensorReader`` on ``port`` with ``params``.

    ``outputs`` picks the reader's wired outputs; with ``sinks`` each gets a
    ``whexar.testing:Sink`` so that a queue channel never fills up.
    """
    actors: list[dict[str, Any]] = [
        {
            "name": "sensors",
            "class": "whexar.actors.sensing:SensorReader",
            "params": {"port": port, **(params or {})},
            "outputs": {name: name for name in outputs},
        }
    ]
    if sinks:
        actors.extend(
            {"name": f"{name}-sink", "class": "whexar.testing:Sink", "inputs": {"inp": name}}
            for name in outputs
        )
    return {"actors": actors, "channels": {name: SENSOR_CHANNELS[name] for name in outputs}}
