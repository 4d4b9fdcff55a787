"""The device links report their raw bytes: every packet the SDK writes and reads on the
servo bus, every chunk of the sensor link, in order, with the runtime clock's time."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from whexar.bus.protocol import Instruction, PacketDecoder
from whexar.runtime.channels import LinkObserver
from whexar.runtime.devices import DEVICES
from whexar.sensors.board_emulator import SENSOR_BOARD, SensorBoardEmulator
from whexar.sensors.frame import Frame, FrameDecoder
from whexar.testing import run_actors
from whexar.testing.bus import bus_graph
from whexar.testing.sensors import sensor_graph

Seen = list[tuple[str, str, float, bytes]]


@pytest.fixture(autouse=True)
def _clean_registry() -> Iterator[None]:
    yield
    DEVICES.clear(SENSOR_BOARD)


def _observer(seen: Seen) -> LinkObserver:
    def observe(link: str, direction: str, t: float, data: bytes) -> None:
        seen.append((link, direction, t, data))

    return observe


def test_the_servo_bus_reports_every_packet_it_writes_and_reads() -> None:
    seen: Seen = []
    result = run_actors(
        bus_graph("emulator", wiggle={}),
        duration=0.5,
        link_observer=_observer(seen),
    )
    assert result.exit_code == 0
    assert {link for link, *_ in seen} == {"bus"}
    times = [t for _, _, t, _ in seen]
    assert times == sorted(times)
    assert times[-1] <= 0.5 + 0.05
    sent, got = PacketDecoder(), PacketDecoder()
    requests = [p for _, d, _, data in seen if d == "tx" for p in sent.feed(data)]
    replies = [p for _, d, _, data in seen if d == "rx" for p in got.feed(data)]
    assert sent.crc_errors == got.crc_errors == 0
    assert not any(p.is_status for p in requests)
    assert replies
    assert all(p.is_status for p in replies)
    kinds = {p.instruction for p in requests}
    assert {Instruction.PING, Instruction.SYNC_READ, Instruction.SYNC_WRITE} <= kinds
    # The start-up's Fast Sync Read probe: MX firmware does not answer it, the wait times
    # out, and that is reported (no data, at the bus time the SDK gave up).
    assert Instruction.FAST_SYNC_READ in kinds
    timeouts = [(t, data) for _, d, t, data in seen if d == "timeout"]
    assert timeouts
    assert all(data == b"" for _, data in timeouts)


def test_the_sensor_link_reports_the_board_s_frames_and_the_reader_s_commands() -> None:
    DEVICES.register(SENSOR_BOARD, "b", SensorBoardEmulator())
    seen: Seen = []
    result = run_actors(
        sensor_graph("emulator:b"),
        duration=0.5,
        link_observer=_observer(seen),
    )
    assert result.exit_code == 0
    assert {link for link, *_ in seen} == {"sensors"}
    decoder = FrameDecoder()
    frames = [f for _, d, _, data in seen if d == "rx" for f in decoder.feed(data)]
    published = result.log.messages("frames")
    assert [f for f in frames if isinstance(f, Frame)]
    assert len([f for f in frames if isinstance(f, Frame)]) >= len(published) > 0
    assert any(d == "tx" for _, d, _, _ in seen)  # the frame-rate command
