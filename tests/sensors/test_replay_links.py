"""Recorded sensor links played back: chunks at their times, the link going away, I²C errors."""

from __future__ import annotations

import errno

import pytest

from whexar.errors import DeviceGoneError
from whexar.runtime.clock import Clock
from whexar.runtime.clock import run as run_loop
from whexar.sensors.replay import BoardReplay, I2CReplay


def test_a_board_link_plays_its_chunks_at_their_times_then_goes_away() -> None:
    replay = BoardReplay(
        [
            ("gone", 0.0, b"cannot open: no such device"),
            ("open", 1.0, b""),
            ("tx", 1.0, b"rate=50#"),
            ("rx", 1.2, b"\x02abc"),
            ("rx", 1.4, b"def\x03"),
            ("gone", 2.0, b"emulated sensor board: unplugged"),
            ("open", 3.0, b""),
            ("rx", 3.5, b"again"),
        ]
    )
    seen: list[tuple[float, bytes | str]] = []

    async def main() -> None:
        clock = Clock()
        with pytest.raises(DeviceGoneError, match="no such device"):
            replay.open(clock)
        await clock.sleep_until(1.0)
        link = replay.open(clock)
        await link.send(b"rate=50#")
        try:
            while True:
                data = await link.receive()
                seen.append((clock.now(), data))
        except DeviceGoneError as exc:
            seen.append((clock.now(), str(exc)))
        await link.aclose()
        await clock.sleep_until(3.0)
        link = replay.open(clock)
        data = await link.receive()
        seen.append((clock.now(), data))

    run_loop(main, virtual=True)
    assert seen == [
        (1.2, b"\x02abc"),
        (1.4, b"def\x03"),
        (2.0, "emulated sensor board: unplugged"),
        (3.5, b"again"),
    ]
    assert replay.mismatches == 0


def test_what_the_reader_sends_is_compared() -> None:
    replay = BoardReplay([("open", 0.0, b""), ("tx", 0.0, b"rate=50#")])

    async def main() -> None:
        link = replay.open(Clock())
        await link.send(b"rate=20#")

    run_loop(main, virtual=True)
    assert replay.mismatches == 1
    assert replay.first_mismatch is not None
    assert (replay.first_mismatch.recorded, replay.first_mismatch.written) == (
        b"rate=50#",
        b"rate=20#",
    )


def test_i2c_calls_get_the_recorded_bytes_and_errors() -> None:
    bus = I2CReplay(
        [
            ("open", 0.0, b""),
            ("tx", 0.0, bytes((0x6B, 0x0F))),
            ("rx", 0.0, bytes((0x68,))),
            ("tx", 0.01, bytes((0x6B, 0x10, 0x60))),
            ("tx", 0.02, bytes((0x6B, 0x28))),
            ("rx", 0.02, bytes(range(6))),
            ("tx", 0.04, bytes((0x6B, 0x28))),
            ("error", 0.04, b"121:Remote I/O error"),
        ]
    )
    opened = bus.opened()
    assert opened.read_byte_data(0x6B, 0x0F) == 0x68
    opened.write_byte_data(0x6B, 0x10, 0x60)
    assert opened.read_i2c_block_data(0x6B, 0x28, 6) == [0, 1, 2, 3, 4, 5]
    with pytest.raises(OSError, match="Remote I/O error") as caught:
        opened.read_i2c_block_data(0x6B, 0x28, 6)
    assert caught.value.errno == errno.EREMOTEIO
    assert caught.value.strerror == "Remote I/O error"
    assert bus.mismatches == 0
    with pytest.raises(OSError, match="past the recording"):  # nothing answers
        opened.read_byte_data(0x6B, 0x0F)
    assert bus.unrecorded_calls == 1


def test_an_i2c_bus_that_could_not_be_opened_is_not_opened_again() -> None:
    bus = I2CReplay([("gone", 0.0, b"cannot open /dev/i2c-1: [Errno 2] No such file")])
    with pytest.raises(DeviceGoneError, match="No such file"):
        bus.opened()
