"""``whexar bench robot``: the CPU the whole controller takes, on real time, bus over a pty.

The robot's graph (``config/graphs/walk.toml``: the bus scheduler, the sensor-board
and IMU readers, six leg actors, the coordinator, a command source) runs on real
time with its servo bus and its sensor board on two pseudo-terminals to ``whexar
emulate --board`` in another process, as the U2D2 and the Mega's USB line would carry
them: the controller reads the board's frames through pyserial-asyncio as on the
robot. The IMU is the graph's in-process emulated LSM9DS1 (an I²C bus cannot be put
on a pty); its emulation is counted. It stands up, then walks the tripod gait. Measured after
the stand-up, in the runtime's process (all threads), per completed bus cycle:

* **core_pct** — process CPU time over wall time: the share of one core the
  controller takes. Target ≤ 25 % here; a Raspberry Pi 4's core is about 3–4×
  slower (issue "On the robot…", item 7).
* **cpu_ms_per_cycle** — process CPU time per bus cycle (a ``ServoStates`` on
  ``servo-state``), against the same 25 % of the cycle's period.
* **cycle_hz** — bus cycles per second, against the bus limit's 98 % for the
  graph's read plan with the goal writes the walk made (the scheduler writes only
  the goals that changed; ``BusStats`` counts the bytes): the controller must not
  slow the bus.

The emulators' own process is not counted: on the robot the servos and the board do
that work.
"""

from __future__ import annotations

import json
import math
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Final

from whexar.actors.graph import robot_graph
from whexar.actors.messages import BusStats
from whexar.bench import Figure, Progress, Report
from whexar.bench.bus import emulators_process, plan_limit
from whexar.bus.emulator.timing import TimingModel
from whexar.bus.plan import PRESETS
from whexar.config import RobotConfig
from whexar.runtime.clock import run as run_loop
from whexar.runtime.supervisor import Runtime
from whexar.runtime.wiring import build_graph

CORE_TARGET_PCT: Final = 25.0
"""The controller's share of one core here (item 7: a Pi 4 core is 3–4× slower)."""
STAND_S: Final = 4.0
"""Start-up and stand-up before the measurement (the stand-up takes about 2.4 s)."""
WALK_SPEED_M_S: Final = 0.1
SHARE_OF_LIMIT: Final = 0.98
"""The bus cycle rate must stay within 2 % of its limit (as ``whexar bench bus``)."""


@dataclass(frozen=True)
class Measured:
    """What ``seconds`` of walking took (:func:`measure`)."""

    core_pct: float
    cpu_ms_per_cycle: float
    cycle_hz: float
    cycles: int
    bytes_per_cycle: float
    """Bus bytes per cycle, reads and writes, as the scheduler counted them (``BusStats``)."""


def measure(seconds: float = 10.0) -> Measured:
    """The controller's CPU and bus over ``seconds`` of walking after the stand-up."""
    marks: list[tuple[float, float]] = []
    stats: list[tuple[float, BusStats]] = []

    def observe(channel: str, msg: object) -> None:
        if channel == "servo-state":
            marks.append((time.perf_counter(), time.process_time()))
        elif isinstance(msg, BusStats):
            stats.append((time.perf_counter(), msg))

    with tempfile.TemporaryDirectory() as folder, emulators_process() as (pty, board):
        script = Path(folder) / "walk.jsonl"
        lines = [{"t": STAND_S, "gait": "tripod", "vx_m_s": WALK_SPEED_M_S}]
        script.write_text("".join(json.dumps(line) + "\n" for line in lines))
        doc = robot_graph(bus=pty, sensors=board, commands=str(script))

        async def main() -> None:
            runtime = Runtime(build_graph(doc, source="bench robot"), observer=observe)
            await runtime.run(duration=STAND_S + seconds)

        run_loop(main)
    kept = [m for m in marks if m[0] >= marks[0][0] + STAND_S] if marks else []
    walked = [m for t, m in stats if kept and t >= kept[0][0]]
    if len(kept) < 2:
        return Measured(float("inf"), float("inf"), 0.0, 0, math.nan)
    (t0, c0), (t1, c1) = kept[0], kept[-1]
    cycles = len(kept) - 1
    # The counters run from the start: the walk's bytes are the difference of two reports.
    nbytes = math.nan
    if len(walked) >= 2 and walked[-1].cycles > walked[0].cycles:
        a, b = walked[0], walked[-1]
        nbytes = (b.bytes_per_cycle * b.cycles - a.bytes_per_cycle * a.cycles) / (
            b.cycles - a.cycles
        )
    return Measured(
        (c1 - c0) / (t1 - t0) * 100, (c1 - c0) / cycles * 1e3, cycles / (t1 - t0), cycles, nbytes
    )


def walking_limit(plan: str, cfg: RobotConfig, bytes_per_cycle: float) -> float:
    """The bus limit (cycles/s) of ``plan`` with the goal writes the walk made: its bytes
    per cycle less the plan's reads are Sync Write, pure wire time. The plan's own limit
    where the bytes are unknown (every goal written every cycle)."""
    timing = TimingModel(baudrate=cfg.bus.baudrate)
    if not math.isfinite(bytes_per_cycle):
        return plan_limit(PRESETS[plan], cfg, timing)[0]
    _, reads = plan_limit(PRESETS[plan], cfg, timing, write_bytes=0)
    writes = max(0.0, bytes_per_cycle - reads)
    return plan_limit(PRESETS[plan], cfg, timing, write_bytes=writes)[0]


def run(progress: Progress = None, *, seconds: float = 10.0) -> Report:
    """Measure the robot's graph; ``progress`` receives a line per step."""
    say = progress or (lambda _line: None)
    say(
        f"the robot's graph on real time, bus and sensor board over ptys to `whexar "
        f"emulate --board`: "
        f"{STAND_S:g} s to stand, {seconds:g} s of tripod walking…"
    )
    m = measure(seconds)
    core, per_cycle, hz, cycles = m.core_pct, m.cpu_ms_per_cycle, m.cycle_hz, m.cycles
    cfg = RobotConfig()
    (bus,) = (a for a in robot_graph()["actors"] if a["name"] == "bus")
    plan = str(bus["params"].get("plan", "default"))
    limit_hz = walking_limit(plan, cfg, m.bytes_per_cycle)
    period_ms = 1e3 / hz if hz > 0 else float("inf")
    return Report(
        "robot",
        [
            Figure("core_pct", "share of one core", core, "%", CORE_TARGET_PCT),
            Figure(
                "cpu_ms_per_cycle",
                "process CPU per bus cycle",
                per_cycle,
                "ms",
                CORE_TARGET_PCT / 100 * period_ms,
            ),
            Figure(
                "cycle_hz",
                f"bus cycles ({plan} plan, limit {limit_hz:.1f} Hz with the walk's goals)",
                hz,
                "Hz",
                SHARE_OF_LIMIT * limit_hz,
                at_least=True,
            ),
        ],
        notes=[
            f"{cycles} cycles over {seconds:g} s of walking after {STAND_S:g} s of stand-up; "
            "CPU is this process's (all threads): the controller and the emulated IMU; "
            "the servo and sensor-board emulators' process is not counted.",
            "A Raspberry Pi 4 core is about 3-4x slower than this machine's: 25 % here is "
            "most of a Pi core.",
        ],
    )


__all__ = ["CORE_TARGET_PCT", "Measured", "measure", "run", "walking_limit"]
