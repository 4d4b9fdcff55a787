"""Every device-owning actor refuses an unknown in-process device with the registry's one text."""

from typing import Any

import pytest

from whexar.runtime.messages import ActorFailed
from whexar.testing import run_actors
from whexar.testing.bus import bus_graph
from whexar.testing.imu import imu_graph
from whexar.testing.sensors import sensor_graph


@pytest.mark.parametrize(
    ("graph", "text"),
    [
        (
            bus_graph("emulator:nope", wiggle={}, max_restarts=0),
            "port = 'emulator:nope': no emulated servo chain registered as 'nope'",
        ),
        (
            sensor_graph("emulator:nope"),
            "port = 'emulator:nope': no emulated sensor board registered as 'nope'",
        ),
        (
            imu_graph("fake:nope", max_restarts=0),
            "device = 'fake:nope': no fake I²C bus registered as 'nope'",
        ),
    ],
)
def test_unknown_device_names_fail_the_actor_with_one_text(
    graph: dict[str, Any], text: str
) -> None:
    result = run_actors(graph, duration=0.5)
    failed = result.events(of=ActorFailed)
    assert failed
    assert text in failed[0].error
    assert "register one with whexar.runtime.devices.DEVICES.register()" in failed[0].error
