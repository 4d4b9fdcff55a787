"""The sensor reader through real serial ports (pseudo-terminals, pyserial-asyncio, real time).

A pty stands in for the board's USB serial device; a symlink stands for its stable
name (as udev's ``/dev/serial/by-id/…``), so unplugging is closing the pty and removing
the link, and plugging back in is a new pty behind the same name.
"""

from __future__ import annotations

import json
import os
import threading
import time
import tty
from pathlib import Path

import pytest

from whexar.actors.messages import SensorFrame, SensorFrameGap, SensorLinkDown, SensorLinkUp
from whexar.cli import main
from whexar.sensors.frame import encode_frame
from whexar.testing import Harness, run_actors
from whexar.testing.sensors import sensor_graph

FSR = (10, 20, 300, 40, 50, 60)


class Board:
    """A pty behind a stable symlink, written to like the board's USB serial device."""

    def __init__(self, link: Path) -> None:
        self.link = link
        self.master = -1
        self.slave = -1

    def plug(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.link.symlink_to(os.ttyname(self.slave))

    def unplug(self) -> None:
        os.close(self.master)
        os.close(self.slave)
        self.link.unlink()

    def send(self, data: bytes) -> None:
        os.write(self.master, data)

    def received(self) -> bytes:
        os.set_blocking(self.master, False)
        try:
            return os.read(self.master, 1024)
        except BlockingIOError:
            return b""


@pytest.mark.slow
@pytest.mark.serial  # real time, a pty
def test_reader_reads_a_serial_port_and_reconnects_after_unplug(tmp_path: Path) -> None:
    board = Board(tmp_path / "ttyBOARD")
    board.plug()
    told: list[bytes] = []

    async def scenario(h: Harness) -> None:
        for seq in range(6):
            board.send(encode_frame(seq=seq, fsr=FSR))
            await h.sleep(0.05)
        told.append(board.received())
        board.unplug()
        await h.wait_for(SensorLinkDown, timeout=2.0)
        board.plug()
        await h.wait_for(SensorLinkUp, timeout=2.0)
        for seq in range(4):
            board.send(encode_frame(seq=seq, fsr=FSR))
            await h.sleep(0.05)
        await h.sleep(0.1)
        told.append(board.received())
        board.unplug()

    result = run_actors(sensor_graph(str(board.link)), scenario=scenario, virtual=False)
    seqs = [f.seq for f in result.messages("frames", of=SensorFrame)]
    assert seqs == [0, 1, 2, 3, 4, 5, 0, 1, 2, 3]
    assert len(result.events(of=SensorLinkUp)) == 2
    assert len(result.events(of=SensorLinkDown)) >= 1
    assert not result.events(of=SensorFrameGap)  # a new connection starts a new sequence
    # After the first frame of each connection, the reader set the board's rate.
    assert told == [b"rate=20#", b"rate=20#"]


@pytest.mark.slow
@pytest.mark.serial  # real time, a pty
def test_cli_prints_frames_and_events_as_json(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    board = Board(tmp_path / "ttyBOARD")
    board.plug()
    config = tmp_path / "robot.toml"
    # No hold-off: the one frame at 0 V is said at once.
    config.write_text("[sensor_board.accelerometer]\nfitted = true\nimplausible_hold_s = 0.0\n")

    def write() -> None:
        time.sleep(0.3)
        board.send(encode_frame(seq=0, ir=(300, 60), acc=(338, 338, 405), fsr=FSR))
        board.send(b"seq=1;ir1=3OO;crc=0000#")  # corrupt: rejected
        # A gap; the left rangefinder unplugged (0 counts); the accelerometer at 0 V.
        board.send(encode_frame(seq=5, ir=(300, 0), acc=(0, 0, 0), fsr=FSR))

    writer = threading.Thread(target=write)
    writer.start()
    try:
        args = ["sensors", "--port", str(board.link), "--config", str(config), "--json"]
        code = main([*args, "--duration", "0.8"])
    finally:
        writer.join()
        board.unplug()
    assert code == 0
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    frames = [r for r in lines if r["kind"] == "frame"]
    events = {r["event"]: r for r in lines if r["kind"] == "event"}
    assert [f["seq"] for f in frames] == [0, 5]
    first = frames[0]
    assert first["raw"]["ir1"] == 300
    assert first["raw"]["fsr2"] == 300
    assert first["ir_distance_m"][0] == pytest.approx(0.315, abs=0.001)  # eq. 5.5
    assert first["ir_distance_m"][1] is None  # 60 counts: beyond 150 cm…
    assert first["ir_status"] == ["range", "clear"]  # …which is "clear"
    assert first["loads"] == list(FSR)
    assert first["contacts"] == [False, False, True, False, False, False]
    assert first["roll_deg"] == pytest.approx(0.34, abs=0.01)
    second = frames[1]
    assert second["ir_distance_m"][1] is None
    assert second["ir_status"] == ["range", "no_reading"]  # 0 counts: unplugged
    assert second["roll_deg"] is None  # (-5, -5, -5) g is not gravity
    assert events["AccelImplausible"]["seq"] == 5
    assert events["AccelImplausible"]["magnitude_g"] == pytest.approx(8.66, abs=0.01)
    assert events["SensorFrameRejected"]["reason"] == "checksum mismatch"
    assert events["SensorFrameGap"]["missed"] == 4
    assert events["SensorLinkStale"]["last_seq"] == 5
    assert frames[1]["missed"] == 4


@pytest.mark.slow
@pytest.mark.serial  # 0.3 s of real time to say the port is missing
def test_cli_on_a_missing_port_reports_it_and_keeps_looking(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["sensors", "--port", str(tmp_path / "none"), "--duration", "0.3"])
    out = capsys.readouterr().out
    assert code == 0
    assert "link DOWN" in out
    assert "No such file or directory" in out
    assert "STALE" not in out  # no frame ever came: nothing went stale
