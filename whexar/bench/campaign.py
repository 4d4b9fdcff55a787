"""``whexar bench campaign``: what running a campaign in parallel gains, and what Ray costs.

Targets (issue 16):

* **pool_time_ratio ≤ 0.6** — a campaign of :data:`RUNS` runs finishes on 2 local
  workers in at most 0.6× the wall time it takes on 1.
* **ray_overhead_pct ≤ 5** — on a local Ray instance, a run's overhead (its task's
  round trip less the run's own wall time, measured inside the task) is at most
  5 % of the run's time.

What is measured
----------------
The campaign is the ``wheels`` scenario cut to :data:`DURATION_S` simulated
seconds (standing up, then riding off), in :data:`RUNS` variations of the
slope and the riding speed, so that every run is its own. It runs whole
through :func:`~whexar.campaign.runner.run_campaign` with ``workers=1``, then
``workers=2``: the wall times include starting the worker processes, as a user
sees them. Then a local Ray instance with one CPU runs :data:`RAY_RUNS` of the
runs one after another as tasks of :func:`~whexar.campaign.runner.run_one`
(the task the campaign submits), the round trip timed from submission to the
result. The instance's start, and its worker's — started and whexar imported
in it by :func:`~whexar.campaign.runner.warm_ray_workers` before the first
run, as :func:`run_campaign` does — are the campaign's start-up, not a run's
cost: they are reported apart.

The results of the three back ends are compared too: the rows must be equal
but for their wall times.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Any, Final

from whexar.bench import Figure, Progress, Report
from whexar.campaign import parse_campaign, run_campaign, run_one
from whexar.campaign.runner import warm_ray_workers
from whexar.campaign.spec import Campaign

RUNS: Final = 16
DURATION_S: Final = 4.0
RAY_RUNS: Final = 8
POOL_RATIO_TARGET: Final = 0.6
RAY_OVERHEAD_TARGET_PCT: Final = 5.0


def bench_campaign(runs: int = RUNS, duration_s: float = DURATION_S) -> Campaign:
    """The bench's campaign: ``runs`` variations of the ``wheels`` scenario."""
    slopes = [0, 4, 8, 12]
    speeds = [0.06, 0.09, 0.12, 0.15]
    combos = [(s, v) for s in slopes for v in speeds][:runs]
    return parse_campaign(
        {
            "name": "bench",
            "scenario": "wheels",
            "metrics": ["distance_m", "mean_current_a"],
            "runs": [
                {"duration_s": duration_s, "terrain.slope_deg": s, "commands[0].vx_m_s": v}
                for s, v in combos
            ],
        },
        "<bench campaign>",
    )


def measure(progress: Progress = None) -> dict[str, Any]:
    """The figures of the module docstring, as a dict."""
    import ray

    say = progress or (lambda _: None)
    campaign = bench_campaign()
    found: dict[str, Any] = {"runs": len(campaign.runs), "duration_s": DURATION_S}
    with tempfile.TemporaryDirectory(prefix="whexar-bench-") as scratch:
        walls = {}
        rows = {}
        for workers in (1, 2):
            say(f"{len(campaign.runs)} runs of {DURATION_S:g} s on {workers} worker(s)…")
            start = time.perf_counter()
            result = run_campaign(campaign, Path(scratch) / str(workers), workers=workers)
            walls[workers] = time.perf_counter() - start
            rows[workers] = result.rows
            assert not result.failed, [r.error for r in result.failed]
        found["wall_1_s"], found["wall_2_s"] = walls[1], walls[2]
        found["pool_time_ratio"] = walls[2] / walls[1]
        found["run_wall_s"] = sum(r.wall_s for r in rows[1]) / len(rows[1])
        say(f"Ray: a local instance with 1 CPU, {RAY_RUNS} runs one after another…")
        start = time.perf_counter()
        ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False, configure_logging=False)
        warm_ray_workers(1)  # as run_campaign does: the campaign's start-up, not a run's
        found["ray_init_s"] = time.perf_counter() - start
        try:
            task: Any = ray.remote(num_cpus=1, max_retries=0)(run_one)
            trips: list[float] = []
            own: list[float] = []
            for run in campaign.runs[:RAY_RUNS]:
                start = time.perf_counter()
                row = ray.get(task.remote(run, None))
                trips.append(time.perf_counter() - start)
                own.append(row.wall_s)
                assert row.same_result(rows[1][int(run.id)]), "Ray's row differs from the pool's"
        finally:
            ray.shutdown()
    overheads = [t - w for t, w in zip(trips, own, strict=True)]
    found["ray_overhead_pct"] = 100 * sum(overheads) / sum(own)
    found["ray_first_overhead_s"] = overheads[0]
    found["ray_warm_overhead_ms"] = 1000 * sum(overheads[1:]) / max(1, len(overheads) - 1)
    found["same_rows"] = all(a.same_result(b) for a, b in zip(rows[1], rows[2], strict=True))
    return found


def run(progress: Progress = None) -> Report:
    """The bench: see the module docstring."""
    found = measure(progress)
    items = [
        Figure(
            "pool_time_ratio",
            f"{found['runs']} runs: 2 workers / 1 worker",
            found["pool_time_ratio"],
            "x",
            POOL_RATIO_TARGET,
        ),
        Figure(
            "ray_overhead_pct",
            "Ray: overhead per run, of the run's time",
            found["ray_overhead_pct"],
            "%",
            RAY_OVERHEAD_TARGET_PCT,
        ),
    ]
    notes = [
        f"{found['runs']} runs of {found['duration_s']:g} s simulated: "
        f"{found['wall_1_s']:.1f} s on 1 worker, {found['wall_2_s']:.1f} s on 2; "
        f"a run takes {found['run_wall_s']:.2f} s in its worker",
        f"Ray: the instance and its worker start in {found['ray_init_s']:.1f} s (not counted); "
        f"overhead of the first task {1000 * found['ray_first_overhead_s']:.1f} ms, "
        f"of the others {found['ray_warm_overhead_ms']:.1f} ms each",
        "rows equal on 1 worker, 2 workers and Ray: " + ("yes" if found["same_rows"] else "NO"),
    ]
    data = {
        "pool_time_ratio": found["pool_time_ratio"],
        "ray_overhead_pct": found["ray_overhead_pct"],
        **{k: v for k, v in found.items() if k not in ("pool_time_ratio", "ray_overhead_pct")},
    }
    return Report("campaign", items, notes, data=data)


__all__ = ["bench_campaign", "measure", "run"]
