"""The servo emulator on a pseudo-terminal, driven by the real dynamixel-sdk."""

from __future__ import annotations

import os
from collections.abc import Iterator

import dynamixel_sdk as dxl
import pytest

from whexar.bus.emulator.pty import PACKET_GAP_S, PtyEmulator
from whexar.config import RobotConfig
from whexar.runtime.clock import monotonic, wait_until
from whexar.testing.bus import servo_chain

CFG = RobotConfig()
IDS = [sid for leg in CFG.legs for sid in leg.servo_ids]
MODEL_NUMBERS = {
    sid: CFG.servo_models[CFG.joints.by_name(joint).model].model_number
    for leg in CFG.legs
    for sid, joint in zip(
        leg.servo_ids,
        ("coxa", "trochanter", "femur", "tibia", "tarsus", "direction", "wheel"),
        strict=True,
    )
}


@pytest.fixture
def port_of() -> Iterator[list[dxl.PortHandler]]:
    opened: list[dxl.PortHandler] = []
    yield opened
    for port in opened:
        port.closePort()


def _open(path: str, opened: list[dxl.PortHandler]) -> dxl.PortHandler:
    port = dxl.PortHandler(path)
    assert port.openPort()  # pyserial accepts 1 Mbps on a pty
    opened.append(port)
    return port


def _sync_read(port: dxl.PortHandler, start: int, length: int) -> tuple[int, dxl.GroupSyncRead]:
    group = dxl.GroupSyncRead(port, dxl.PacketHandler(2.0), start, length)
    for sid in IDS:
        assert group.addParam(sid)
    return group.txRxPacket(), group


def test_sync_read_of_42_servos_through_the_sdk(port_of: list[dxl.PortHandler]) -> None:
    assert len(IDS) == 42
    with PtyEmulator(
        servo_chain(CFG, return_delay_us=CFG.bus.return_delay_time_us), realtime=False
    ) as emulator:
        port = _open(emulator.path, port_of)
        # Addresses 0–9: model number, model information, firmware, ID, baud, return delay.
        result, group = _sync_read(port, 0, 10)
        assert result == dxl.COMM_SUCCESS
        for sid in IDS:
            assert group.getData(sid, 0, 2) == MODEL_NUMBERS[sid]
            assert group.getData(sid, 7, 1) == sid
            assert group.getData(sid, 9, 1) == CFG.bus.return_delay_time_us // 2
        handler = dxl.PacketHandler(2.0)
        assert handler.write1ByteTxRx(port, 5, 65, 1) == (dxl.COMM_SUCCESS, 0)  # LED on
        assert handler.read1ByteTxRx(port, 5, 65)[:2] == (1, dxl.COMM_SUCCESS)
        assert emulator.stats.errors == 0


def test_garbage_and_partial_packets_do_not_stop_the_emulator(
    port_of: list[dxl.PortHandler],
) -> None:
    with PtyEmulator(
        servo_chain(CFG, return_delay_us=CFG.bus.return_delay_time_us), realtime=False
    ) as emulator:
        port = _open(emulator.path, port_of)
        # A garbage run, then a header with an absurd LEN, then half a packet.
        port.writePort(b"\x00\x13\x37" * 10 + b"\xff\xff\xfd\x00\x01\xff\xff")
        port.writePort(b"\xff\xff\xfd\x00\x01\x07\x00\x02\x84")
        # The half packet is dropped when the next bytes come after a gap.
        wait_until(monotonic() + 2 * PACKET_GAP_S)
        handler = dxl.PacketHandler(2.0)
        model, result, error = handler.ping(port, 1)
        assert (result, error) == (dxl.COMM_SUCCESS, 0)
        assert model == MODEL_NUMBERS[1]
        assert emulator.stats.garbage_bytes >= 30
        assert emulator.stats.partial_packets == 1


def test_realtime_sync_read_takes_its_modelled_bus_time(port_of: list[dxl.PortHandler]) -> None:
    with PtyEmulator(
        servo_chain(CFG, return_delay_us=CFG.bus.return_delay_time_us), realtime=True
    ) as emulator:
        port = _open(emulator.path, port_of)
        # Present Current … Present Position (126–135): 42 × 10 bytes. The SDK
        # gives a sync read 8.8 + 34 ms; a process stall on a busy machine can
        # outlast that and time the read out, as it would on the robot. A stall
        # only slows a read, so the fastest of the reads that came back is the
        # bus time; a path that is always too slow fails every attempt.
        walls = []
        results = []
        for _ in range(8):
            start = monotonic()
            result, _group = _sync_read(port, 126, 10)
            results.append(result)
            if result == dxl.COMM_SUCCESS:
                walls.append(monotonic() - start)
                if len(walls) == 3:
                    break
            else:
                # Let the late status packets land before the next request
                # clears the port.
                wait_until(monotonic() + 0.1)
        assert walls, results
        transaction = emulator.last_transaction
        assert transaction is not None
        cost = transaction.cost_s
        # Request 14 + 42 bytes, 42 status packets of 11 + 10 bytes, at 10 µs a byte.
        assert cost > (14 + 42 + 42 * 21) * 10e-6
        assert min(walls) >= 0.9 * cost, (walls, cost)
        print(
            f"sync read 42 × 10 B over the pty: {min(walls) * 1e3:.2f} ms wall, "
            f"{cost * 1e3:.2f} ms modelled"
        )


def test_a_sync_write_occupies_the_bus(port_of: list[dxl.PortHandler]) -> None:
    with PtyEmulator(
        servo_chain(CFG, return_delay_us=CFG.bus.return_delay_time_us), realtime=True
    ) as emulator:
        port = _open(emulator.path, port_of)
        handler = dxl.PacketHandler(2.0)
        writer = dxl.GroupSyncWrite(port, handler, 116, 4)
        for sid in IDS:
            assert writer.addParam(sid, (2048).to_bytes(4, "little"))
        start = monotonic()
        assert writer.txPacket() == dxl.COMM_SUCCESS
        write_cost = (14 + 42 * 5) * 10e-6
        # A ping waits 34 ms for its reply; a stall may outlast it (see above).
        results = [handler.ping(port, 1)[1] for _ in range(3)]
        assert dxl.COMM_SUCCESS in results, results
        ping_cost = emulator.last_transaction.cost_s if emulator.last_transaction else 0.0
        assert monotonic() - start >= 0.9 * (write_cost + ping_cost)


def test_close_is_idempotent_and_the_pty_goes_away() -> None:
    emulator = PtyEmulator(servo_chain(CFG, return_delay_us=CFG.bus.return_delay_time_us)).start()
    path = emulator.path
    assert os.path.exists(path)
    emulator.close()
    emulator.close()
    with pytest.raises(RuntimeError):
        emulator.start()
