"""Field logs for tests: the robot's graph run on a real clock against the servo emulator.

:func:`record_field_log` makes what the robot would record, as close as a machine
without one gets: ``whexar emulate`` serves 42 emulated servos on a pseudo-terminal
in real time (optionally with a fault plan), and ``whexar run`` drives them through
dynamixel-sdk over it, the sensor board and the IMU emulated in its process, a
command script played on the wall clock, everything recorded. Its timers, the pty's
latency and the machine's load make it a log of a real clock: what a replay by time
is for (:mod:`whexar.record.replay`). It takes as long as it records.
"""

from __future__ import annotations

import os
import selectors
import subprocess
import sys
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from whexar.runtime.errors import UsageError

__all__ = ["record_field_log", "write_script"]

ROOT = Path(__file__).resolve().parents[2]
"""The checkout: the graphs and fault plans are named relative to it."""


def write_script(path: str | os.PathLike[str], commands: Iterable[Mapping[str, Any]]) -> Path:
    """A command script (JSON lines, each a time ``t`` and MotionCommand fields)."""
    import json

    out = Path(path)
    out.write_text("".join(json.dumps(dict(c)) + "\n" for c in commands))
    return out


def _line(proc: subprocess.Popen[str], timeout_s: float) -> str:
    assert proc.stdout is not None
    with selectors.DefaultSelector() as sel:
        sel.register(proc.stdout, selectors.EVENT_READ)
        if not sel.select(timeout_s):
            return ""
    return proc.stdout.readline()


def record_field_log(
    path: str | os.PathLike[str],
    *,
    script: str | os.PathLike[str],
    duration_s: float,
    faults: str | os.PathLike[str] | None = None,
    graph: str | os.PathLike[str] = ROOT / "config" / "graphs" / "walk.toml",
    sets: Sequence[str] = (),
    timeout_s: float = 60.0,
) -> Path:
    """Record ``duration_s`` of the robot's graph on a real clock into ``path`` (MCAP),
    its servos emulated over a pty (with the bus fault plan ``faults``), commands from
    ``script``; ``sets`` are ``ACTOR.PARAM=VALUE`` of ``whexar run --set``. Raises
    :class:`UsageError` with what either process said when it fails."""
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    emulate = [sys.executable, "-m", "whexar.cli", "emulate"]
    if faults is not None:
        emulate += ["--faults", str(faults)]
    server = subprocess.Popen(
        emulate, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT, env=env
    )
    try:
        first = _line(server, 20.0)
        if " on " not in first:
            server.kill()
            assert server.stderr is not None
            raise UsageError(f"whexar emulate did not start: {first}{server.stderr.read()}")
        pty = first.split(" on ", 1)[1].split(" at ")[0]
        run = [
            sys.executable,
            "-m",
            "whexar.cli",
            "run",
            str(graph),
            "--set",
            f"bus.port={pty}",
            "--commands",
            str(script),
            "--duration",
            repr(float(duration_s)),
            "--record",
            str(path),
            "--quiet",
        ]
        for item in sets:
            run += ["--set", item]
        done = subprocess.run(
            run, capture_output=True, text=True, cwd=ROOT, env=env, timeout=timeout_s, check=False
        )
        # 3: a safe stop (a fault plan that loses a leg's servo): the log is still whole.
        if done.returncode not in (0, 3) or not Path(path).exists():
            raise UsageError(
                f"whexar run exited {done.returncode}:\n{done.stdout[-2000:]}{done.stderr[-2000:]}"
            )
        return Path(path)
    finally:
        if server.poll() is None:
            server.terminate()
            try:
                server.wait(5.0)
            except subprocess.TimeoutExpired:
                server.kill()
                server.wait()
