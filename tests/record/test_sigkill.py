"""A recording process killed with SIGKILL leaves a file readable up to its last flush
(at most ``flush_period_s`` before the kill), and `recover` makes it a complete file; a
runtime killed beside its recording process leaves a complete file."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from whexar.record.reader import Recording, recover
from whexar.runtime.clock import monotonic, wait_until

# Small messages at 500 Hz fill a 64 KiB chunk in about 2 s, so only the periodic flush
# (every 0.5 s by default) saves the last second: the case that matters.
CHILD = """
import sys
from whexar.record.writer import Recorder
from whexar.runtime.clock import monotonic, wait_until
from whexar.runtime.messages import Heartbeat

recorder = Recorder(sys.argv[1])
print("ready", flush=True)
seq = 0
while True:
    now = monotonic()
    recorder("beats", Heartbeat(t=now, source="child", seq=seq))
    recorder.write_pending()
    seq += 1
    wait_until(now + 0.002)
"""


def _kill_after(tmp_path: Path, recorder: str, seconds: float) -> tuple[Path, float]:
    """Run CHILD with ``recorder`` (``module:Class``), kill it with SIGKILL after
    ``seconds``; the file's path and the time of the kill."""
    path = tmp_path / "killed.mcap"
    script = tmp_path / "child.py"
    module, name = recorder.split(":")
    script.write_text(
        CHILD.replace("whexar.record.writer import Recorder", f"{module} import {name} as Recorder")
    )
    child = subprocess.Popen(
        [sys.executable, str(script), str(path)],
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)},
    )
    try:
        assert child.stdout is not None
        assert child.stdout.readline() == "ready\n"
        wait_until(monotonic() + seconds)
        killed_at = monotonic()
        child.send_signal(signal.SIGKILL)
    finally:
        child.kill()
        child.wait(timeout=10)
    assert child.returncode == -signal.SIGKILL
    return path, killed_at


@pytest.mark.slow
@pytest.mark.serial  # the loss is measured on the wall clock
def test_a_killed_recording_reads_back_to_its_last_half_second(tmp_path: Path) -> None:
    path, killed_at = _kill_after(tmp_path, "whexar.record.writer:Recorder", 1.5)
    recording = Recording(path)
    assert not recording.complete
    assert recording.damage is not None
    times = [r.value.t for r in recording.records() if r.topic == "/beats"]
    assert len(times) > 200
    lost_s = killed_at - times[-1]
    # Killed 1.5 s in, just before the third flush: the worst case, measured 0.499 s.
    # The bound leaves 0.1 s for a busy machine's scheduling.
    assert 0 <= lost_s < 0.6, f"lost {lost_s:.3f} s"

    fixed = recover(path, tmp_path / "fixed.mcap")
    assert fixed.messages == len(times)
    assert Recording(fixed.output).complete


@pytest.mark.slow
@pytest.mark.serial  # the loss is measured on the wall clock
def test_a_runtime_killed_beside_its_recording_process_leaves_a_complete_file(
    tmp_path: Path,
) -> None:
    path, killed_at = _kill_after(tmp_path, "whexar.record.sidecar:RecorderProcess", 1.0)
    # The recording process sees its pipe close and ends the file: summary and footer.
    deadline = monotonic() + 20.0
    while not Recording(path).complete and monotonic() < deadline:
        wait_until(monotonic() + 0.05)
    recording = Recording(path)
    assert recording.complete, recording.describe_end()
    seqs = [r.value.seq for r in recording.records() if r.topic == "/beats"]
    assert len(seqs) > 200
    assert seqs == list(range(len(seqs)))
    last = max(r.value.t for r in recording.records() if r.topic == "/beats")
    assert 0 <= killed_at - last < 0.1  # all it had packed (every 2 ms), on a busy machine
