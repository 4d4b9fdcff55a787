"""Test and tool helpers for the sensor reader: its channels and a one-actor graph."""

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
