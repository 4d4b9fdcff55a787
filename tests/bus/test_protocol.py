"""Protocol 2.0 codec: the e-manual's worked examples byte for byte, the SDK's CRC and framing."""

from __future__ import annotations

from typing import Any

import pytest
from dynamixel_sdk import PacketHandler
from dynamixel_sdk.protocol2_packet_handler import Protocol2PacketHandler
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from whexar.bus.protocol import (
    ALERT,
    BROADCAST_ID,
    Instruction,
    Packet,
    PacketDecoder,
    PacketError,
    bulk_read_params,
    bulk_write_params,
    crc16,
    encode_fast_status,
    encode_instruction,
    encode_status,
    fast_status_parts,
    parse_bulk_read_params,
    parse_bulk_write_params,
    parse_read_params,
    parse_sync_read_params,
    parse_sync_write_params,
    parse_write_params,
    read_params,
    split_fast_status,
    stuff,
    sync_read_params,
    sync_write_params,
    unstuff,
    write_params,
)
from whexar.errors import UsageError


def h(text: str) -> bytes:
    return bytes.fromhex(text)


def le(value: int, size: int) -> bytes:
    return value.to_bytes(size, "little")


# Worked examples of the ROBOTIS e-manual, "DYNAMIXEL Protocol 2.0" (instruction details).
INSTRUCTIONS = [
    ("ping", 1, Instruction.PING, b"", "FFFFFD00 01 0300 01 194E"),
    ("broadcast ping", BROADCAST_ID, Instruction.PING, b"", "FFFFFD00 FE 0300 01 3142"),
    ("read", 1, Instruction.READ, read_params(132, 4), "FFFFFD00 01 0700 02 84000400 1D15"),
    (
        "write",
        1,
        Instruction.WRITE,
        write_params(116, le(512, 4)),
        "FFFFFD00 01 0900 03 7400 00020000 CA89",
    ),
    (
        "reg write",
        1,
        Instruction.REG_WRITE,
        write_params(104, le(200, 4)),
        "FFFFFD00 01 0900 04 6800 C8000000 AE8E",
    ),
    ("action", 1, Instruction.ACTION, b"", "FFFFFD00 01 0300 05 02CE"),
    ("factory reset", 1, Instruction.FACTORY_RESET, b"\x01", "FFFFFD00 01 0400 06 01 A1E6"),
    ("reboot", 1, Instruction.REBOOT, b"", "FFFFFD00 01 0300 08 2F4E"),
    ("clear", 1, Instruction.CLEAR, h("0144584C22"), "FFFFFD00 01 0800 10 0144584C22 B1DC"),
    (
        "sync read",
        BROADCAST_ID,
        Instruction.SYNC_READ,
        sync_read_params(132, 4, [1, 2]),
        "FFFFFD00 FE 0900 82 84000400 0102 CEFA",
    ),
    (
        "sync write",
        BROADCAST_ID,
        Instruction.SYNC_WRITE,
        sync_write_params(116, 4, {1: le(150, 4), 2: le(170, 4)}),
        "FFFFFD00 FE 1100 83 74000400 0196000000 02AA000000 8287",
    ),
    (
        "fast sync read",
        BROADCAST_ID,
        Instruction.FAST_SYNC_READ,
        sync_read_params(132, 4, [3, 7, 4]),
        "FFFFFD00 FE 0A00 8A 84000400 030704 20F2",
    ),
    (
        "bulk read",
        BROADCAST_ID,
        Instruction.BULK_READ,
        bulk_read_params([(1, 144, 2), (2, 146, 1)]),
        "FFFFFD00 FE 0D00 92 0190000200 0292000100 1A05",
    ),
    (
        "bulk write",
        BROADCAST_ID,
        Instruction.BULK_WRITE,
        bulk_write_params([(1, 32, le(160, 2)), (2, 31, b"\x50")]),
        "FFFFFD00 FE 1000 93 0120000200A000 021F000100 50 B768",
    ),
]

STATUSES = [
    ("ping ID 1", 1, 0, h("060426"), "FFFFFD00 01 0700 55 00 060426 655D"),
    ("ping ID 2", 2, 0, h("060426"), "FFFFFD00 02 0700 55 00 060426 6F6D"),
    ("read", 1, 0, le(166, 4), "FFFFFD00 01 0800 55 00 A6000000 8CC0"),
    ("sync read ID 2", 2, 0, le(2079, 4), "FFFFFD00 02 0800 55 00 1F080000 BABE"),
    ("write", 1, 0, b"", "FFFFFD00 01 0400 55 00 A10C"),
    ("bulk read ID 1", 1, 0, le(119, 2), "FFFFFD00 01 0600 55 00 7700 C369"),
    ("bulk read ID 2", 2, 0, b"\x24", "FFFFFD00 02 0500 55 00 24 8BA9"),
]

FAST_SYNC_STATUS = "FFFFFD00 FE 1900 55 00 03 A6000000 8408 00 07 1F080000 16CA 00 04 FF030000 D19E"
FAST_BULK_STATUS = "FFFFFD00 FE 1400 55 00 03 A6000000 67A4 00 07 A501 2474 00 04 1F D9C1"


@pytest.mark.parametrize(("name", "pid", "inst", "params", "wire"), INSTRUCTIONS)
def test_instruction_packets_match_the_emanual(
    name: str, pid: int, inst: Instruction, params: bytes, wire: str
) -> None:
    packet = encode_instruction(pid, inst, params)
    assert packet == h(wire), name
    assert PacketDecoder().feed(packet) == [Packet(pid, inst, params)]


@pytest.mark.parametrize(("name", "pid", "error", "params", "wire"), STATUSES)
def test_status_packets_match_the_emanual(
    name: str, pid: int, error: int, params: bytes, wire: str
) -> None:
    packet = encode_status(pid, error, params)
    assert packet == h(wire), name
    [decoded] = PacketDecoder().feed(packet)
    assert decoded == Packet(pid, Instruction.STATUS, params, error)
    assert decoded.is_status
    assert decoded.encode() == packet


def test_fast_sync_read_status_matches_the_emanual() -> None:
    entries = [(0, 3, le(166, 4)), (0, 7, le(2079, 4)), (0, 4, le(1023, 4))]
    packet = encode_fast_status(entries)
    assert packet == h(FAST_SYNC_STATUS)
    # Each servo's CRC is the running CRC of the packet so far, header included.
    assert crc16(packet[:14]) == 0x0884
    assert crc16(packet[:22]) == 0xCA16
    assert b"".join(fast_status_parts(entries)) == packet
    assert [len(p) for p in fast_status_parts(entries)] == [16, 8, 8]
    [decoded] = PacketDecoder().feed(packet)
    assert decoded.id == BROADCAST_ID
    assert decoded.error == 0
    assert split_fast_status(decoded, 4) == entries


def test_fast_bulk_read_matches_the_emanual() -> None:
    entries = [(0, 3, le(166, 4)), (0, 7, le(421, 2)), (0, 4, b"\x1f")]
    assert encode_fast_status(entries) == h(FAST_BULK_STATUS)
    [decoded] = PacketDecoder().feed(h(FAST_BULK_STATUS))
    assert split_fast_status(decoded, [4, 2, 1]) == entries
    # The e-manual's Fast Bulk Read instruction shows CRC 20 F2, copied from the
    # Fast Sync Read example; its own bytes give DA 2D.
    params = bulk_read_params([(3, 132, 4), (7, 124, 2), (4, 146, 1)])
    packet = encode_instruction(BROADCAST_ID, Instruction.FAST_BULK_READ, params)
    assert packet[:-2] == h("FFFFFD00 FE 1200 9A 0384000400 077C000200 0492000100")
    assert packet[-2:] == h("DA2D")


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=300), st.integers(0, 0xFFFF))
def test_crc_is_the_sdks(data: bytes, start: int) -> None:
    sdk = Protocol2PacketHandler()
    assert crc16(data, start) == sdk.updateCRC(start, list(data), len(data))


class CapturePort:
    """Just enough of a port for the SDK's TxOnly calls."""

    def __init__(self) -> None:
        self.is_using = False
        self.sent = b""

    def clearPort(self) -> None:
        pass

    def writePort(self, packet: Any) -> int:
        self.sent = bytes(packet)
        return len(self.sent)


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 252), st.integers(0, 0xFFFF), st.binary(min_size=1, max_size=64))
def test_write_packets_equal_the_sdks(pid: int, address: int, data: bytes) -> None:
    assume(b"\xff\xff\xfd" not in bytes((Instruction.WRITE,)) + write_params(address, data))
    port = CapturePort()
    PacketHandler(2.0).writeTxOnly(port, pid, address, len(data), list(data))
    assert encode_instruction(pid, Instruction.WRITE, write_params(address, data)) == port.sent


def test_sdk_4_1_sends_instruction_packets_unstuffed() -> None:
    # txPacket drops addStuffing's result when stuffing lengthens the packet, so
    # the SDK sends FF FF FD unstuffed (LEN 8, not 9). The decoder still reads it
    # right, as a servo would: unstuffing only touches FF FF FD FD.
    port = CapturePort()
    PacketHandler(2.0).writeTxOnly(port, 1, 224, 3, [0xFF, 0xFF, 0xFD])
    assert port.sent[:13] == h("FFFFFD00 01 0800 03 E000 FFFFFD")
    stuffed = encode_instruction(1, Instruction.WRITE, write_params(224, h("FFFFFD")))
    assert stuffed != port.sent
    expected = [Packet(1, Instruction.WRITE, write_params(224, h("FFFFFD")))]
    assert PacketDecoder().feed(port.sent) == expected == PacketDecoder().feed(stuffed)


def test_stuffing_follows_the_emanual_rule() -> None:
    # "When the pattern FF FF FD appears, add FD": FF FF FD → FF FF FD FD.
    assert stuff(h("03 FFFFFD")) == h("03 FFFFFDFD")
    assert stuff(h("FFFFFDFD")) == h("FFFFFDFDFD")
    assert stuff(h("FFFFFF FD")) == h("FFFFFF FDFD")
    assert unstuff(stuff(h("FFFFFD FFFFFD 00"))) == h("FFFFFD FFFFFD 00")
    packet = encode_instruction(1, Instruction.WRITE, write_params(224, h("FFFFFD")))
    # LEN counts the stuffed byte: INST + 2 address + 3 data + 1 stuffing + CRC 2 = 9.
    assert packet == h("FFFFFD00 01 0900 03 E000 FFFFFDFD") + packet[-2:]
    assert crc16(packet[:-2]) == int.from_bytes(packet[-2:], "little")
    assert PacketDecoder().feed(packet)[0].params == write_params(224, h("FFFFFD"))


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=200))
def test_unstuff_inverts_stuff(body: bytes) -> None:
    stuffed = stuff(body)
    assert unstuff(stuffed) == body
    assert b"\xff\xff\xfd" not in stuffed.replace(b"\xff\xff\xfd\xfd", b"")


def test_decoder_resyncs_over_garbage_and_split_feeds() -> None:
    ping = encode_instruction(1, Instruction.PING)
    status = encode_status(7, ALERT | 7)
    bad = bytearray(encode_status(3, 0, b"\x01\x02"))
    bad[-1] ^= 0x40
    stream = (
        b"\x00\xff\xff\xfd\xfd\x13" + ping + b"\xff\xff" + bytes(bad) + status + b"\xff\xff\xfd"
    )
    decoder = PacketDecoder()
    packets: list[Packet] = []
    for byte in stream:  # one byte at a time
        packets += decoder.feed(bytes((byte,)))
    assert packets == [Packet(1, Instruction.PING, b""), Packet(7, Instruction.STATUS, b"", 0x87)]
    assert decoder.crc_errors == 1
    assert decoder.packets == 2
    assert decoder.pending == 3  # a header may be starting
    assert decoder.garbage_bytes == 6 + 2 + len(bad)
    # The same stream in one piece gives the same packets.
    assert PacketDecoder().feed(stream) == packets


def test_decoder_keeps_half_a_packet_until_the_rest_arrives() -> None:
    packet = encode_instruction(BROADCAST_ID, Instruction.SYNC_READ, sync_read_params(126, 10, [1]))
    decoder = PacketDecoder()
    assert decoder.feed(packet[:9]) == []
    assert decoder.pending == 9
    assert decoder.feed(packet[9:]) == [Packet(BROADCAST_ID, 0x82, sync_read_params(126, 10, [1]))]
    assert decoder.pending == 0


def test_decoder_bounds_the_length() -> None:
    # A corrupted LEN of 60000 must not make the decoder wait for 60 kB.
    huge = b"\xff\xff\xfd\x00\x01\x60\xea\x02"
    ping = encode_instruction(2, Instruction.PING)
    decoder = PacketDecoder()
    assert decoder.feed(huge + ping) == [Packet(2, Instruction.PING, b"")]
    assert PacketDecoder(max_length=0xFFFF).feed(huge + ping) == []


@settings(max_examples=200, deadline=None)
@given(
    st.integers(0, 252),
    st.sampled_from([i for i in Instruction if i != Instruction.STATUS]),
    st.binary(max_size=80),
    st.one_of(st.none(), st.integers(0, 255)),
    st.binary(max_size=20),
)
def test_random_packets_round_trip(
    pid: int, inst: Instruction, params: bytes, error: int | None, junk: bytes
) -> None:
    if error is None:
        packet = Packet(pid, int(inst), params)
    else:
        packet = Packet(pid, Instruction.STATUS, params, error)
    wire = packet.encode()
    assert PacketDecoder().feed(wire) == [packet]
    # A false header in the junk costs a CRC error and a rescan, never a packet.
    assert PacketDecoder().feed(junk + wire + wire)[-2:] == [packet, packet]


@settings(max_examples=300, deadline=None)
@given(st.lists(st.binary(max_size=64), max_size=8))
def test_random_garbage_never_raises(chunks: list[bytes]) -> None:
    decoder = PacketDecoder()
    out = [p for chunk in chunks for p in decoder.feed(chunk)]
    assert decoder.packets == len(out)
    assert decoder.pending <= 7 + decoder.max_length


def test_parameter_parsers_invert_the_builders() -> None:
    assert parse_read_params(read_params(132, 4)) == (132, 4)
    assert parse_write_params(write_params(116, b"\x01\x02")) == (116, b"\x01\x02")
    assert parse_sync_read_params(sync_read_params(126, 10, [1, 9, 3])) == (126, 10, [1, 9, 3])
    data = {5: b"\x01\x02", 2: b"\x03\x04"}
    assert parse_sync_write_params(sync_write_params(116, 2, data)) == (116, 2, list(data.items()))
    reads = [(1, 132, 4), (8, 126, 10)]
    assert parse_bulk_read_params(bulk_read_params(reads)) == reads
    writes = [(1, 116, b"\x00\x08\x00\x00"), (3, 64, b"\x01")]
    assert parse_bulk_write_params(bulk_write_params(writes)) == writes
    for parser, bad in [
        (parse_read_params, b"\x01"),
        (parse_sync_write_params, h("74000400 01 0203")),
        (parse_bulk_read_params, h("0190")),
        (parse_bulk_write_params, h("0120000500 A0")),
    ]:
        with pytest.raises(PacketError):
            parser(bad)


def test_builders_refuse_what_cannot_be_sent() -> None:
    with pytest.raises(UsageError, match="expected 4"):
        sync_write_params(116, 4, {1: b"\x00"})
    with pytest.raises(UsageError, match="id = 255"):
        encode_instruction(255, Instruction.PING)
    with pytest.raises(PacketError):
        split_fast_status(Packet(1, Instruction.STATUS, b"", 0), 4)
    [fast] = PacketDecoder().feed(h(FAST_SYNC_STATUS))
    with pytest.raises(PacketError):
        split_fast_status(fast, 5)
