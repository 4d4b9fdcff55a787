"""The fast codec equals the plain one it replaced: a byte-table CRC, framing by concatenation,
and the decoder as first written, byte for byte and counter for counter."""

from __future__ import annotations

import random

from hypothesis import given, settings
from hypothesis import strategies as st

from whexar.bus.protocol import (
    BROADCAST_ID,
    HEADER,
    MAX_LENGTH,
    Instruction,
    Packet,
    PacketDecoder,
    crc16,
    encode_fast_status,
    encode_instruction,
    encode_status,
    stuff,
    unstuff,
)


def _plain_table() -> list[int]:
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return table


TABLE = _plain_table()


def plain_crc16(data: bytes, crc: int = 0) -> int:
    """The byte-at-a-time table loop."""
    for byte in data:
        crc = ((crc << 8) & 0xFFFF) ^ TABLE[(crc >> 8) ^ byte]
    return crc


def plain_frame(packet_id: int, body: bytes) -> bytes:
    body = body.replace(b"\xff\xff\xfd", b"\xff\xff\xfd\xfd")
    length = len(body) + 2
    head = HEADER + bytes((packet_id, length & 0xFF, length >> 8))
    crc = plain_crc16(head + body)
    return head + body + bytes((crc & 0xFF, crc >> 8))


class PlainDecoder:
    """:class:`PacketDecoder` as first written, on :func:`plain_crc16`."""

    def __init__(self, max_length: int = MAX_LENGTH) -> None:
        self.max_length = max_length
        self.buf = bytearray()
        self.garbage_bytes = self.crc_errors = self.packets = 0

    def feed(self, data: bytes) -> list[Packet]:
        buf = self.buf
        buf += data
        out: list[Packet] = []
        while True:
            at = buf.find(HEADER)
            if at < 0:
                keep = 0
                for k in (3, 2, 1):
                    if len(buf) >= k and buf.endswith(HEADER[:k]):
                        keep = k
                        break
                self.garbage_bytes += len(buf) - keep
                del buf[: len(buf) - keep]
                return out
            if at:
                self.garbage_bytes += at
                del buf[:at]
            if len(buf) < 7:
                return out
            packet_id, length = buf[4], buf[5] | (buf[6] << 8)
            if packet_id in (0xFD, 0xFF) or length < 3 or length > self.max_length:
                self.garbage_bytes += 1
                del buf[:1]
                continue
            total = 7 + length
            if len(buf) < total:
                return out
            if plain_crc16(bytes(buf[: total - 2])) != buf[total - 2] | (buf[total - 1] << 8):
                self.crc_errors += 1
                self.garbage_bytes += 1
                del buf[:1]
                continue
            body = bytes(buf[7 : total - 2])
            del buf[:total]
            if body[0] == Instruction.STATUS:
                if len(body) < 2:
                    self.garbage_bytes += total
                    continue
                if packet_id != BROADCAST_ID:
                    body = unstuff(body)
                packet = Packet(packet_id, body[0], body[2:], body[1])
            else:
                body = unstuff(body)
                packet = Packet(packet_id, body[0], body[1:])
            self.packets += 1
            out.append(packet)


# Bytes that make headers and stuffing likely, mixed with any byte.
tricky = st.lists(
    st.one_of(st.sampled_from([0xFF, 0xFD, 0x00, 0x55, 0xFE]), st.integers(0, 255)), max_size=80
).map(bytes)


@settings(max_examples=500, deadline=None)
@given(st.one_of(st.binary(max_size=300), tricky), st.integers(0, 0xFFFF))
def test_crc16_is_the_byte_table_loop(data: bytes, start: int) -> None:
    expected = plain_crc16(data, start)
    assert crc16(data, start) == expected
    assert crc16(bytearray(data), start) == expected
    assert crc16(memoryview(data), start) == expected


def test_crc16_every_length_and_start() -> None:
    rng = random.Random(5)
    for n in range(0, 70):
        for _ in range(30):
            data = rng.randbytes(n)
            start = rng.choice([0, 0xFFFF, rng.randrange(0x10000)])
            assert crc16(data, start) == plain_crc16(data, start)
    assert crc16(b"") == 0
    assert crc16(b"", 0x1234) == 0x1234
    big = rng.randbytes(70_001)  # beyond the cached unpackers
    assert crc16(big, 7) == plain_crc16(big, 7)


@settings(max_examples=400, deadline=None)
@given(st.integers(0, 252), st.integers(0, 255), st.one_of(tricky, st.binary(max_size=200)))
def test_status_and_instruction_packets_are_the_plain_frames(
    pid: int, byte: int, params: bytes
) -> None:
    assert encode_status(pid, byte, params) == plain_frame(pid, bytes((0x55, byte)) + params)
    assert encode_status(pid, byte, bytearray(params)) == encode_status(pid, byte, params)
    assert encode_status(pid, byte, list(params)) == encode_status(pid, byte, params)  # type: ignore[arg-type]
    assert encode_instruction(pid, byte, params) == plain_frame(pid, bytes((byte,)) + params)
    assert encode_instruction(BROADCAST_ID, byte, params) == plain_frame(
        BROADCAST_ID, bytes((byte,)) + params
    )
    assert stuff(params) == params.replace(b"\xff\xff\xfd", b"\xff\xff\xfd\xfd")


def test_fast_status_running_crcs_are_the_plain_ones() -> None:
    rng = random.Random(9)
    for _ in range(200):
        entries = [
            (rng.randrange(256), rng.randrange(253), rng.randbytes(rng.randrange(0, 9)))
            for _ in range(rng.randrange(1, 8))
        ]
        packet = encode_fast_status(entries)
        at = 8
        for _, _, data in entries:
            at += len(data) + 2
            assert plain_crc16(packet[:at]) == int.from_bytes(packet[at : at + 2], "little")
            at += 2


def _stream(rng: random.Random) -> bytes:
    """Packets (some stuffed, some corrupt, some cut), garbage and false headers."""
    out = bytearray()
    for _ in range(rng.randrange(1, 8)):
        kind = rng.randrange(6)
        params = bytes(rng.choice([0xFF, 0xFD, 0x00, rng.randrange(256)]) for _ in range(30))
        params = params[: rng.randrange(0, 30)]
        pid = rng.choice([1, 7, 252, BROADCAST_ID])
        if kind == 0:
            packet = bytearray(encode_instruction(pid, rng.randrange(256), params))
        elif kind == 1 and pid != BROADCAST_ID:
            packet = bytearray(encode_status(pid, rng.randrange(256), params))
        elif kind == 2:
            packet = bytearray(encode_fast_status([(0, 3, params[:4]), (0, 4, params[4:8])]))
        elif kind == 3:
            packet = bytearray(plain_frame(pid, bytes((0x55,)) + params[:1]))  # ERR may be missing
        elif kind == 4:
            packet = bytearray(rng.choice([HEADER, HEADER[:3], b"\xff\xff\xfd\x00\xfd"]))
            packet += rng.randbytes(rng.randrange(0, 12))
        else:
            packet = bytearray(rng.randbytes(rng.randrange(0, 20)))
        if packet and rng.random() < 0.2:  # corrupt one byte
            packet[rng.randrange(len(packet))] ^= 1 << rng.randrange(8)
        if packet and rng.random() < 0.1:  # cut short
            del packet[rng.randrange(len(packet)) :]
        out += packet
    return bytes(out)


def test_decoder_is_the_plain_decoder() -> None:
    rng = random.Random(11)
    for _ in range(400):
        max_length = rng.choice([MAX_LENGTH, 0xFFFF, 20])
        ours, plain = PacketDecoder(max_length=max_length), PlainDecoder(max_length)
        data = b"".join(_stream(rng) for _ in range(3))
        at = 0
        while at < len(data):
            step = rng.choice([1, 2, 7, 11, 64, len(data)])
            chunk = data[at : at + step]
            at += step
            feed = rng.choice([bytes, bytearray, memoryview])
            assert ours.feed(feed(chunk)) == plain.feed(chunk)
            assert (ours.garbage_bytes, ours.crc_errors, ours.packets, ours.pending) == (
                plain.garbage_bytes,
                plain.crc_errors,
                plain.packets,
                len(plain.buf),
            )
            if rng.random() < 0.05:
                ours.reset()
                plain.garbage_bytes += len(plain.buf)
                plain.buf.clear()
        for packet in ours.feed(b""):
            assert isinstance(packet.params, bytes)
