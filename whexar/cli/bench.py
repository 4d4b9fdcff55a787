"""``whexar bench …``: measure speed and latency against their targets (:mod:`whexar.bench`)."""

from __future__ import annotations

import argparse
import importlib
from typing import TYPE_CHECKING

from whexar.cli.common import Commands, print_json

if TYPE_CHECKING:
    from whexar.bench import Report


def _bench(args: argparse.Namespace) -> int:
    """Run the suite ``args.bench_command`` (a module of :mod:`whexar.bench`)."""
    suite = importlib.import_module(f"whexar.bench.{args.bench_command}")
    report: Report = suite.run(progress=None if args.json else print)
    if args.json:
        print_json(report.json)
    else:
        print(report.render())
    return 0 if report.passed else 1


SUITES: dict[str, str] = {
    "kin": "inverse kinematics speed",
    "runtime": "message passing and virtual time",
    "bus": "servo bus cycle rates per read plan, CPU per cycle, real time over a pty",
    "sensors": "sensor frame decoding speed and frame-to-message latency (real time)",
    "cycle": "CPU per control cycle of the locomotion stack (six legs and the coordinator)",
    "sim": "the simulated WHexaR against real time; CPU per bus cycle by part",
    "record": "what recording costs the runtime: CPU overhead, a cycle's wait, file size",
    "fieldbus": "a field log's servo bus played back by time: replay speed, cost per transaction",
    "campaign": "a campaign on 2 workers against 1; what Ray adds to a run",
    "robot": "the whole controller on real time, bus over a pty: share of a core, CPU per cycle",
    "reflex": "a reflex's latency from its stimulus to the wire; the reactive layer's CPU",
}
"""The suites, each a module of :mod:`whexar.bench` with a ``run(progress)``."""


def add_commands(commands: Commands) -> None:
    """Add this group's commands to the ``whexar`` command table."""
    bench = commands.add_parser("bench", help="measure speed against the targets")
    suites = bench.add_subparsers(dest="bench_command", required=True, metavar="SUITE")
    for name, text in SUITES.items():
        suite = suites.add_parser(name, help=text)
        suite.add_argument("--json", action="store_true", help="print the figures as JSON")
        suite.set_defaults(handler=_bench)
