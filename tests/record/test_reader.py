"""A recording cut anywhere, or damaged, reads up to where it ends and says so; `recover`
makes it a complete file; a recording of another version is refused clearly."""

from __future__ import annotations

import struct
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import pytest
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import Chunk, ChunkIndex
from mcap.writer import CompressionType, Writer

from whexar.record import reader as reader_module
from whexar.record.encoding import RecordingError
from whexar.record.reader import Record, Recording, recover

if TYPE_CHECKING:
    from tests.record.conftest import RecordedRun


def _key(r: Record) -> tuple[str, int, bytes]:
    return (r.topic, r.log_time, r.data)


def test_a_file_cut_anywhere_reads_up_to_where_it_ends(
    recorded_run: RecordedRun, tmp_path: Path
) -> None:
    data = recorded_run.path.read_bytes()
    full = Counter(_key(r) for r in Recording(recorded_run.path).records())
    counts = []
    cut_path = tmp_path / "cut.mcap"
    for fraction in (0.02, 0.1, 0.3, 0.5, 0.77, 0.95, 0.999):
        cut = int(len(data) * fraction)
        cut_path.write_bytes(data[:cut])
        recording = Recording(cut_path)
        records = list(recording.records())  # no exception, whatever the cut
        got = Counter(_key(r) for r in records)
        assert not got - full  # nothing invented
        assert [r.log_time for r in records] == sorted(r.log_time for r in records)
        damage = recording.damage
        assert damage is not None
        assert not recording.complete
        assert damage.offset <= cut
        assert damage.size == cut
        text = damage.describe(cut_path)
        assert "ends early" in text
        assert f"of {cut:,}" in text
        if records:
            assert damage.last_ns is not None
            assert max(r.log_time for r in records) <= damage.last_ns
            assert f"t = {damage.last_ns / 1e9:.3f} s" in text
        counts.append(len(records))
    assert counts == sorted(counts)
    assert counts[0] < counts[-1]
    assert counts[-1] == sum(full.values())  # cut in the index: every message is there


def _chunks(path: Path) -> list[ChunkIndex]:
    """The chunk indexes of a complete recording, as the ``mcap`` package reads them."""
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    assert len(summary.chunk_indexes) >= 3
    return list(summary.chunk_indexes)


def _damaged(path: Path, tmp_path: Path, change: Callable[[bytearray], None]) -> Recording:
    data = bytearray(path.read_bytes())
    change(data)
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    return Recording(bad)


def test_a_damaged_chunk_ends_the_readable_part_there(
    recorded_run: RecordedRun, tmp_path: Path
) -> None:
    third = _chunks(recorded_run.path)[2]
    middle = third.chunk_start_offset + third.chunk_length // 2

    def flip(data: bytearray) -> None:
        data[middle] ^= 0xFF

    recording = _damaged(recorded_run.path, tmp_path, flip)
    records = list(recording.records())
    assert records
    assert recording.damage is not None
    assert recording.damage.offset == third.chunk_start_offset
    assert "a chunk cannot be read" in recording.damage.reason
    assert max(r.log_time for r in records) <= recording.damage.last_ns  # type: ignore[operator]


def test_a_chunk_length_gone_wrong_is_corruption_not_a_cut(
    recorded_run: RecordedRun, tmp_path: Path
) -> None:
    # The walk jumps by the corrupted length to where no record starts.
    second = _chunks(recorded_run.path)[1]
    length_at = second.chunk_start_offset + 1  # opcode, then the record's length
    length = int.from_bytes(recorded_run.path.read_bytes()[length_at : length_at + 8], "little")

    def shorten(data: bytearray) -> None:
        data[length_at : length_at + 8] = (length - 1).to_bytes(8, "little")

    recording = _damaged(recorded_run.path, tmp_path, shorten)
    assert recording.damage is not None
    assert recording.damage.offset == second.chunk_start_offset + 9 + length - 1
    assert "no record starts here" in recording.damage.reason
    assert list(recording.records())  # what comes before is read


def test_recover_makes_a_complete_file_of_the_readable_part(
    recorded_run: RecordedRun, tmp_path: Path
) -> None:
    data = recorded_run.path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    readable = [_key(r) for r in Recording(cut).records()]
    out = tmp_path / "fixed.mcap"
    report = recover(cut, out)
    assert report.messages == len(readable) > 0
    assert "recovered" in report.describe()
    assert "lost" in report.describe()
    fixed = Recording(out)
    assert fixed.complete
    assert fixed.damage is None
    assert [_key(r) for r in fixed.records()] == readable
    assert fixed.metadata["run"] == Recording(recorded_run.path).metadata["run"]
    assert fixed.metadata["whexar.recovered"]["messages"] == str(len(readable))
    assert set(fixed.attachments) == {"wiring.toml", "blob.bin"}
    with open(out, "rb") as f:  # the plain reader needs the summary: it is there now
        assert sum(1 for _ in make_reader(f).iter_messages()) == len(readable)
    with pytest.raises(RecordingError, match="another file"):
        recover(out, out)


@pytest.mark.parametrize(
    ("compression", "chunked"),
    [
        (CompressionType.ZSTD, True),
        (CompressionType.LZ4, True),
        (CompressionType.NONE, True),
        (CompressionType.NONE, False),
    ],
)
def test_records_read_what_the_mcap_package_reads(
    compression: CompressionType, chunked: bool, tmp_path: Path
) -> None:
    """The reader walks chunks itself (faster than ``breakup_chunk``): the same messages,
    topics, times and bytes as the ``mcap`` package, with or without a topic selection, a
    channel first defined mid-file, equal log times, every compression, and messages
    outside chunks."""
    path = tmp_path / "plain.mcap"
    with open(path, "wb") as f:
        writer = Writer(
            f,
            chunk_size=300,
            compression=compression,
            use_chunking=chunked,
        )
        writer.start()
        schema = writer.register_schema("blob", "", b"")
        a = writer.register_channel("/a", "", schema)
        b = writer.register_channel("/b", "", schema)
        for k in range(200):
            writer.add_message(a, 1000 * (k // 2), bytes([k % 256]) * (k % 7), 0, k)
            writer.add_message(b, 1000 * k + 500 - 900 * (k % 3), b"b%d" % k, 0, k)
            if k == 120:
                c = writer.register_channel("/c", "", schema)
            if k >= 120:
                writer.add_message(c, 1000 * k, b"", 0, k)
            if k == 40:  # defined in one chunk, its messages chunks later
                d = writer.register_channel("/d", "", schema)
            if k >= 150:
                writer.add_message(d, 1000 * k, b"d", 0, k)
        writer.finish()  # type: ignore[no-untyped-call]
    with open(path, "rb") as f:
        expected = [
            (channel.topic, m.log_time, m.data)
            for _, channel, m in make_reader(f, validate_crcs=True).iter_messages(
                log_time_order=False
            )
        ]
    recording = Recording(path)
    assert recording.damage is None
    in_file = [_key(r) for r in recording.records(file_order=True, decode=False)]
    assert in_file == expected
    assert [_key(r) for r in recording.records(decode=False)] == sorted(
        expected, key=lambda e: e[1]
    )  # a stable sort: equal times stay in file order
    picked = [_key(r) for r in recording.records(["/c", "/a"], file_order=True)]
    assert picked == [e for e in expected if e[0] in ("/a", "/c")]
    assert len(picked) == 200 + 80
    later = [_key(r) for r in recording.records(["/d"])]
    assert later == [e for e in expected if e[0] == "/d"]
    assert len(later) == 50


def test_a_topic_selection_leaves_chunks_without_it_unread(
    recorded_run: RecordedRun, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Whexar's writer defines every channel before the chunks that use it: a chunk whose
    # Message Indexes name no channel asked for is not even decompressed.
    every = [_key(r) for r in Recording(recorded_run.path).records(decode=False)]
    chunks = len(_chunks(recorded_run.path))
    read: list[int] = []
    decompressed = reader_module._decompressed

    def counted(chunk: Chunk) -> bytes:
        read.append(1)
        return decompressed(chunk)

    monkeypatch.setattr(reader_module, "_decompressed", counted)
    tf = [_key(r) for r in Recording(recorded_run.path).records(["/tf"], decode=False)]
    assert tf == [k for k in every if k[0] == "/tf"]
    assert len(tf) == 1
    assert chunks > 3
    assert len(read) == 1
    # Cut between a chunk's indexes, a selection still reads all the chunk holds.
    data = recorded_run.path.read_bytes()
    cut_path = tmp_path / "cut.mcap"
    cuts = _after_first_index(data)
    assert len(cuts) > 3
    for cut in (*cuts[1:3], cuts[-1], int(len(data) * 0.6), int(len(data) * 0.999)):
        cut_path.write_bytes(data[:cut])
        recording = Recording(cut_path)
        everything = [_key(r) for r in recording.records(decode=False)]
        for topic in {k[0] for k in every}:
            picked = [_key(r) for r in recording.records([topic], decode=False)]
            assert picked == [k for k in everything if k[0] == topic]


def _after_first_index(data: bytes) -> list[int]:
    """Offsets just after the first Message Index of each chunk followed by several."""
    head = struct.Struct("<BQ")
    pos, out, previous = 8, [], 0
    while pos + head.size <= len(data):
        opcode, length = head.unpack_from(data, pos)
        end = pos + head.size + length
        if opcode == Opcode.MESSAGE_INDEX and previous == Opcode.CHUNK:
            nxt = data[end] if end < len(data) else 0
            if nxt == Opcode.MESSAGE_INDEX:
                out.append(end)
        previous, pos = opcode, end
    return out


def _file_with_metadata(path: Path, metadata: dict[str, dict[str, str]]) -> Path:
    with open(path, "wb") as f:
        writer = Writer(f)
        writer.start()
        for name, values in metadata.items():
            writer.add_metadata(name, values)
        writer.finish()  # type: ignore[no-untyped-call]
    return path


def test_a_recording_of_another_version_is_refused_clearly(tmp_path: Path) -> None:
    other = _file_with_metadata(tmp_path / "old.mcap", {"whexar": {"version": "9.4.1"}})
    with pytest.raises(RecordingError, match=r"recorded by whexar 9\.4\.1.*use whexar 9\.4\.x"):
        Recording(other).check_compatible()
    Recording(other).check_compatible("9.4.7")  # the same major.minor reads it
    foreign = _file_with_metadata(tmp_path / "foreign.mcap", {})
    with pytest.raises(RecordingError, match="not a whexar recording"):
        Recording(foreign).check_compatible()


@pytest.mark.parametrize(
    ("content", "match"),
    [(b"", "is empty"), (b"hello, world\n", "not an MCAP file"), (b"\x89MC", "not an MCAP")],
)
def test_what_is_not_mcap_is_a_clear_error(content: bytes, match: str, tmp_path: Path) -> None:
    path = tmp_path / "x.mcap"
    path.write_bytes(content)
    with pytest.raises(RecordingError, match=match):
        Recording(path)
    with pytest.raises(RecordingError, match="cannot read"):
        Recording(tmp_path / "missing.mcap")
