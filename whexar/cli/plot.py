"""``whexar plot``: PNG plots of a recording.

``whexar plot LOG -o DIR [--legs …] [--joints …] [--from T] [--to T]`` draws from a
recording (:mod:`whexar.record.plots`): goal against present angle per joint of each
leg (``joints_leg{N}.png``, thesis Fig. 6.2), current per servo and per leg
(``currents.png``, Fig. 6.8), the gait diagram (``gait.png``, Fig. 3.3), body tilt
(``tilt.png``), electric power and cost of transport (``power.png``). ``--legs`` takes
leg numbers 0–5 or names (RF, LF, RM, LM, RR, LR), ``--joints`` joint names (coxa …
wheel); both take several values, with spaces or commas. ``--from``/``--to`` bound the
window in seconds of the recording's time (as ``whexar log info`` shows it).

It prints each file written on stdout, and on stderr each plot skipped for want of
data and, for a recording cut short, where it ends (what is there is plotted). A
missing or unreadable file, a bad leg or joint or an empty window is bad input (exit 2).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from whexar.cli.common import Commands, instant


def _plot(args: argparse.Namespace) -> int:
    from whexar.record.plots import write_plots

    written = write_plots(
        args.log,
        args.output,
        legs=args.legs,
        joints=args.joints,
        t_from=args.t_from,
        t_to=args.t_to,
        say=lambda text: print(text, file=sys.stderr),
    )
    for path in written:
        print(path)
    if not written:
        print(f"{args.log}: nothing to plot", file=sys.stderr)
    return 0


def add_commands(commands: Commands) -> None:
    """Add this group's commands to the ``whexar`` command table."""
    plot = commands.add_parser(
        "plot",
        help="PNG plots of a recording: joints, currents, gait, tilt, power",
        description="Draw a recording (MCAP) as PNG plots: goal against present angle per "
        "joint of each leg (joints_leg{N}.png, thesis Fig. 6.2), current per servo and per "
        "leg (currents.png, Fig. 6.8), the gait diagram (gait.png, Fig. 3.3), body roll and "
        "pitch (tilt.png), electric power and cost of transport (power.png). A plot whose "
        "data is not in the recording is skipped, and said so.",
    )
    plot.add_argument("log", type=Path, metavar="LOG", help="the recording (.mcap)")
    plot.add_argument(
        "-o", "--output", type=Path, required=True, metavar="DIR", help="write the PNGs here"
    )
    plot.add_argument(
        "--legs",
        nargs="+",
        metavar="LEG",
        help="legs to plot: 0–5 or RF, LF, RM, LM, RR, LR (default: all six)",
    )
    plot.add_argument(
        "--joints",
        nargs="+",
        metavar="JOINT",
        help="joints to plot: coxa, trochanter, femur, tibia, tarsus, direction, wheel "
        "(default: every joint with data)",
    )
    plot.add_argument(
        "--from", dest="t_from", type=instant, metavar="T", help="start of the window (s)"
    )
    plot.add_argument("--to", dest="t_to", type=instant, metavar="T", help="end of the window (s)")
    plot.set_defaults(handler=_plot)
