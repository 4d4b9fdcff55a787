"""The port a real bus runs on waits for bytes without spinning; probes have a bounded wait."""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Iterator

import pytest

from whexar.bus.emulator.port import EmulatedPort
from whexar.bus.protocol import Instruction
from whexar.bus.sdk import DxlBus, WaitingPortHandler
from whexar.testing.bus import servo_chain


@pytest.fixture
def pty() -> Iterator[tuple[int, WaitingPortHandler]]:
    master, slave = os.openpty()
    port = WaitingPortHandler(os.ttyname(slave))
    assert port.openPort()
    yield master, port
    port.closePort()
    os.close(master)
    os.close(slave)


def _sdk_wait(port: WaitingPortHandler, length: int) -> bytes:
    """What dynamixel-sdk's ``rxPacket`` does while it waits: read, check the timeout, again."""
    got = b""
    while len(got) < length:
        got += port.readPort(length - len(got))
        if len(got) < length and port.isPacketTimeout():
            break
    return got


@pytest.mark.slow
def test_waiting_for_a_silent_servo_costs_no_cpu(pty: tuple[int, WaitingPortHandler]) -> None:
    _, port = pty
    port.setPacketTimeoutMillis(300)
    wall, cpu = time.perf_counter(), time.thread_time()
    assert _sdk_wait(port, 11) == b""
    wall, cpu = time.perf_counter() - wall, time.thread_time() - cpu
    assert wall >= 0.29  # the SDK's timeout is honoured …
    assert cpu < 0.03  # … asleep in select(), not polling (the SDK's own port spins: ~0.3 s)


def test_bytes_are_returned_as_soon_as_they_arrive(pty: tuple[int, WaitingPortHandler]) -> None:
    master, port = pty
    sent: list[float] = []

    def answer() -> None:
        time.sleep(0.05)
        sent.append(time.perf_counter())
        os.write(master, b"\xff\xff\xfd\x00\x01\x04\x00\x55\x00\xa1\x0c")

    threading.Thread(target=answer).start()
    port.setPacketTimeoutMillis(1000)
    got = _sdk_wait(port, 11)
    late = time.perf_counter() - sent[0]
    assert len(got) == 11
    assert late < 0.02  # woken by the bytes, not by the timeout


def test_a_probe_of_a_dead_servo_waits_only_its_bound() -> None:
    chain = servo_chain()
    chain.faults.silent_until = {9: float("inf")}
    port = EmulatedPort(chain)
    bus = DxlBus(port)
    assert not bus.ping(9).ok
    full = port.take_elapsed()  # the SDK's own timeout: 2 × 16 ms latency + 2 ms + bytes
    assert not bus.ping(9, timeout_ms=3.0).ok
    bounded = port.take_elapsed()
    assert full > 0.034
    assert bounded < 0.0035
    assert bus.ping(8, timeout_ms=3.0).ok  # a live servo answers well within it
    assert port.timeout_cap_ms is None  # the bound was for that ping only


def test_writes_riding_on_a_read_go_out_once_its_last_status_is_in() -> None:
    chain = servo_chain()
    seen: list[tuple[float, int]] = []
    chain.hooks.append(lambda _c, t, ps: seen.extend((t, p.instruction) for p in ps))
    port = EmulatedPort(chain)
    bus = DxlBus(port)
    goals = bus.prepare_sync_write(116, 4, {3: (2100).to_bytes(4, "little")})
    ids = list(range(1, 43))
    result = bus.sync_read(ids, 132, 4, then=[goals])
    assert result.ok
    assert result.sent == [0]
    assert len(result.data) == 42  # every status decoded, the write sent in between
    (t_read, first), (t_write, second) = seen
    assert (first, second) == (Instruction.SYNC_READ, Instruction.SYNC_WRITE)
    read_cost = chain.timing.sync_read_s(42, 4, chain.servos[1].return_delay_s)
    assert t_write == pytest.approx(t_read + read_cost)  # after the last status, not before
    port.take_elapsed()
    chain.advance(1.0)
    assert chain.servos[3].goal == 2100


def test_writes_riding_on_a_failed_read_go_out_after_it() -> None:
    chain = servo_chain()
    chain.faults.silent_until = {42: float("inf")}  # the last servo never answers
    bus = DxlBus(EmulatedPort(chain))
    goals = bus.prepare_sync_write(116, 4, {3: (2100).to_bytes(4, "little")})
    result = bus.sync_read(list(range(1, 43)), 132, 4, then=[goals])
    assert not result.ok
    assert result.failed == 42
    assert result.sent == [0]
    assert chain.servos[3].goal == 2100


def test_remove_stuffing_is_the_sdks() -> None:
    """whexar's packet handler unstuffs exactly as dynamixel-sdk's (its fast path skips
    only packets with nothing stuffed)."""
    import random

    from dynamixel_sdk.protocol2_packet_handler import Protocol2PacketHandler

    from whexar.bus.sdk import PacketHandler

    sdk, ours = Protocol2PacketHandler(), PacketHandler()
    rng = random.Random(7)
    stuffed = 0
    for _ in range(3000):
        body = [
            rng.choice([0xFF, 0xFD, 0x00, rng.randrange(256)]) for _ in range(rng.randrange(1, 30))
        ]
        length = len(body) + 2
        packet = [0xFF, 0xFF, 0xFD, 0x00, 0x01, length & 0xFF, length >> 8, *body, 0x12, 0x34]
        stuffed += b"\xff\xff\xfd\xfd" in bytes(packet[5:])
        assert ours.removeStuffing(list(packet)) == sdk.removeStuffing(list(packet))
    assert stuffed > 50  # the slow path was exercised too
