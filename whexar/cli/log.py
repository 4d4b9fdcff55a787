"""``whexar log``: look at recordings and mend them.

``whexar log info LOG [--json]`` prints what a recording holds (:mod:`whexar.record.info`):
duration, messages per channel and type with their rates and longest gaps, events by
level and the errors, and whether the file is complete or where its readable part ends.
``whexar log recover LOG [-o OUT]`` rewrites the readable part of a file that has no
footer (a killed recording) as a complete file, by default ``LOG``'s name with
``.recovered.mcap``, and says how much it saved. ``whexar log diff A B`` compares two
recordings by time (:mod:`whexar.record.diff`) and exits 1 where they differ beyond
tolerance. A file that is not a recording, or cannot be read, is bad input (exit 2).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from whexar.cli.common import Commands, print_json


def _info(args: argparse.Namespace) -> int:
    from whexar.record.info import format_info, summarize

    info = summarize(args.log)
    if args.json:
        print_json(info.as_dict())
    else:
        print(format_info(info))
    return 0


def _recover(args: argparse.Namespace) -> int:
    from whexar.record.reader import Recording, recover

    source: Path = args.log
    recording = Recording(source)
    if recording.complete and recording.damage is None and args.output is None:
        print(f"{source} is complete: nothing to recover")
        return 0
    output: Path = args.output or source.with_name(f"{source.stem}.recovered.mcap")
    report = recover(source, output)
    if report.damage is not None:
        print(report.damage.describe(source), file=sys.stderr)
    print(report.describe())
    return 0


def _diff(args: argparse.Namespace) -> int:
    from whexar.cli.replay import tolerances_of
    from whexar.record.diff import diff_recordings

    report = diff_recordings(args.first, args.second, tolerances_of(args))
    plots = []
    if args.report is not None:
        from whexar.record.diff_plots import write_diff_plots

        plots = write_diff_plots(
            args.first, args.second, args.report, report, labels=(args.first.name, args.second.name)
        )
    if args.json:
        print_json({"first": str(args.first), "second": str(args.second), **report.to_json()})
    else:
        w = report.tolerances.window_s
        verdict = "agree within tolerance" if report.agrees else "differ"
        print(f"whexar log diff: {args.first} against {args.second}")
        print(f"  compared      {report.compared} samples by time (window {w:g} s): they {verdict}")
        table = report.table(all_rows=args.all)
        if table.count("\n") > 0 or args.all:
            print("  " + table.replace("\n", "\n  "))
        if plots:
            print(f"report: {len(plots)} plots in {args.report}")
    return 0 if report.agrees else 1


def add_commands(commands: Commands) -> None:
    """Add this group's commands to the ``whexar`` command table."""
    log = commands.add_parser(
        "log",
        help="look at recordings (MCAP): info, recover, diff",
        description="Look at whexar's recordings (MCAP files) and mend them.",
    )
    sub = log.add_subparsers(dest="log_command", required=True, metavar="COMMAND")
    info = sub.add_parser(
        "info",
        help="duration, messages per channel, rates, gaps, errors, completeness",
        description="Say what a recording holds: duration, message counts per channel and "
        "type, rates, the longest gap per channel, events by level and the errors, and "
        "whether the file is complete or where its readable part ends.",
    )
    info.add_argument("log", type=Path, metavar="LOG", help="the recording (.mcap)")
    info.add_argument("--json", action="store_true", help="print one line of JSON")
    info.set_defaults(handler=_info)
    recover = sub.add_parser(
        "recover",
        help="rewrite a recording that has no footer (a killed process) as a complete file",
        description="Copy the readable part of a recording that was cut short (no MCAP "
        "footer: the recording process was killed) into a complete, indexed file.",
    )
    recover.add_argument("log", type=Path, metavar="LOG", help="the recording (.mcap)")
    recover.add_argument(
        "-o",
        "--output",
        type=Path,
        default=None,
        help="write to OUT (default: LOG's name with .recovered.mcap)",
    )
    recover.set_defaults(handler=_recover)
    diff = sub.add_parser(
        "diff",
        help="compare two recordings by time: every field within its tolerance, events in order",
        description="Compare two recordings (the original and a replay of it, or two runs) "
        "as signals: every field of every state message against the other's samples of the "
        "same key within a time window, with an absolute tolerance per kind (angles, "
        "lengths, currents…); events, step commands and swing ends matched by kind and "
        "order. Prints the fields beyond tolerance (all with --all); exit status 1 when "
        "any is.",
    )
    diff.add_argument("first", type=Path, metavar="A", help="the first recording (.mcap)")
    diff.add_argument("second", type=Path, metavar="B", help="the second recording (.mcap)")
    from whexar.cli.replay import add_tolerance_options

    add_tolerance_options(diff)
    diff.add_argument("--all", action="store_true", help="every field, not only those beyond")
    diff.add_argument("--report", type=Path, metavar="DIR", help="draw both runs into DIR")
    diff.add_argument("--json", action="store_true", help="print the report as JSON")
    diff.set_defaults(handler=_diff)
