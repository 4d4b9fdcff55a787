"""A recorded bus played back to dynamixel-sdk answers as the servos did, at the same bus times."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from whexar.bus.emulator.port import EmulatedPort
from whexar.bus.replay import BusReplay, ReplayPort, expects_reply
from whexar.bus.sdk import DxlBus, tap_port
from whexar.testing.bus import servo_chain

GOAL = 116
PRESENT = 132
IDS = list(range(1, 43))

Session = Callable[[DxlBus], list[Any]]


def _session(bus: DxlBus) -> list[Any]:
    """A cycle's worth of SDK calls: pings (one of a silent servo), a sync read with goals
    riding on it, a read that fails half-way, a register read."""
    goals = bus.prepare_sync_write(GOAL, 4, {3: (2100).to_bytes(4, "little")})
    out: list[Any] = [bus.ping(8).ok, bus.ping(9).ok]
    read = bus.sync_read(IDS, PRESENT, 4, then=[goals])
    out += [read.result, read.failed, read.sent, read.data, read.errors]
    ids = [1, 2, 9, 10]
    failed = bus.sync_read(ids, PRESENT, 4)
    out += [failed.result, failed.failed, failed.data]
    reply = bus.read(4, _register())
    out += [reply.result, reply.value]
    return out


def _register() -> Any:
    from whexar.bus.control_table import MODELS

    return next(iter(MODELS.values())).register("present_position")


def _record(session: Session) -> tuple[list[Any], list[tuple[str, float, bytes]], list[float]]:
    """Run ``session`` on the emulator (servo 9 silent), its port tapped: what the SDK
    returned, the link's events, and the bus time each call took."""
    chain = servo_chain()
    chain.faults.silent_until = {9: float("inf")}
    port = EmulatedPort(chain)
    events: list[tuple[str, float, bytes]] = []
    clock = [0.0]
    tap_port(port, lambda d, t, b: events.append((d, t, b)), lambda: clock[0] + port.elapsed_s)
    bus = DxlBus(port)
    results = session(bus)
    clock[0] += port.take_elapsed()
    port.closePort()  # the last reads are reported once something else happens
    return results, events, clock


def _replay(
    events: list[tuple[str, float, bytes]], session: Session
) -> tuple[list[Any], ReplayPort, float]:
    clock = [0.0]
    port = BusReplay(events, baudrate=1_000_000).open(lambda: clock[0])
    results = session(DxlBus(port))
    clock[0] += port.take_elapsed()
    return results, port, clock[0]


def test_a_replayed_session_gets_the_recorded_answers_at_the_recorded_times() -> None:
    recorded, events, clock = _record(_session)
    assert {d for d, _, _ in events} == {"tx", "rx", "timeout"}  # the silent servo timed out
    replayed, port, end = _replay(events, _session)
    assert replayed == recorded
    assert recorded[:2] == [True, False]
    assert port.mismatches == 0
    assert port.unrecorded_timeouts == 0
    assert port.replay.left() == 0  # every recorded packet was written
    assert end == clock[0]  # the session ends at the same bus time, timeouts included


def test_a_different_packet_is_counted_and_named() -> None:
    _, events, _ = _record(_session)

    def other(bus: DxlBus) -> list[Any]:
        return [bus.ping(7).ok]  # the recording pinged servo 8 first

    results, port, _ = _replay(events, other)
    assert port.mismatches == 1
    mismatch = port.first_mismatch
    assert mismatch is not None
    assert mismatch.recorded[4] == 8
    assert mismatch.written[4] == 7
    assert results == [False]  # the recorded answer is servo 8's: the SDK refuses it


def test_past_the_recording_nothing_answers() -> None:
    _, events, _ = _record(lambda bus: [bus.ping(8).ok])
    results, port, _ = _replay(events, lambda bus: [bus.ping(8).ok, bus.ping(8).ok])
    assert results == [True, False]
    assert port.past_end == 1
    assert port.unrecorded_timeouts == 1


def test_which_packets_are_answered() -> None:
    chain_bus = DxlBus(EmulatedPort(servo_chain()))
    sync_write = chain_bus.prepare_sync_write(GOAL, 4, {1: bytes(4)})
    assert not expects_reply(sync_write)
    ping = bytes((0xFF, 0xFF, 0xFD, 0x00, 0x05, 0x03, 0x00, 0x01, 0, 0))
    broadcast_ping = bytes((0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x03, 0x00, 0x01, 0, 0))
    broadcast_write = bytes((0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x06, 0x00, 0x03, 64, 0, 1, 0, 0))
    assert expects_reply(ping)
    assert expects_reply(broadcast_ping)
    assert not expects_reply(broadcast_write)
    assert expects_reply(b"\x01")  # not a packet: the recording says what came back


def test_a_reply_cut_by_a_timeout_is_read_as_it_was_on_the_robot() -> None:
    # On a real port a reply can straggle: part of it, the SDK gives up, the rest late.
    _, events, _ = _record(lambda bus: [bus.ping(8).ok, bus.ping(8).ok])
    (tx1, rx1, tx2, rx2) = events
    assert (tx1[0], rx1[0], tx2[0], rx2[0]) == ("tx", "rx", "tx", "rx")
    status = rx1[2]
    straggling = [
        ("tx", 1.0, tx1[2]),
        ("rx", 1.001, status[:6]),
        ("timeout", 1.010, b""),
        ("rx", 1.012, status[6:]),  # late: cleared by the next transaction, never read
        ("tx", 1.020, tx2[2]),
        ("rx", 1.021, rx2[2]),
    ]
    clock = [0.0]
    port = BusReplay(straggling, baudrate=1_000_000).open(lambda: clock[0])
    bus = DxlBus(port)
    first = bus.ping(8)
    assert not first.ok  # part of a packet, then the timeout: corrupt, as on the robot
    assert port.take_elapsed() == 1.010  # the wait cost what it cost on the recording
    clock[0] = 1.010
    assert bus.ping(8).ok
    assert port.take_elapsed() == 1.021 - 1.010
    assert port.unrecorded_timeouts == 0
    assert port.mismatches == 0
