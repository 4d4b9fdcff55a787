"""The recorder writes MCAP itself (``whexar.record.writer._McapFile``): the files must stay
valid and indexed for every reader, the ``mcap`` package's indexed and streaming ones,
whexar's own, and Foxglove's, which finds a chunk's messages through its message indexes."""

from __future__ import annotations

import io
import struct
import zlib
from collections import Counter
from pathlib import Path
from typing import TYPE_CHECKING

import pytest
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.reader import make_reader
from mcap.records import Chunk, Message, MessageIndex
from mcap.stream_reader import StreamReader, breakup_chunk

from whexar.record.reader import Recording
from whexar.record.writer import Recorder
from whexar.runtime.messages import Heartbeat

if TYPE_CHECKING:
    from tests.record.conftest import RecordedRun


def _chunk_records(data: bytes, offset: int) -> tuple[Chunk, bytes]:
    stream = ReadDataStream(io.BytesIO(data[offset + 9 :]))
    chunk = Chunk.read(stream)
    if chunk.compression == "zstd":
        records = zstandard.decompress(chunk.data, max_output_size=chunk.uncompressed_size)
    else:
        assert chunk.compression == ""
        records = chunk.data
    return chunk, records


def test_message_indexes_point_at_every_message_of_their_chunk(recorded_run: RecordedRun) -> None:
    data = recorded_run.path.read_bytes()
    with open(recorded_run.path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    assert summary.chunk_indexes
    indexed = 0
    for chunk_index in summary.chunk_indexes:
        chunk, records = _chunk_records(data, chunk_index.chunk_start_offset)
        assert len(records) == chunk.uncompressed_size == chunk_index.uncompressed_size
        assert zlib.crc32(records) == chunk.uncompressed_crc
        assert chunk_index.compressed_size == len(chunk.data)
        in_chunk = [r for r in breakup_chunk(chunk) if isinstance(r, Message)]
        times = [m.log_time for m in in_chunk]
        assert (chunk.message_start_time, chunk.message_end_time) == (min(times), max(times))
        assert (chunk_index.message_start_time, chunk_index.message_end_time) == (
            min(times),
            max(times),
        )
        assert set(chunk_index.message_index_offsets) == {m.channel_id for m in in_chunk}
        for channel_id, offset in chunk_index.message_index_offsets.items():
            assert data[offset] == 0x07  # Message Index
            (length,) = struct.unpack_from("<Q", data, offset + 1)
            index = MessageIndex.read(
                ReadDataStream(io.BytesIO(data[offset + 9 : offset + 9 + length]))
            )
            assert index.channel_id == channel_id
            for log_time, at in index.records:
                assert records[at] == 0x05  # a Message record starts there
                channel, _, time = struct.unpack_from("<HIQ", records, at + 9)
                assert (channel, time) == (channel_id, log_time)
                indexed += 1
    assert indexed == summary.statistics.message_count  # type: ignore[union-attr]


def test_statistics_and_summary_match_the_messages(recorded_run: RecordedRun) -> None:
    with open(recorded_run.path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        stats = summary.statistics
        assert stats is not None
        counts = Counter(channel.id for _, channel, _ in reader.iter_messages())
        times = [m.log_time for _, _, m in reader.iter_messages(log_time_order=False)]
    assert dict(counts) == dict(stats.channel_message_counts)
    assert stats.message_count == sum(counts.values())
    assert (stats.message_start_time, stats.message_end_time) == (min(times), max(times))
    assert stats.channel_count == len(summary.channels)
    assert stats.schema_count == len(summary.schemas)
    assert stats.chunk_count == len(summary.chunk_indexes)
    assert stats.attachment_count == len(summary.attachment_indexes) == 2
    assert stats.metadata_count == len(summary.metadata_indexes) == 3  # whexar, run, whexar.end
    data = recorded_run.path.read_bytes()
    summary_start, offsets_start, crc = struct.unpack_from("<QQI", data, len(data) - 8 - 20)
    footer = data[len(data) - 8 - 29 : len(data) - 8 - 4]
    assert zlib.crc32(footer, zlib.crc32(data[summary_start : len(data) - 8 - 29])) == crc
    assert summary_start < offsets_start


def test_the_streaming_reader_reads_what_the_indexed_one_does(recorded_run: RecordedRun) -> None:
    with open(recorded_run.path, "rb") as f:
        indexed = [
            (channel.topic, m.log_time, m.data)
            for _, channel, m in make_reader(f).iter_messages(log_time_order=False)
        ]
    with open(recorded_run.path, "rb") as f:
        streamed = [
            (channel.topic, m.log_time, m.data)
            for _, channel, m in make_reader(f, validate_crcs=True).iter_messages(
                log_time_order=False
            )
        ]
        f.seek(0)
        raw = list(StreamReader(f, skip_magic=False, emit_chunks=False).records)
    assert sorted(streamed) == sorted(indexed)
    assert sum(isinstance(r, Message) for r in raw) == len(indexed)


@pytest.mark.parametrize("compression", ["lz4", "none"])
def test_every_compression_reads_back(compression: str, tmp_path: Path) -> None:
    path = tmp_path / f"{compression}.mcap"
    with Recorder(path, compression=compression, chunk_size=512) as recorder:
        for i in range(300):
            recorder("beats", Heartbeat(t=(i + 1) / 100, source="beat", seq=i))
            if i % 7 == 0:
                recorder.write_pending()
    recording = Recording(path)
    assert recording.complete
    assert recording.compression == ("" if compression == "none" else compression)
    assert [r.value.seq for r in recording.records() if r.topic == "/beats"] == list(range(300))
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        assert len(summary.chunk_indexes) > 10
        assert sum(1 for _ in reader.iter_messages()) == 300
