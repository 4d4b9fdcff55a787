"""The emulated board on a pty, in real time, read through a real serial port."""

from __future__ import annotations

import pytest
import serial

from whexar.runtime.clock import monotonic
from whexar.sensors.board_emulator import SensorBoardEmulator
from whexar.sensors.board_pty import BoardPty
from whexar.sensors.frame import Frame, FrameDecoder

pytestmark = [pytest.mark.slow, pytest.mark.serial]  # real time, a pty


def test_frames_arrive_at_the_rate_the_host_asks() -> None:
    board = SensorBoardEmulator(counts={"ir1": 402, "fsr2": 230})
    with BoardPty(board) as pty:
        port = serial.Serial(pty.path, 1_000_000, timeout=0.02)
        try:
            port.reset_input_buffer()
            port.write(b"rate=50#")
            decoder = FrameDecoder()
            decoder.clear(tail_expected=True)
            arrivals: list[tuple[float, Frame]] = []
            end = monotonic() + 1.2
            while monotonic() < end:
                for item in decoder.feed(port.read(4096)):
                    assert isinstance(item, Frame), item
                    arrivals.append((monotonic(), item))
        finally:
            port.close()
        assert pty.error is None
        assert board.commands == [b"rate=50#"]
        assert pty.stats.received_bytes == len(b"rate=50#")
    late = arrivals[3:]  # after the rate took hold
    (t0, first), (t1, last) = late[0], late[-1]
    assert (len(late) - 1) / (t1 - t0) == pytest.approx(50, rel=0.1)
    assert [f.seq for _, f in late] == list(range(first.seq or 0, (last.seq or 0) + 1))
    assert last.ir == (402, 80)
    assert last.fsr == (0, 0, 230, 0, 0, 0)
