"""The sensor board's frame codec: the grammar of firmware/PROTOCOL.md, resync, and bad input.

Unit tests pin each rule; property tests (hypothesis) feed arbitrary byte streams and
valid frames mangled by insertions, deletions and bit flips, split at arbitrary points.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from whexar.sensors.frame import (
    MAX_FRAME_BYTES,
    Frame,
    FrameDecoder,
    Mode,
    Rejected,
    crc16,
    encode_frame,
)

PROTOCOL = Path(__file__).resolve().parents[2] / "firmware" / "PROTOCOL.md"
THESIS_FRAME = b"ir1=5;ir2=7;accx=0;accy=1;accz=2;fsr0=5;fsr1=7;fsr2=3;fsr3=2;fsr4=6;fsr5=8#"
"""The example frame of Žák 2023, 5.4, byte for byte."""

FSR = (0, 12, 230, 251, 0, 198)


def frames(items: list[Frame | Rejected]) -> list[Frame]:
    return [i for i in items if isinstance(i, Frame)]


def rejected(items: list[Frame | Rejected]) -> list[Rejected]:
    return [i for i in items if isinstance(i, Rejected)]


def good(seq: int, **kw: object) -> bytes:
    values: dict[str, object] = {"ir": (402, 118), "acc": (338, 337, 405), "fsr": FSR}
    values.update(kw)
    return encode_frame(seq=seq, **values)  # type: ignore[arg-type]


# --------------------------------------------------------------------------- the format


def test_crc_is_ccitt_false_with_its_check_value() -> None:
    assert crc16(b"123456789") == 0x29B1


def test_encoder_writes_the_thesis_frame_byte_for_byte() -> None:
    plain = encode_frame(ir=(5, 7), acc=(0, 1, 2), fsr=(5, 7, 3, 2, 6, 8), checksum=False)
    assert plain == THESIS_FRAME


def test_checked_frame_is_the_thesis_frame_with_seq_first_and_crc_last() -> None:
    data = good(4711)
    assert data.startswith(b"seq=4711;ir1=402;ir2=118;accx=338;")
    body, crc = data[:-1].rsplit(b";crc=", 1)
    assert crc == b"%04X" % crc16(body + b";")
    # A thesis-era parser (split on ';' and '=') still finds every value.
    fields = dict(item.split(b"=") for item in data[:-1].split(b";"))
    assert fields[b"ir1"] == b"402"
    assert fields[b"fsr5"] == b"198"


def test_protocol_documents_example_decodes() -> None:
    text = PROTOCOL.read_text()
    examples = re.findall(r"^(seq=\S+#)$", text, flags=re.M)
    assert examples, "PROTOCOL.md shows a checked frame"
    for example in examples:
        (frame,) = FrameDecoder().feed(example.encode())
        assert isinstance(frame, Frame), frame
        assert frame.checked


def test_decodes_every_group() -> None:
    (frame,) = FrameDecoder().feed(good(7))
    assert frame == Frame(
        seq=7, ir=(402, 118), acc=(338, 337, 405), fsr=FSR, checked=True, unknown_keys=0
    )


def test_frame_split_at_every_byte_decodes_once() -> None:
    data = good(3)
    for cut in range(1, len(data)):
        decoder = FrameDecoder()
        assert decoder.feed(data[:cut]) == []
        (frame,) = decoder.feed(data[cut:])
        assert isinstance(frame, Frame)
        assert frame.seq == 3


def test_whitespace_and_nul_between_frames_are_ignored() -> None:
    decoder = FrameDecoder()
    out = decoder.feed(b"\r\n" + good(1) + b"\n\x00 " + good(2) + b"\r\n")
    assert [f.seq for f in frames(out)] == [1, 2]
    assert rejected(out) == []


def test_groups_may_be_absent_but_not_partial() -> None:
    decoder = FrameDecoder()
    (frame,) = decoder.feed(encode_frame(seq=1, fsr=FSR))
    assert isinstance(frame, Frame)
    assert frame.ir is None
    assert frame.acc is None
    (bad,) = decoder.feed(encode_frame(seq=2, fsr=FSR, extra=[("ir1", 5)]))
    assert isinstance(bad, Rejected)
    assert "ir2 missing" in bad.reason


def test_unknown_keys_are_ignored_and_counted() -> None:
    decoder = FrameDecoder()
    (frame,) = decoder.feed(encode_frame(seq=1, fsr=FSR, extra=[("temp", -12), ("vbat", 7400)]))
    assert isinstance(frame, Frame)
    assert frame.unknown_keys == 2
    assert decoder.stats.unknown_keys == 2


@pytest.mark.parametrize(
    ("data", "reason"),
    [
        (encode_frame(seq=1, fsr=FSR, checksum=False), "no checksum"),
        (encode_frame(fsr=FSR), "no sequence number"),
        (good(1)[:-5] + b"12a4#", "malformed checksum"),
        (good(1)[:-5] + b"0000#", "checksum mismatch"),
        (encode_frame(seq=1, fsr=(0, 0, 0, 0, 0, 1024)), "fsr5 = 1024 out of range"),
        (encode_frame(seq=1, fsr=(0, 0, -1, 0, 0, 0)), "fsr2 = -1 out of range"),
        (encode_frame(seq=65536, fsr=FSR), "seq = 65536 out of range"),
        (encode_frame(seq=1, fsr=FSR, extra=[("fsr0", 1)]), "'fsr0' repeated"),
        (encode_frame(seq=1, extra=[("temp", 3)]), "no sensor values"),
        (b"seq=1;fsr0==3;crc=????#", "not key=value"),
        (b"seq=1;Fsr0=3;crc=????#", "not key=value"),
        (b"seq=1;fsr0=3;;crc=????#", "not key=value"),
        (b"seq=1;fsr0=123456;crc=????#", "not key=value"),
    ],
)
def test_bad_frames_are_rejected_with_a_reason(data: bytes, reason: str) -> None:
    if b"crc=????" in data:  # give grammar errors a correct checksum, so grammar is what fails
        body = data[: data.rindex(b"crc=")]
        data = body + b"crc=%04X#" % crc16(body)
    decoder = FrameDecoder()
    (item,) = decoder.feed(data)
    assert isinstance(item, Rejected), item
    assert reason in item.reason
    assert decoder.stats.rejected == 1
    # The decoder is unharmed: the next good frame decodes.
    assert [f.seq for f in frames(decoder.feed(good(9)))] == [9]


def test_thesis_mode_accepts_the_plain_frame_and_still_checks_a_crc() -> None:
    decoder = FrameDecoder(mode="thesis")
    (plain,) = decoder.feed(THESIS_FRAME)
    assert plain == Frame(seq=None, ir=(5, 7), acc=(0, 1, 2), fsr=(5, 7, 3, 2, 6, 8), checked=False)
    (bad,) = decoder.feed(good(1)[:-5] + b"0000#")
    assert isinstance(bad, Rejected)
    (checked,) = decoder.feed(good(2))
    assert isinstance(checked, Frame)
    assert checked.checked


def test_thesis_mode_rejects_a_frame_with_seq_but_no_crc() -> None:
    decoder = FrameDecoder(mode="thesis")
    # A checked frame whose tail was lost: it carries seq, so it needed a crc.
    (cut,) = decoder.feed(b"seq=5;ir1=402;ir2=118#")
    assert isinstance(cut, Rejected)
    assert cut.reason == "seq but no checksum (a checked frame cut short?)"
    # A corrupted byte that became '#' after the IR group: neither half is published.
    data = bytearray(good(6))
    data[data.index(b";accx")] = ord("#")
    out = decoder.feed(bytes(data))
    assert frames(out) == []
    assert rejected(out)[0].reason.startswith("seq but no checksum")
    (after,) = decoder.feed(good(7))  # the next intact frame still decodes
    assert isinstance(after, Frame)
    assert after.seq == 7
    # In checked mode the same cut frame was always refused.
    (checked,) = FrameDecoder().feed(b"seq=5;ir1=402;ir2=118#")
    assert isinstance(checked, Rejected)


def test_thesis_mode_recovers_a_plain_frame_after_garbage() -> None:
    out = FrameDecoder(mode="thesis").feed(b"\xff\xfe" + THESIS_FRAME[:20] + THESIS_FRAME)
    assert len(frames(out)) == 1
    assert len(rejected(out)) == 1


def test_run_without_terminator_is_bounded_and_reported() -> None:
    decoder = FrameDecoder()
    out = decoder.feed(b"x" * 5000)
    assert out == []
    assert len(decoder._buf) <= MAX_FRAME_BYTES
    out = decoder.feed(good(1))
    assert [f.seq for f in frames(out)] == [1]
    assert any("no '#' within" in r.reason for r in rejected(out))


def test_frame_longer_than_the_limit_is_rejected() -> None:
    extra = [(f"k{i}", 1) for i in range(40)]
    (item,) = FrameDecoder().feed(encode_frame(seq=1, fsr=FSR, extra=extra))
    assert isinstance(item, Rejected)
    assert "longer than" in item.reason


# --------------------------------------------------------------------------- sequence


def test_sequence_gaps_wrap_and_restarts() -> None:
    decoder = FrameDecoder()
    seqs = [65533, 65534, 65535, 0, 1, 4, 5, 0, 1, 30000, 20]
    out = frames(decoder.feed(b"".join(good(s) for s in seqs)))
    assert [(f.seq, f.missed, f.restarted) for f in out] == [
        (65533, 0, False),
        (65534, 0, False),
        (65535, 0, False),
        (0, 0, False),  # a wrap, not a restart
        (1, 0, False),
        (4, 2, False),  # 2 and 3 lost
        (5, 0, False),
        (0, 0, True),  # 0 where 6 was due: the board reset
        (1, 0, False),
        (30000, 29998, False),
        (20, 0, True),  # backwards
    ]
    assert decoder.stats.missed == 2 + 29998
    assert decoder.stats.restarts == 2


def test_a_frame_cut_off_by_opening_the_port_is_dropped_quietly() -> None:
    decoder = FrameDecoder()
    decoder.clear(tail_expected=True)  # opened while the board was sending
    tail = good(4)[40:]
    out = decoder.feed(tail + good(5) + tail)
    assert [f.seq for f in frames(out)] == [5]
    assert len(rejected(out)) == 1  # only the first bytes get the benefit of the doubt
    assert decoder.stats.rejected == 1
    assert decoder.stats.garbage_bytes == 2 * len(tail)
    # A first candidate that holds a frame after garbage is reported as usual.
    decoder.clear(tail_expected=True)
    out = decoder.feed(b"noise" + good(6))
    assert [f.seq for f in frames(out)] == [6]
    assert rejected(out)[0].reason.startswith("garbage before a frame")
    # Without tail_expected the tail is a rejected frame.
    assert len(rejected(FrameDecoder().feed(tail))) == 1


def test_clear_forgets_the_sequence_and_the_partial_frame() -> None:
    decoder = FrameDecoder()
    decoder.feed(good(10) + good(11)[:30])
    decoder.clear()
    (frame,) = frames(decoder.feed(good(0)))
    assert frame.missed == 0
    assert not frame.restarted


# --------------------------------------------------------------------------- properties

values_10bit = st.integers(min_value=0, max_value=1023)
frame_values = st.tuples(
    st.tuples(values_10bit, values_10bit),
    st.tuples(values_10bit, values_10bit, values_10bit),
    st.tuples(*[values_10bit] * 6),
)


def split(data: bytes, cuts: list[int]) -> list[bytes]:
    points = sorted({c % (len(data) + 1) for c in cuts})
    return [data[a:b] for a, b in zip([0, *points], [*points, len(data)], strict=True)]


def decode_chunks(decoder: FrameDecoder, chunks: list[bytes]) -> list[Frame | Rejected]:
    out: list[Frame | Rejected] = []
    for chunk in chunks:
        out.extend(decoder.feed(chunk))
    return out


@settings(max_examples=300, derandomize=True)
@given(st.binary(max_size=2000), st.lists(st.integers(min_value=0), max_size=20))
def test_arbitrary_bytes_never_raise_and_chunking_does_not_matter(
    data: bytes, cuts: list[int]
) -> None:
    for mode in ("checked", "thesis"):
        whole = FrameDecoder(mode=mode).feed(data)
        pieces = decode_chunks(FrameDecoder(mode=mode), split(data, cuts))
        assert whole == pieces
        assert all(isinstance(i, Frame | Rejected) for i in whole)


mutation = st.one_of(
    st.tuples(st.just("insert"), st.integers(min_value=0), st.integers(0, 255)),
    # A stray terminator, which cuts a frame short: worth its own odds.
    st.tuples(st.just("insert"), st.integers(min_value=0), st.just(ord("#"))),
    st.tuples(st.just("delete"), st.integers(min_value=0), st.just(0)),
    st.tuples(st.just("flip"), st.integers(min_value=0), st.integers(0, 7)),
)


def mangle(data: bytes, mutations: list[tuple[str, int, int]]) -> bytes:
    out = bytearray(data)
    for kind, where, arg in mutations:
        if kind == "insert":
            out.insert(where % (len(out) + 1), arg)
        elif out:
            at = where % len(out)
            if kind == "delete":
                del out[at]
            else:
                out[at] ^= 1 << arg
    return bytes(out)


@pytest.mark.slow
@settings(max_examples=300, derandomize=True)
@given(
    st.lists(frame_values, min_size=1, max_size=8),
    st.integers(min_value=0, max_value=65535),
    st.lists(
        st.lists(mutation, min_size=1, max_size=4).map(tuple) | st.none(),
        min_size=8,
        max_size=8,
    ),
    st.lists(st.integers(min_value=0), max_size=12),
    st.sampled_from(["checked", "thesis"]),
)
def test_mangled_frames_are_never_published_and_intact_ones_always_are(
    values: list[tuple[tuple[int, ...], ...]],
    first_seq: int,
    mutations: list[tuple[tuple[str, int, int], ...] | None],
    cuts: list[int],
    mode: Mode,
) -> None:
    originals: dict[int, Frame] = {}
    stream = bytearray()
    intact: list[int] = []
    for i, (ir, acc, fsr) in enumerate(values):
        seq = (first_seq + i) % 65536
        data = encode_frame(seq=seq, ir=ir, acc=acc, fsr=fsr)
        originals[seq] = Frame(seq, ir, acc, fsr, checked=True)  # type: ignore[arg-type]
        muts = mutations[i]
        mangled = data if muts is None else mangle(data, list(muts))
        if mangled == data:
            intact.append(seq)
        stream += mangled
    # In thesis mode too, for every frame that carries seq: a checked frame cut short
    # by a corrupted '#' once passed there. A plain frame has nothing to check it
    # by (a damaged "seq=" leaves one), so thesis mode can promise no more.
    decoder = FrameDecoder(mode=mode)
    out = decode_chunks(decoder, split(bytes(stream), cuts))
    published = [f for f in frames(out) if f.seq is not None or mode == "checked"]
    for frame in published:
        original = originals.get(frame.seq)  # type: ignore[arg-type]
        assert original is not None, f"invented frame {frame}"
        assert (frame.ir, frame.acc, frame.fsr) == (original.ir, original.acc, original.fsr)
    got = [f.seq for f in published]
    for seq in intact:
        assert seq in got, f"intact frame {seq} lost: {bytes(stream)!r}"
    assert decoder.stats.frames == len(frames(out))
