"""``whexar bench sensors``: frame decoding speed and frame-to-message latency.

* **Decoder** — 20,000 checked frames with varying values, fed to
  :class:`~whexar.sensors.frame.FrameDecoder` in 64-byte chunks (a USB
  full-speed packet); frames per second, median of 5 runs. The board sends at
  most 50 frames/s.
* **Latency** — the real :class:`~whexar.actors.sensing.SensorReader` on real
  time reads a pseudo-terminal through pyserial-asyncio while a thread writes
  frames into the other end at 100 Hz. Latency is from the moment the write
  of a frame's last byte returned to the moment its :class:`SensorFrame` was
  published on the reader's channel; median over the frames. A pty hands the
  reader each frame in one piece, as a USB serial adapter hands over a
  packet; the wire time of the frame itself (about 1 ms at 1 Mbps) comes
  before its last byte and is not part of the figure.
"""

from __future__ import annotations

import os
import statistics
import threading
import time
import tty
from collections.abc import Callable

from whexar.actors.messages import SensorFrame
from whexar.actors.sensing.monitor import sensor_graph
from whexar.bench import Figure, Progress, Report
from whexar.runtime.clock import run as run_loop
from whexar.runtime.messages import Message
from whexar.runtime.supervisor import Runtime
from whexar.runtime.wiring import build_graph
from whexar.sensors.frame import FrameDecoder, encode_frame

FRAMES_TARGET_PER_S = 20_000.0
"""Issue target: the decoder keeps up with 400 boards' worth of frames."""
LATENCY_TARGET_MS = 1.0
"""Issue target: last byte of a frame to the published message, median, real time."""
CHUNK_BYTES = 64


def sample_stream(count: int) -> bytes:
    """``count`` checked frames whose values change from frame to frame."""
    return b"".join(
        encode_frame(
            seq=i % 65536,
            ir=((i * 7) % 1024, (i * 13) % 1024),
            acc=(338, 337 + i % 3, 405),
            fsr=tuple((i * (leg + 1) * 31) % 1024 for leg in range(6)),
        )
        for i in range(count)
    )


def decoder_rate(stream: bytes, frames: int) -> float:
    """Frames per second of one decoder fed ``stream`` in 64-byte chunks."""
    decoder = FrameDecoder()
    start = time.perf_counter()
    decoded = 0
    for at in range(0, len(stream), CHUNK_BYTES):
        decoded += len(decoder.feed(stream[at : at + CHUNK_BYTES]))
    elapsed = time.perf_counter() - start
    if decoded != frames:
        raise RuntimeError(f"decoded {decoded} of {frames} frames")
    return frames / elapsed


def latencies_ms(frames: int = 300, rate_hz: float = 100.0) -> list[float]:
    """Per-frame latency (ms) of the reader on a pty; see the module docstring."""
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    written: dict[int, float] = {}
    published: dict[int, float] = {}
    up = threading.Event()

    def observe(channel: str, msg: Message) -> None:
        if channel == "frames" and isinstance(msg, SensorFrame) and msg.seq is not None:
            published[msg.seq] = time.perf_counter()

    def writer() -> None:
        up.wait(5.0)
        time.sleep(0.1)
        for seq in range(frames):
            data = encode_frame(seq=seq, ir=(300, 200), acc=(338, 338, 405), fsr=(seq % 1024,) * 6)
            os.write(master, data)
            written[seq] = time.perf_counter()
            time.sleep(1.0 / rate_hz)

    graph = build_graph(sensor_graph(path, outputs=("frames",)))
    runtime = Runtime(graph, observer=observe)
    duration = 0.5 + frames / rate_hz

    async def main() -> int:
        up.set()
        return await runtime.run(duration=duration)

    thread = threading.Thread(target=writer, daemon=True)
    thread.start()
    try:
        run_loop(main)
    finally:
        thread.join(timeout=5.0)
        os.close(master)
        os.close(slave)
    return [1000.0 * (published[s] - written[s]) for s in written if s in published]


def run(progress: Progress = None, *, frames: int = 20_000, repeats: int = 5) -> Report:
    """Measure and return the figures; ``progress`` receives a line per step."""
    say: Callable[[str], None] = progress or (lambda _line: None)
    stream = sample_stream(frames)
    say(f"decoding {frames:,} frames in {CHUNK_BYTES}-byte chunks ({repeats} runs)…")
    rate = statistics.median(decoder_rate(stream, frames) for _ in range(repeats))
    say("timing frames through a pty into the sensor reader (300 frames at 100 Hz)…")
    lat = latencies_ms()
    if not lat:
        raise RuntimeError("no frame reached the reader through the pty")
    median = statistics.median(lat)
    p95 = statistics.quantiles(lat, n=20)[-1] if len(lat) >= 20 else max(lat)
    return Report(
        "sensors",
        [
            Figure(
                "frames_per_s",
                "frames decoded per second (median)",
                rate,
                "fr/s",
                FRAMES_TARGET_PER_S,
                at_least=True,
            ),
            Figure(
                "latency_ms",
                "last byte to published frame (median)",
                median,
                "ms",
                LATENCY_TARGET_MS,
            ),
        ],
        notes=[
            f"latency over {len(lat)} frames: 95th percentile {p95:.3f} ms, max {max(lat):.3f} ms",
            "the board sends at most 50 frames/s; a frame is about 110 bytes, 1.1 ms at 1 Mbps",
        ],
    )


__all__ = ["decoder_rate", "latencies_ms", "run", "sample_stream"]
