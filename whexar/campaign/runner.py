"""Running a campaign: every run on local worker processes or as Ray tasks; the results.

Theory of operation
-------------------
:func:`run_one` is one run, in this process: it builds the run's scenario
(:meth:`~whexar.campaign.spec.RunSpec.build`, in a scratch folder), simulates
it on virtual time and computes its metrics. It never raises: an exception
becomes a row with ``outcome = "failed"`` and the error.

:func:`run_campaign` runs the runs it has not finished yet on one of two
back ends, both with one run per CPU at a time:

* *Local processes* (the default): ``workers`` processes, started with
  ``spawn`` (no fork of a process that may hold threads), each taking runs one
  after another over a pipe. A run that takes longer than its ``timeout_s`` of
  wall time has its worker killed; a worker that dies (a segfault, the OOM
  killer) fails its run with the exit code. Either way a fresh worker takes its
  place and the campaign goes on.
* *Ray* (``ray=ADDRESS``, or ``""`` for Ray's default: the cluster
  ``RAY_ADDRESS`` names, one ``ray start`` made on this machine, else a new
  local instance): every run is a task of :func:`run_one` with one CPU and no
  retry, submitted as CPUs free up so that a run's timeout counts from its
  start; a run over its time is cancelled with force.

A run is a function of its :class:`~whexar.campaign.spec.RunSpec` alone:
virtual time, seeded terrains, the same code. So the rows — metrics and the
world's state hash — are the same, bit for bit, whichever back end or worker
ran them; only ``wall_s`` differs.

Each finished row is appended to ``runs.jsonl`` in the output folder at once,
so an interrupted campaign loses only the runs under way; ``resume=True``
keeps the rows that finished ``ok`` with an unchanged
:attr:`~whexar.campaign.spec.RunSpec.key` and runs the rest (failed ones
again). At the end come ``results.json``, ``results.csv``, ``summary.md``
and a plot of every numeric metric (:mod:`whexar.campaign.results`), and the
campaign's built-in report if it names one.
"""

from __future__ import annotations

import contextlib
import json
import multiprocessing
import os
import signal
import tempfile
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any, Final

from whexar.campaign.metrics import compute
from whexar.campaign.rows import CampaignResult, Row
from whexar.campaign.spec import Campaign, RunSpec
from whexar.errors import UsageError
from whexar.runtime.clock import monotonic

RUNS_FILE: Final = "runs.jsonl"
"""Rows as they finish, one JSON object a line: what ``--resume`` reads. Python's JSON,
``NaN`` and ``Infinity`` included, not strict JSON: a kept row must come back exactly as it
was run, so that a resumed campaign's rows equal a fresh one's (``results.json`` is the
strict copy)."""
POLL_S: Final = 0.5
"""How often the runner looks at the clock for timeouts and progress."""
RAY_INSTALL: Final = "--ray needs Ray, which is not installed: pip install 'whexar[cluster]'"


@dataclass(frozen=True)
class Progress:
    """Where a campaign stands: for a progress line."""

    total: int
    done: int
    failed: int
    running: int
    skipped: int
    elapsed_s: float
    latest: Row | None = None

    @property
    def eta_s(self) -> float | None:
        """Wall time left at the pace so far (``None`` before the first run ends)."""
        ran = self.done - self.skipped
        if ran <= 0:
            return None
        return self.elapsed_s / ran * (self.total - self.done)


def run_one(run: RunSpec, recordings: str | None = None) -> Row:
    """Run ``run`` in this process; never raises (a failure is a failed row).

    ``recordings`` is the folder its recording goes to when the campaign keeps them.
    """
    start = monotonic()
    try:
        with tempfile.TemporaryDirectory(prefix="whexar-run-") as scratch:
            scenario = run.build(Path(scratch))
            record = None
            if run.record and recordings is not None:
                Path(recordings).mkdir(parents=True, exist_ok=True)
                record = Path(recordings) / f"{run.id}.mcap"
            result = scenario.run(record=record)
            metrics = compute(run.metrics, result, run.window)
            state_hash = result.world.state_hash()
    except Exception as exc:  # a run's failure is a row, never the campaign's end
        error = f"{type(exc).__name__}: {exc}"
        return _failed(run, error, monotonic() - start, traceback.format_exc())
    return Row(
        run.id,
        run.label,
        run.variation,
        metrics,
        state_hash,
        "ok",
        None,
        monotonic() - start,
        run.key,
    )


def _failed(run: RunSpec, error: str, wall_s: float, details: str | None = None) -> Row:
    return Row(
        run.id, run.label, run.variation, {}, None, "failed", error, wall_s, run.key, details
    )


# --------------------------------------------------------------------------- local processes


def _crashed(code: int | None) -> str:
    """Why a worker ended under its run: a signal (``SIGKILL`` from the OOM killer,
    ``SIGSEGV``) or an exit code."""
    if code is not None and code < 0:
        try:
            return f"worker crashed: killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"worker crashed: killed by signal {-code}"
    return f"worker crashed: exit code {code}"


def _worker(conn: Connection, recordings: str | None) -> None:
    """A worker process: runs what comes down the pipe until it gets ``None``."""
    while True:
        try:
            run = conn.recv()
        except EOFError:
            return
        if run is None:
            return
        conn.send(run_one(run, recordings))


class _Slot:
    """One worker process and the run it has, if any."""

    def __init__(self, ctx: Any, recordings: str | None) -> None:
        self.conn, theirs = ctx.Pipe()
        self.process = ctx.Process(target=_worker, args=(theirs, recordings), daemon=True)
        self.process.start()
        theirs.close()
        self.run: RunSpec | None = None
        self.started = 0.0

    def give(self, run: RunSpec) -> None:
        self.run, self.started = run, monotonic()
        self.conn.send(run)

    def kill(self) -> None:
        self.process.kill()
        self.process.join()
        self.conn.close()

    def stop(self) -> None:
        with contextlib.suppress(BrokenPipeError, OSError):
            self.conn.send(None)
        self.process.join(timeout=5)
        if self.process.is_alive():
            self.process.kill()
            self.process.join()
        self.conn.close()


def _local(
    runs: Sequence[RunSpec],
    workers: int,
    recordings: str | None,
    on_row: Callable[[Row], None],
    on_tick: Callable[[int], None],
) -> None:
    ctx = multiprocessing.get_context("spawn")
    queue = list(reversed(runs))
    slots = [_Slot(ctx, recordings) for _ in range(min(workers, len(runs)))]
    try:
        while queue or any(s.run is not None for s in slots):
            for s in slots:
                if s.run is None and queue:
                    s.give(queue.pop())
            busy = [s for s in slots if s.run is not None]
            on_tick(len(busy))
            ready = wait([s.conn for s in busy] + [s.process.sentinel for s in busy], POLL_S)
            now = monotonic()
            for k, s in enumerate(slots):
                run = s.run
                if run is None:
                    continue
                if s.conn in ready:
                    try:
                        row = s.conn.recv()
                    except (EOFError, OSError):
                        row = None
                    if row is not None:
                        s.run = None
                        on_row(row)
                        continue
                if s.process.sentinel in ready or not s.process.is_alive():
                    s.process.join(timeout=5)  # its exit code is known once it is joined
                    on_row(_failed(run, _crashed(s.process.exitcode), now - s.started))
                elif now - s.started > run.timeout_s:
                    on_row(_failed(run, f"timed out after {run.timeout_s:g} s", now - s.started))
                else:
                    continue
                s.kill()
                slots[k] = _Slot(ctx, recordings)
    finally:
        for s in slots:
            if s.run is not None:
                s.kill()
            else:
                s.stop()


# --------------------------------------------------------------------------- Ray


def _ray(
    runs: Sequence[RunSpec],
    address: str,
    recordings: str | None,
    on_row: Callable[[Row], None],
    on_tick: Callable[[int], None],
) -> None:
    try:
        import ray
    except ImportError:
        raise UsageError(RAY_INSTALL) from None
    started_here = not ray.is_initialized()
    if started_here:
        ray.init(
            address=address or None,
            include_dashboard=False,
            log_to_driver=False,
            configure_logging=False,
        )
    try:
        task: Any = ray.remote(num_cpus=1, max_retries=0)(run_one)
        cpus = max(1, int(ray.cluster_resources().get("CPU", 1)))  # type: ignore[no-untyped-call]
        warm_ray_workers(cpus)
        queue = list(reversed(runs))
        pending: dict[Any, tuple[RunSpec, float]] = {}
        while queue or pending:
            while queue and len(pending) < cpus:
                run = queue.pop()
                pending[task.remote(run, recordings)] = (run, monotonic())
            on_tick(len(pending))
            ready, _ = ray.wait(list(pending), num_returns=1, timeout=POLL_S)
            now = monotonic()
            for ref in ready:
                run, started = pending.pop(ref)
                try:
                    on_row(ray.get(ref))
                except Exception as exc:  # the task died: its worker crashed or was killed
                    on_row(_failed(run, f"{type(exc).__name__}: {exc}", now - started))
            for ref, (run, started) in list(pending.items()):
                if now - started > run.timeout_s:
                    ray.cancel(ref, force=True)
                    del pending[ref]
                    on_row(_failed(run, f"timed out after {run.timeout_s:g} s", now - started))
    finally:
        if started_here:
            ray.shutdown()


def _ready() -> int:
    """A Ray task that only loads what a run needs (whexar, MuJoCo): a started worker."""
    import whexar.sim.run  # noqa: F401 - imported for its cost, paid here once

    return os.getpid()


def warm_ray_workers(count: int) -> None:
    """Start ``count`` Ray workers and import whexar in them before the first run.

    A worker Ray starts for the first task pays about a second to start and import
    whexar and MuJoCo; that is the campaign's start-up, like the local pool's
    spawn, not a run's cost, and the runs' timeouts must not count it.
    """
    import ray

    ready: Any = ray.remote(num_cpus=1, max_retries=0)(_ready)
    ray.get([ready.remote() for _ in range(count)])


# --------------------------------------------------------------------------- the campaign


def default_workers() -> int:
    """As many workers as this process may use CPUs."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def read_rows(path: Path) -> list[Row]:
    """The rows of a ``runs.jsonl``; a line cut by a kill is skipped."""
    rows: list[Row] = []
    if not path.is_file():
        return rows
    for line in path.read_text().splitlines():
        try:
            rows.append(Row.from_json(json.loads(line)))
        except (json.JSONDecodeError, TypeError):
            continue
    return rows


def run_campaign(
    campaign: Campaign,
    out_dir: str | Path,
    *,
    workers: int | None = None,
    ray: str | None = None,
    resume: bool = False,
    progress: Callable[[Progress], None] | None = None,
) -> CampaignResult:
    """Run ``campaign`` (see the module docstring); its files go into ``out_dir``.

    ``workers`` local processes (default: :func:`default_workers`), or Ray tasks
    when ``ray`` is an address (``""``: Ray's default). ``resume`` keeps the
    rows already finished ``ok`` in ``out_dir``. ``progress`` is called as runs
    start and end.
    """
    from whexar.campaign.results import write_results

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    todo = list(campaign.runs)
    journal = out / RUNS_FILE
    kept: dict[str, Row] = {}
    if resume:
        keys = {r.id: r.key for r in todo}
        for row in read_rows(journal):
            if row.outcome == "ok" and keys.get(row.id) == row.key:
                kept[row.id] = row
        journal.write_text("".join(json.dumps(r.to_json()) + "\n" for r in kept.values()))
    else:
        journal.write_text("")
    rows: dict[str, Row] = dict(kept)
    start = monotonic()
    state = {"failed": 0, "running": 0}
    latest: list[Row] = []

    def report() -> None:
        if progress is not None:
            progress(
                Progress(
                    total=len(todo),
                    done=len(rows),
                    failed=state["failed"],
                    running=state["running"],
                    skipped=len(kept),
                    elapsed_s=monotonic() - start,
                    latest=latest[-1] if latest else None,
                )
            )

    def on_row(row: Row) -> None:
        rows[row.id] = row
        latest.append(row)
        state["failed"] += row.outcome == "failed"
        with journal.open("a") as f:
            f.write(json.dumps(row.to_json()) + "\n")
        report()

    def on_tick(running: int) -> None:
        state["running"] = running
        report()

    pending = [r for r in todo if r.id not in kept]
    recordings = str((out / "recordings").resolve()) if any(r.record for r in pending) else None
    report()
    if pending:
        if ray is not None:
            _ray(pending, ray, recordings, on_row, on_tick)
        else:
            _local(pending, workers or default_workers(), recordings, on_row, on_tick)
    state["running"] = 0
    report()
    ordered = [rows[r.id] for r in todo if r.id in rows]
    result = CampaignResult(campaign, ordered, out, monotonic() - start)
    result.files = write_results(result)
    return result


__all__ = [
    "RAY_INSTALL",
    "RUNS_FILE",
    "CampaignResult",
    "Progress",
    "Row",
    "default_workers",
    "read_rows",
    "run_campaign",
    "run_one",
    "warm_ray_workers",
]
