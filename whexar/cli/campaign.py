"""``whexar campaign FILE``: many simulated runs, on local processes or a Ray cluster.

The campaign file (:mod:`whexar.campaign.spec`; a shipped name such as
``servo-failures`` or a TOML path) is checked whole, every run included,
before anything runs: a bad one prints every problem and exits with status 1.
Then its runs go to ``--workers N`` local processes (default: one per CPU) or,
with ``--ray [ADDRESS]``, to Ray tasks (:mod:`whexar.campaign.runner`).

A progress line on stderr shows the runs done, failed and running, and the
time left at the pace so far. The results go into ``-o DIR`` (default
``campaigns/NAME``): ``results.csv``, ``results.json``, ``summary.md``,
``metrics.png``, ``runs.jsonl`` as the runs finish, and the recordings when the
campaign keeps them. ``--resume`` keeps the runs already finished there.
``--config FILE`` runs them all with that robot configuration in place of the base
scenario's (the runs' ``config.*`` keys set on it; the summary names it). The
exit status is 0 when every run finished, 2 when some failed (their rows say why).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from whexar.cli.common import Commands, StatusLine, print_json, print_problems
from whexar.errors import ConfigError

if TYPE_CHECKING:
    from whexar.campaign.runner import CampaignResult, Progress

BAR_WIDTH: Final = 20
"""Characters of the progress bar."""
FAILED_STATUS: Final = 2
"""Exit status when some runs failed (the campaign itself went through)."""


def duration_text(seconds: float | None) -> str:
    """``95`` → ``"1 min 35 s"``; ``None`` → ``"?"``."""
    if seconds is None:
        return "?"
    s = round(seconds)
    return f"{s // 60} min {s % 60:02d} s" if s >= 60 else f"{s} s"


class CampaignProgress(StatusLine):
    """The progress line of a campaign: a ``progress`` callback of :func:`run_campaign`."""

    def __init__(self, name: str, stream: Any = None) -> None:
        super().__init__(stream)
        self.name = name
        self._drawn: tuple[int, int, int] | None = None

    def __call__(self, p: Progress) -> None:
        """Draw ``p`` when something changed (the clock alone redraws a live line)."""
        key = (p.done, p.failed, p.running)
        if not self.live and key == self._drawn:
            return
        self._drawn = key
        line = self.line(p)
        self._write(self.fitted(line) if self.live else line + "\n")

    def line(self, p: Progress) -> str:
        """The line for ``p``."""
        skipped = f", {p.skipped} kept" if p.skipped else ""
        latest = ""
        if p.latest is not None:
            r = p.latest
            latest = f"  [run {r.id}{' ' + r.label if r.label else ''}: {r.outcome}]"
        filled = round(BAR_WIDTH * p.done / p.total) if p.total else BAR_WIDTH
        bar = "[" + "#" * filled + "." * (BAR_WIDTH - filled) + "] "
        return (
            f"{bar}campaign {self.name}: {p.done}/{p.total} done, {p.failed} failed, "
            f"{p.running} running{skipped}  {duration_text(p.elapsed_s)} elapsed, "
            f"{duration_text(p.eta_s)} left{latest}"
        )


def _shown(path: Path, folder: Path) -> str:
    try:
        return str(path.relative_to(folder))
    except ValueError:
        return str(path)


def summary_lines(result: CampaignResult) -> list[str]:
    """What the terminal shows at the end: counts, where the files are, the failures."""
    rows = result.rows
    failed = result.failed
    files = ", ".join(_shown(p, result.out_dir) for p in result.files)
    lines = [
        f"campaign {result.campaign.name}: {len(rows)} runs, {len(rows) - len(failed)} ok, "
        f"{len(failed)} failed, {duration_text(result.wall_s)}",
        f"results: {result.out_dir}/ ({files})",
    ]
    lines += [f"  failed: run {r.id} {r.label}: {r.error}" for r in failed]
    return lines


def _campaign(args: argparse.Namespace) -> int:
    from whexar.campaign import load_campaign, run_campaign

    try:
        campaign = load_campaign(args.file, config=args.config)
    except ConfigError as exc:
        print_problems(exc)
        return 1
    out = args.output or Path("campaigns") / campaign.name
    progress = CampaignProgress(campaign.name)
    try:
        result = run_campaign(
            campaign,
            out,
            workers=args.workers,
            ray=args.ray,
            resume=args.resume,
            progress=progress,
        )
    finally:
        progress.finish()
    if args.json:
        print_json(
            {
                "campaign": campaign.name,
                "runs": len(result.rows),
                "failed": len(result.failed),
                "wall_s": result.wall_s,
                "out_dir": str(result.out_dir),
            }
        )
    else:
        print("\n".join(summary_lines(result)))
    return FAILED_STATUS if result.failed else 0


def _workers(value: str) -> int:
    try:
        number = int(value)
    except ValueError:
        number = 0
    if number < 1:
        raise argparse.ArgumentTypeError(f"{value!r}: expected a number of processes ≥ 1")
    return number


def add_commands(commands: Commands) -> None:
    """Add this group's commands to the ``whexar`` command table."""
    p = commands.add_parser(
        "campaign",
        help="run many simulated runs: a base scenario and its variations",
        description="Run every variation of a campaign file (config/campaigns/*.toml) as "
        "its own simulated run, on local processes or a Ray cluster; one row per run "
        "in results.csv and results.json, with summary plots.",
    )
    p.add_argument("file", metavar="FILE|NAME", help="a campaign file or a shipped campaign")
    backend = p.add_mutually_exclusive_group()
    backend.add_argument(
        "--workers",
        type=_workers,
        metavar="N",
        help="local worker processes (default: one per CPU)",
    )
    backend.add_argument(
        "--ray",
        nargs="?",
        const="",
        metavar="ADDRESS",
        help="run as Ray tasks: on the cluster at ADDRESS, else Ray's default (RAY_ADDRESS, "
        "a cluster started on this machine, or a new local instance); "
        "needs pip install 'whexar[cluster]'",
    )
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        metavar="DIR",
        help="where the results go (default: campaigns/NAME)",
    )
    p.add_argument(
        "--config",
        type=Path,
        metavar="FILE",
        help="a robot configuration for every run, in place of the base scenario's",
    )
    p.add_argument("--resume", action="store_true", help="keep the runs already finished in DIR")
    p.add_argument("--json", action="store_true", help="print the outcome as one JSON object")
    p.set_defaults(handler=_campaign)
