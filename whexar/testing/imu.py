"""Test and tool helpers for the IMU reader: a one-actor graph on a fake chip."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any


def imu_graph(
    device: str = "fake",
    params: Mapping[str, Any] | None = None,
    *,
    outputs: Sequence[str] = ("tilt", "samples"),
    max_restarts: int | None = None,
) -> dict[str, Any]:
    """A wiring document: an ``ImuReader`` on ``device`` with ``params``, outputs on queues.

    ``device`` is ``"fake"`` (a fresh fake chip) or ``"fake:NAME"`` (one
    registered in :data:`~whexar.runtime.devices.DEVICES` as
    :data:`~whexar.sensors.imu_emulator.I2C_BUS`).
    """
    channels = {"tilt": "BodyTilt", "samples": "ImuSample"}
    doc: dict[str, Any] = {
        "actors": [
            {
                "name": "imu",
                "class": "whexar.actors.sensing:ImuReader",
                "params": {"device": device, **(params or {})},
                "outputs": {name: name for name in outputs},
            }
        ],
        "channels": {name: {"message": channels[name], "policy": "queue"} for name in outputs},
    }
    if max_restarts is not None:
        doc["runtime"] = {"restart": {"max_restarts": max_restarts}}
    return doc
