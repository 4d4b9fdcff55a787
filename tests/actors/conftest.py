"""Fixtures of the actor tests."""

from collections.abc import Iterator

import pytest

from whexar.bus.emulator.chain import SERVO_CHAIN, ServoChain
from whexar.runtime.devices import DEVICES
from whexar.testing.bus import servo_chain


@pytest.fixture
def chain() -> Iterator[ServoChain]:
    """The thesis robot's emulated servos, registered as the port ``emulator:test``."""
    with DEVICES.registered(SERVO_CHAIN, "test", servo_chain()) as made:
        yield made
