"""Test and tool helpers for the sensor reader: its channels and a one-actor graph
(:mod:`whexar.actors.sensing.monitor`, where the monitor and the benchmark take it from)."""

from whexar.actors.sensing.monitor import SENSOR_CHANNELS, sensor_graph

__all__ = ["SENSOR_CHANNELS", "sensor_graph"]
