"""The SDK helpers whexar overrides, and the emulated port's buffer, behave as before."""

from __future__ import annotations

import random
from types import SimpleNamespace
from typing import Any

import pytest
from dynamixel_sdk.protocol2_packet_handler import TXPACKET_MAX_LEN, Protocol2PacketHandler

from whexar.bus.emulator.port import EmulatedPort
from whexar.bus.protocol import encode_status
from whexar.bus.sdk import DxlBus, PacketHandler
from whexar.errors import DeviceGoneError
from whexar.testing.bus import servo_chain


def _outcome(call: Any, packet: list[Any]) -> tuple[Any, ...]:
    """What a call returns (or raises), and what it leaves of the list it was given."""
    try:
        result = call(packet)
    except Exception as exc:
        return ("raised", type(exc), list(packet))
    return ("returned", list(result), result is packet, list(packet))


def _packet(rng: random.Random) -> list[Any]:
    size = rng.choice([rng.randrange(0, 40), rng.randrange(1010, 1030)])
    body = [rng.choice([0xFF, 0xFD, 0x00, rng.randrange(256)]) for _ in range(size)]
    length = len(body) + 2
    length = rng.choice([length, length, length, length - 1, length + 1, 0, 1, 2, 0xFFFF])
    packet: list[Any] = [0xFF, 0xFF, 0xFD, 0x00, rng.randrange(256), length & 0xFF]
    packet += [length >> 8, *body, rng.choice([0xFD, 0x12]), rng.choice([0xFD, 0x34])]
    if rng.random() < 0.05:  # LEN bytes that spell FF FF with the instruction FD
        packet[5:8] = [0xFF, 0xFF, 0xFD]
    if rng.random() < 0.03:  # not a byte: the SDK's loop decides
        packet[rng.randrange(len(packet))] = rng.choice([256, -1, 0x1FD, 1.5])
    return packet


@pytest.mark.slow
@pytest.mark.parametrize("helper", ["addStuffing", "removeStuffing"])
def test_stuffing_helpers_are_the_sdks(helper: str) -> None:
    """Same result, same list left behind, same exception: on any list, not only packets
    the SDK builds or receives (a body ending FF FF FD before a CRC_L of FD included)."""
    sdk, ours = Protocol2PacketHandler(), PacketHandler()
    rng = random.Random(3)
    seen = set()
    for _ in range(6000):
        packet = _packet(rng)
        expected = _outcome(getattr(sdk, helper), list(packet))
        assert _outcome(getattr(ours, helper), list(packet)) == expected
        seen.add((expected[0], expected[0] == "returned" and expected[1] != packet))
    assert seen == {("returned", False), ("returned", True), ("raised", False)}
    assert TXPACKET_MAX_LEN == 1024  # the bound addStuffing's fast path checks against


def test_update_crc_is_the_sdks() -> None:
    sdk, ours = Protocol2PacketHandler(), PacketHandler()
    rng = random.Random(4)
    for _ in range(2000):
        data = list(rng.randbytes(rng.randrange(0, 60)))
        size = rng.randrange(0, len(data) + 1)
        start = rng.randrange(0x10000)
        assert ours.updateCRC(start, data, size) == sdk.updateCRC(start, data, size)


class _Chain:
    """Just enough of a servo chain for the port: each write answers the next canned reply."""

    def __init__(self) -> None:
        self.faults = SimpleNamespace(unplugged=False, tx_fail=0)
        self.timing = SimpleNamespace(baudrate=1_000_000, bits_per_byte=10)
        self.replies: list[bytes] = []

    def transact(self, request: bytes, t: float) -> Any:
        return SimpleNamespace(reply=self.replies.pop(0), cost_s=0.0)


def test_port_buffer_is_a_plain_fifo() -> None:
    """Reads, writes, clears and peeks as on the bytearray the port kept before."""
    rng = random.Random(6)
    chain = _Chain()
    port = EmulatedPort(chain)  # type: ignore[arg-type]
    plain = bytearray()
    for _ in range(20_000):
        op = rng.randrange(10)
        if op < 2:
            reply = rng.randbytes(rng.choice([0, 0, 11, 21, 60]))
            chain.replies.append(reply)
            assert port.writePort([1, 2, 3]) == 3
            plain += reply
        elif op < 7:
            n = rng.choice([rng.randrange(-15, 30), 0, 11])
            expected = bytes(plain[:n])
            del plain[:n]
            got = port.readPort(n)
            assert type(got) is bytes
            assert got == expected
        elif op == 7:
            port.clearPort()
            plain.clear()
        else:
            assert port.peek() == bytes(plain)
            assert port.getBytesAvailable() == len(plain)
            assert port.isPacketTimeout() == (not plain)


def test_an_unplugged_port_still_raises_through_the_bus() -> None:
    chain = servo_chain()
    port = EmulatedPort(chain)
    bus = DxlBus(port)
    chain.faults.unplugged = True
    with pytest.raises(DeviceGoneError, match="emulated") as gone:
        bus.sync_read([1, 2], 132, 4)
    assert isinstance(gone.value.__cause__, OSError)
    assert not port.is_using
    with pytest.raises(DeviceGoneError):
        bus.send(bus.prepare_sync_write(116, 4, {3: bytes(4)}))
    chain.faults.unplugged = False
    port._rx, port._rx_at = encode_status(1, 0, bytes(4)), 0
    chain.faults.unplugged = True
    with pytest.raises(OSError, match="disconnected"):
        port.readPort(11)
