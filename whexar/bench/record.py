"""``whexar bench record``: what recording a run costs the runtime.

Targets (issue 15): recording costs **≤ 5 %** of the runtime's CPU
(:data:`OVERHEAD_TARGET_PCT`) and delays no control cycle by more than **1 ms**
(:data:`DELAY_TARGET_MS`).

What is measured
----------------
The first :data:`BENCH_SECONDS` of the ``course`` scenario, the full runtime and
the physics on virtual time (as ``whexar bench sim``), :data:`REPEATS` times
without a recording and as many times with one, in pairs (every other pair
recorded first), so that both see the machine in the same state:

* **overhead_pct** — the share of the runtime's work the recorder adds, counted in
  instructions (**instructions_pct**, :func:`count_instructions`): the course run
  under Valgrind for :data:`BASE_SECONDS` and for :data:`BENCH_SECONDS`, without
  and with a recording; what the longer runs add over the shorter ones is what a
  simulated second costs, start-ups left out. The counts repeat closely, closer
  without a recording than with one (how the runtime packs and sends follows the
  recording process's pace; docs/recording.md says how closely); they do not see
  the caches. Without Valgrind, the CPU figure below instead.
  The recording is ``whexar sim``'s, written by a process of its own
  (:class:`~whexar.record.sidecar.RecorderProcess`, not counted): the runtime hands
  over, taps the device links and packs;
* **overhead_cpu_pct** — the process's CPU time with a recording over that without,
  less one, the median over the pairs (each pair run back to back). On a shared VM
  a run's CPU time for the same work moves by more than the target, and a recording
  process busy on the other vCPU slows this one as any busy neighbour does: the
  figure moves between runs of this bench by several times the target
  (docs/recording.md), so it is reported, not judged;
* **direct_pct** — the same share counted directly, free of the machine's drift:
  in a run of its own, the packing and sending between cycles (timed) and the
  hand-overs (counted, at the unit cost measured after it); what it leaves out is
  the recorder's wake-ups and its effect on the caches, which the median above has;
* **writer_process_cpu_pct** — that process's CPU (start-up included) against the
  same runtime CPU: what recording costs the machine besides, on another core;
* **max_cycle_delay_ms** — the longest single hand-over between cycles (its p99
  beside it): the runtime packs and sends between cycles as on the robot
  (:meth:`~whexar.record.sidecar.RecorderProcess.run`, every
  :data:`~whexar.record.sidecar.PACK_PERIOD_S`, at most
  :data:`~whexar.record.writer.WRITE_BUDGET_S` at a time), so that is the
  longest a cycle can wait for it. Writes during which Python's garbage
  collector ran are counted apart (**max_cycle_delay_with_gc_ms**,
  **writes_with_gc**): a collection walks the whole process (the simulation's
  message log too) and stalls the loop wherever it falls, for tens of
  milliseconds after 20 s of the course (docs/recording.md);
* **bytes_per_s** — the file's size per simulated second;
* **replay_realtime_factor** — a 60 s log replayed with ``--fast``
  (:mod:`whexar.bench.replay`; target ≥ 50×).
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import functools
import gc
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, Final

from whexar.bench import Figure, Progress, Report
from whexar.bench import replay as replay_bench
from whexar.record.sidecar import RecorderProcess
from whexar.runtime.messages import Heartbeat
from whexar.sim.scenario import DEFAULT_SCENARIO, load_scenario

OVERHEAD_TARGET_PCT: Final = 5.0
DELAY_TARGET_MS: Final = 1.0
BENCH_SECONDS: Final = 10.0
REPEATS: Final = 8
BASE_SECONDS: Final = 2.0
"""The shorter run of the instruction count: what both lengths share (start-up, the
model, the recording process's start) cancels out."""
PROBE_ATTEMPTS: Final = 6
"""Runs of one probe before the count gives up (see ``count_instructions``)."""
_VALGRIND: Final = (
    "valgrind",
    "--tool=cachegrind",
    "--cache-sim=no",
    "--cachegrind-out-file=/dev/null",
)
_REFS = re.compile(rb"^==\d+== I\s+refs:\s+([\d,]+)", re.MULTILINE)


def _probe(seconds: float, record: bool) -> None:
    """The run whose instructions :func:`count_instructions` counts (its own process)."""
    chosen = load_scenario(DEFAULT_SCENARIO).with_overrides(duration_s=seconds)
    with tempfile.TemporaryDirectory() as folder:
        chosen.run(record=Path(folder) / "probe.mcap" if record else None)


def instructions(command: list[str]) -> int:
    """The instructions ``command`` executes, counted by Valgrind (cachegrind, no cache
    simulation): deterministic code counts nearly the same from run to run, whatever
    else the machine does.
    Child processes run natively and are not counted."""
    done = subprocess.run(
        [*_VALGRIND, *command],
        capture_output=True,
        check=False,
    )
    found = _REFS.search(done.stderr)
    if done.returncode != 0 or found is None:
        # The command's own last words, not Valgrind's summary lines.
        lines = done.stderr.decode(errors="replace").splitlines()
        said = [line for line in lines if line.strip() and not line.startswith(("==", "--"))]
        tail = " / ".join(said[-3:]) or "nothing said"
        raise RuntimeError(
            f"valgrind {' '.join(command)} failed (exit status {done.returncode}): {tail}"
        )
    return int(found.group(1).replace(b",", b""))


def count_instructions(
    seconds: float = BENCH_SECONDS, base_s: float = BASE_SECONDS, progress: Progress = None
) -> dict[str, Any] | None:
    """The instructions a recording adds to the runtime's process, per simulated second
    of the course between ``base_s`` and ``seconds``, against those without it
    (``None`` without Valgrind).

    Four runs under Valgrind, two at a time (each far slower than natively): the
    course for ``base_s`` and for ``seconds``, without and with a recording. The
    difference of the two lengths leaves what both share (interpreter start-up, the
    model, the recording process's start) out: what remains is what each simulated
    second costs. Unlike CPU time on a shared machine, the counts repeat.
    """
    if shutil.which("valgrind") is None:
        return None
    say = progress or (lambda _: None)
    say(f"instructions counted by Valgrind: {base_s:g} s and {seconds:g} s, without and with…")
    runs = [(t, record) for t in (base_s, seconds) for record in (False, True)]
    commands = [
        [sys.executable, "-c", f"from whexar.bench.record import _probe; _probe({t!r}, {r!r})"]
        for t, r in runs
    ]

    def counted(command: list[str]) -> int:
        # Under Valgrind, MuJoCo's XML parser now and then refuses an attribute of the
        # model (a different one each time: "unknown error in attribute 'mass'"),
        # in one run of three or four; never natively. Such a run ends early: run it again.
        for _ in range(PROBE_ATTEMPTS - 1):
            try:
                return instructions(command)
            except RuntimeError as exc:
                say(f"{exc}; again…")
        return instructions(command)

    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        counts = dict(zip(runs, pool.map(counted, commands), strict=True))
    plain = counts[seconds, False] - counts[base_s, False]
    recorded = counts[seconds, True] - counts[base_s, True]
    return {
        "instructions_pct": round(100.0 * (recorded / plain - 1.0), 2),
        "instructions_per_s_without": round(plain / (seconds - base_s)),
        "instructions_per_s_with": round(recorded / (seconds - base_s)),
    }


@contextlib.contextmanager
def _timed_writes(
    durations: list[float], collected: list[float] | None = None, calls: list[int] | None = None
) -> Iterator[None]:
    """Time every hand-over between cycles (``write_pending`` with a budget) of every
    recording process while the block runs, and count the hand-overs (``calls[0]``);
    the class's methods are restored after it. A write during which the garbage
    collector ran goes to ``collected`` instead, if given."""
    original = RecorderProcess.write_pending
    handing = {
        name: getattr(RecorderProcess, name) for name in ("__call__", "link_bytes", "transform")
    }
    counted = calls if calls is not None else [0]

    def collections() -> int:  # read per write: a gc.callbacks hook would run per collection
        return sum(generation["collections"] for generation in gc.get_stats())

    @functools.wraps(original)
    def timed(self: RecorderProcess, budget_s: float | None = None) -> int:
        before = collections()
        start = time.perf_counter()
        try:
            return original(self, budget_s)
        finally:
            if budget_s is not None:
                took = time.perf_counter() - start
                gc_ran = collections() != before and collected is not None
                (collected if gc_ran and collected is not None else durations).append(took)

    def counting(method: Callable[..., None]) -> Callable[..., None]:
        @functools.wraps(method)
        def count(*args: Any) -> None:
            counted[0] += 1
            method(*args)

        return count

    RecorderProcess.write_pending = timed  # type: ignore[method-assign]
    for name, method in handing.items():
        setattr(RecorderProcess, name, counting(method))
    try:
        yield
    finally:
        RecorderProcess.write_pending = original  # type: ignore[method-assign]
        for name, method in handing.items():
            setattr(RecorderProcess, name, method)


def _handover_s(folder: str, count: int = 50_000) -> float:
    """CPU seconds of one hand-over (a message; a link's bytes), the mean of both."""
    recorder = RecorderProcess(Path(folder) / "handover.mcap", max_pending=2 * count)
    beat = Heartbeat(t=1.0, source="bench", seq=1)
    data = b"\xff\xff\xfd\x00" * 8
    pending = recorder._pending
    took = 0.0
    for _ in range(count // 100):  # a few hundred pending at a time, as in a run
        start = time.process_time()
        for _ in range(100):
            recorder("beats", beat)
            recorder.link_bytes("bus", "rx", 1.0, data)
        took += time.process_time() - start
        pending.clear()
    recorder.close()
    return took / (2 * count)


def measure(
    seconds: float = BENCH_SECONDS, repeats: int = REPEATS, progress: Progress = None
) -> dict[str, Any]:
    """The figures of ``--json`` (see the module docstring)."""
    say = progress or (lambda _: None)
    chosen = load_scenario(DEFAULT_SCENARIO).with_overrides(duration_s=seconds)
    plain: list[float] = []
    recorded: list[float] = []
    writes: list[float] = []
    collected: list[float] = []
    writer: list[float] = []
    size = 0
    sim_seconds = seconds
    with tempfile.TemporaryDirectory() as folder:
        for k in range(repeats):
            # Every other pair in the other order: a drifting machine favours neither.
            recorded_first = k % 2 == 1
            say(f"pair {k + 1}/{repeats}: with and without a recording…")
            for record in (recorded_first, not recorded_first):
                path = Path(folder) / f"bench-{k}.mcap" if record else None
                cpu = time.process_time()
                result = chosen.run(record=path)
                (recorded if record else plain).append(time.process_time() - cpu)
                if path is not None:
                    size = path.stat().st_size
                    if result.recorder_stats is not None:
                        writer.append(result.recorder_stats.process_cpu_s)
                    sim_seconds = max(result.run.end_time, seconds)
        # The hand-overs timed in a run of their own: timing costs CPU too.
        say("a recorded run with every hand-over timed…")
        calls = [0]
        with _timed_writes(writes, collected, calls):
            chosen.run(record=Path(folder) / "bench-timed.mcap")
        handover = _handover_s(folder)
    # What the runtime side's own code took in the timed run: packing and sending
    # (timed) and the hand-overs (counted, at their unit cost).
    direct = sum(writes) + sum(collected) + calls[0] * handover
    ratios = sorted(100.0 * (w / p - 1.0) for p, w in zip(plain, recorded, strict=True))
    without, with_ = statistics.median(plain), statistics.median(recorded)
    writes.sort()
    return {
        "overhead_cpu_pct": round(statistics.median(ratios), 2),
        "overhead_cpu_pct_range": (round(ratios[0], 2), round(ratios[-1], 2)),
        "direct_pct": round(100.0 * direct / statistics.median(plain), 2),
        "handovers": calls[0],
        "handover_us": round(1e6 * handover, 3),
        "packing_s": round(sum(writes) + sum(collected), 4),
        "writer_process_cpu_pct": round(
            100.0 * statistics.median(writer) / without if writer else 0.0, 2
        ),
        "max_cycle_delay_ms": round(1000.0 * writes[-1], 3) if writes else 0.0,
        "p99_cycle_delay_ms": round(1000.0 * writes[int(0.99 * (len(writes) - 1))], 3)
        if writes
        else 0.0,
        "max_cycle_delay_with_gc_ms": round(1000.0 * max(writes + collected, default=0.0), 3),
        "writes_with_gc": len(collected),
        "bytes_per_s": round(size / sim_seconds),
        "cpu_s_without": round(without, 3),
        "cpu_s_with": round(with_, 3),
        "sim_seconds": round(sim_seconds, 3),
    }


def run(progress: Progress = None) -> Report:
    """The bench: see the module docstring."""
    say = progress or (lambda _: None)
    say(f"course, first {BENCH_SECONDS:g} s simulated, without and with a recording…")
    found = measure(progress=progress)
    counted = count_instructions(progress=progress)
    replayed = replay_bench.measure(progress=progress)
    if counted is not None:
        overhead = counted["instructions_pct"]
        label = "runtime instructions the recorder adds (Valgrind)"
    else:
        overhead = found["overhead_cpu_pct"]
        label = "CPU the recorder adds to the runtime (median of pairs)"
    items = [
        Figure("overhead_pct", label, overhead, "%", OVERHEAD_TARGET_PCT),
        Figure(
            "max_cycle_delay_ms",
            "longest hand-over between cycles (no GC in it)",
            found["max_cycle_delay_ms"],
            "ms",
            DELAY_TARGET_MS,
        ),
        Figure(
            "replay_realtime_factor",
            f"replay of a {replayed['replayed_s']:g} s log, --fast",
            replayed["replay_realtime_factor"],
            "×",
            replay_bench.REPLAY_TARGET,
            at_least=True,
        ),
    ]
    if counted is not None:
        counts = (
            f"instructions per simulated second of the course ({BASE_SECONDS:g}–"
            f"{BENCH_SECONDS:g} s): {counted['instructions_per_s_without'] / 1e9:.3f} G "
            f"without a recording, {counted['instructions_per_s_with'] / 1e9:.3f} G with one"
        )
    else:
        counts = "instructions not counted: Valgrind is not installed (apt-get install valgrind)"
    notes = [
        counts,
        f"{found['sim_seconds']:g} s simulated: {found['cpu_s_without']:g} s of CPU "
        f"without a recording, {found['cpu_s_with']:g} s with one (medians of {REPEATS}); "
        f"CPU time added, median of the pairs: {found['overhead_cpu_pct']:g} % (the pairs "
        f"ranged over {found['overhead_cpu_pct_range'][0]:g} to "
        f"{found['overhead_cpu_pct_range'][1]:g} %: the machine's noise)",
        f"the runtime side's own code, timed and counted: {found['direct_pct']:g} % "
        f"({found['handovers']} hand-overs at {found['handover_us']:g} µs, "
        f"{found['packing_s']:g} s packing and sending)",
        f"the recording process, on another core: {found['writer_process_cpu_pct']:g} % "
        "of the runtime's CPU besides (its start-up included)",
        f"hand-overs between cycles: p99 {found['p99_cycle_delay_ms']:.3f} ms, "
        f"longest {found['max_cycle_delay_ms']:.3f} ms; {found['writes_with_gc']} writes had "
        "a garbage collection in them (the process's, whoever allocated), the longest "
        f"{found['max_cycle_delay_with_gc_ms']:.3f} ms",
        f"file: {found['bytes_per_s'] / 1000:.1f} kB per simulated second",
        f"replay of {replayed['replayed_s']:g} s: {replayed['replay_wall_s']:g} s with --fast, "
        f"{replayed['replay_check_wall_s']:g} s with --check as well "
        f"({replayed['replay_check_realtime_factor']:g}×; quickest of {replay_bench.REPEATS})",
    ]
    data = {
        "overhead_pct": overhead,
        "overhead_cpu_pct": found["overhead_cpu_pct"],
        "instructions_pct": None if counted is None else counted["instructions_pct"],
        "max_cycle_delay_ms": found["max_cycle_delay_ms"],
        "replay_realtime_factor": replayed["replay_realtime_factor"],
        "replay_check_realtime_factor": replayed["replay_check_realtime_factor"],
        "bytes_per_s": found["bytes_per_s"],
        "writer_process_cpu_pct": found["writer_process_cpu_pct"],
        "direct_pct": found["direct_pct"],
    }
    return Report("record", items, notes, data=data)
