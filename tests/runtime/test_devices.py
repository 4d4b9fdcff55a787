"""The registry of in-process devices: one table for every kind, one error text."""

import pytest

from whexar.runtime.devices import DeviceKind, DeviceRegistry
from whexar.runtime.errors import UsageError

BOARD = DeviceKind[str]("emulated board", "emulator")
CHAIN = DeviceKind[str]("emulated chain", "emulator")


def test_kinds_with_the_same_scheme_are_apart() -> None:
    devices = DeviceRegistry()
    devices.register(BOARD, "a", "board a")
    devices.register(CHAIN, "a", "chain a")
    assert devices.get(BOARD, "a", setting="port") == "board a"
    assert devices.get(CHAIN, "a", setting="port") == "chain a"
    assert (BOARD, "a") in devices
    assert devices.names(BOARD) == ["a"]
    devices.clear(BOARD)
    assert devices.names(BOARD) == []
    assert devices.names(CHAIN) == ["a"]


def test_register_replaces_and_unregister_forgets() -> None:
    devices = DeviceRegistry()
    devices.register(BOARD, "x", "first")
    devices.register(BOARD, "x", "second")
    assert devices.get(BOARD, "x", setting="port") == "second"
    devices.unregister(BOARD, "x")
    devices.unregister(BOARD, "x")  # forgetting twice is harmless
    assert (BOARD, "x") not in devices
    assert BOARD.port("x") == "emulator:x"


def test_registered_lasts_for_the_block() -> None:
    devices = DeviceRegistry()
    with devices.registered(CHAIN, "t", "chain") as device:
        assert device == "chain"
        assert devices.get(CHAIN, "t", setting="port") == "chain"
    assert devices.names(CHAIN) == []


def test_an_unknown_name_names_the_setting_the_kind_and_the_known_names() -> None:
    devices = DeviceRegistry()
    with pytest.raises(UsageError) as caught:
        devices.get(BOARD, "nope", setting="port = 'emulator:nope'")
    assert str(caught.value) == (
        "port = 'emulator:nope': no emulated board registered as 'nope' (registered: none); "
        "register one with whexar.runtime.devices.DEVICES.register()"
    )
    devices.register(BOARD, "b", "x")
    devices.register(BOARD, "a", "y")
    with pytest.raises(UsageError, match=r"\(registered: a, b\)"):
        devices.get(BOARD, "nope", setting="port")
