"""``whexar replay``: a recording played back through the same actors, and checked.

``whexar replay LOG [--from T] [--to T] [--speed X | --fast] [--check] [--config FILE]
[--record FILE] [--live [PORT]] [--json]`` (:mod:`whexar.record.replay`): the recorded
servo-bus, sensor-link and IMU bytes go back in through the SDK's port, the frame
decoder and the I²C calls; the recorded motion commands are fed at their times; the
actors run on virtual time. By default as fast as the CPU allows; ``--speed X`` paces
it at X times real time (``--live`` alone paces it at 1×).

``--check`` compares every message with the recorded one and exits 1 at the first
divergence, naming the channel, the time, the field and both values: with an edited
configuration (``--config``) or code, a regression test on a real log.

A progress line on stderr (redrawn on a terminal, every 10 replayed seconds
otherwise); the summary on stdout (``--json``: one JSON object). Exit status: 0, 1 a
divergence, 2 bad input (a missing, damaged-beyond-use or incompatible recording, a
bad window).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from whexar.cli.common import (
    DEFAULT_LIVE_PORT,
    Commands,
    StatusLine,
    factor,
    instant,
    print_json,
    tcp_port,
    tolerance,
)
from whexar.cli.run import assignment
from whexar.errors import UsageError
from whexar.runtime.clock import monotonic

if TYPE_CHECKING:
    from whexar.record.diff import Tolerances
    from whexar.record.replay import ReplayResult

FLOAT_TOLERANCE: Final = 1e-9
"""``--tolerance``'s default: :data:`whexar.record.replay.FLOAT_TOLERANCE` (not imported
here, so that ``whexar --help`` stays fast)."""

LOG_EVERY_S: Final = 10.0
"""Replayed seconds between two progress lines when stderr is no terminal."""
BAR: Final = 24
"""Width of the progress bar, in characters."""


def tolerance_setting(value: str) -> tuple[str, float]:
    """An argument type: ``NAME=VALUE`` of a tolerance (``angle_rad=0.05``)."""
    name, sep, text = value.partition("=")
    try:
        number = float(text)
    except ValueError:
        number = math.nan
    if not sep or not math.isfinite(number) or number < 0:
        raise argparse.ArgumentTypeError(
            f"{value!r}: expected NAME=VALUE with a number ≥ 0, e.g. angle_rad=0.05"
        )
    return name.strip(), number


def add_tolerance_options(cmd: argparse.ArgumentParser) -> None:
    """``--window`` and ``--tol`` of the time-aligned comparison (replay, log diff)."""
    cmd.add_argument(
        "--window",
        type=float,
        metavar="S",
        help="how far apart in time two samples of one signal may be (default 0.05 s: five "
        "bus cycles)",
    )
    cmd.add_argument(
        "--tol",
        type=tolerance_setting,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="an absolute tolerance of the time-aligned comparison (repeatable): angle_rad, "
        "length_m, current_a, speed_m_s, event_s, … (defaults: docs/replay.md)",
    )


def tolerances_of(args: argparse.Namespace) -> Tolerances:
    """The tolerances ``--window`` and ``--tol`` ask for; an unknown name is a usage error."""
    from whexar.record.diff import DEFAULT_TOLERANCES

    settings = dict(args.tol)
    if args.window is not None:
        settings["window_s"] = args.window
    try:
        return DEFAULT_TOLERANCES.with_(settings)
    except KeyError as exc:
        raise UsageError(f"--tol {exc.args[0]}") from None


class Progress(StatusLine):
    """The progress line: ``progress(t, end)`` callbacks of :func:`~whexar.record.replay.replay`."""

    def __init__(self, stream: Any = None) -> None:
        super().__init__(stream)
        self._wall = monotonic()
        self._logged = -math.inf

    def __call__(self, t: float, end: float) -> None:
        """Redraw (or, off a terminal, print every :data:`LOG_EVERY_S`) the line."""
        if not self.live and t - self._logged < LOG_EVERY_S and t < end:
            return
        self._logged = t
        self._write(self.line(t, end) if self.live else self.line(t, end) + "\n")

    def line(self, t: float, end: float) -> str:
        """``[#####-----]  12.0/60.0 s  14.2× real time  4 s left``."""
        share = min(1.0, t / end) if end > 0 else 1.0
        done = round(share * BAR)
        wall = monotonic() - self._wall
        rate = t / wall if wall > 0 else math.inf
        left = (end - t) / rate if rate > 0 else math.inf
        text = (
            f"[{'#' * done}{'-' * (BAR - done)}] {t:6.1f}/{end:.1f} s  "
            f"{rate:5.1f}× real time  {left:4.0f} s left"
        )
        return self.fitted(text) if self.live else text


def summary(result: ReplayResult) -> dict[str, Any]:
    """The figures of ``whexar replay --json``."""
    d = result.divergence
    return {
        "recording": str(result.path),
        "replayed_s": result.duration_s,
        "recorded_s": result.recorded_s,
        "wall_s": result.wall_s,
        "realtime_factor": result.realtime_factor,
        "checked": result.checked,
        "compared": result.compared,
        "divergence": None
        if d is None
        else {
            "kind": d.kind,
            "channel": d.channel,
            "t": d.t,
            "what": d.what,
            "recorded": d.recorded,
            "replayed": d.replayed,
        },
        "fed": result.fed,
        "links": result.links,
        "dropped": {
            name: {k: v for k, v in s.dropped.items() if v}
            for name, s in result.channels.items()
            if any(s.dropped.values())
        },
        "config_changes": result.config_changes,
        "damage": result.damage,
        "clock": result.clock,
        "agrees": result.agrees,
        "ended_early": result.ended_early,
        "report": None if result.report is None else result.report.to_json(),
        "uncompared": result.uncompared,
    }


def summary_text(result: ReplayResult) -> str:
    """The summary for the terminal."""
    lines = [
        f"whexar replay: {result.path}",
        f"  replayed      {result.duration_s:.3f} of {result.recorded_s:.3f} s in "
        f"{result.wall_s:.2f} s ({result.realtime_factor:.1f}× real time)",
        "  devices       "
        + (
            "by time (a log of a real clock)"
            if result.clock == "real"
            else "byte for byte (a log of virtual time)"
        ),
    ]
    for channel, count in result.fed.items():
        lines.append(f"  fed           {channel}: {count} recorded messages")
    for name, what in result.links.items():
        lines.append(f"  link {name:<9}{what}")
    for change in result.config_changes:
        lines.append(f"  config        {change}")
    if result.damage:
        lines.append(f"  recording     {result.damage}")
    if result.ended_early:
        lines.append(f"  ended early   {result.ended_early}")
    report = result.report
    if result.checked and report is not None:
        w = report.tolerances.window_s
        if report.agrees:
            lines.append(
                f"  check         by time (window {w:g} s): {report.compared} samples agree "
                "with the recording within tolerance"
            )
        else:
            first = report.first_beyond
            lines.append(f"  check         by time (window {w:g} s): {report.compared} samples, ")
            if first is not None:
                lines[-1] += (
                    f"the first lasting difference at t = {first.first_beyond_t:.3f} s on "
                    f"{first.channel} {first.message}.{first.field} ({first.first_beyond_key})"
                )
            else:
                lines[-1] += "events or samples without a match"
            lines.append("  " + report.table().replace("\n", "\n  "))
        if result.uncompared:
            lines.append(f"  not compared  {', '.join(result.uncompared)} (in one run only)")
    elif result.checked:
        if result.divergence is None:
            lines.append(f"  check         {result.compared} messages agree with the recording")
        else:
            lines.append(f"  check         {result.compared} messages agreed, then:")
            lines.append("  " + result.divergence.describe().replace("\n", "\n  "))
    return "\n".join(lines)


def _replay(args: argparse.Namespace) -> int:
    from whexar.record.replay import replay

    live = None
    if args.live is not None:
        from whexar.record.live import LiveView

        live = LiveView(args.live)
        print(f"live view: {live.url} (Foxglove: open a WebSocket connection)", file=sys.stderr)
    speed = None if args.fast else args.speed or (1.0 if live is not None else None)
    progress = Progress()
    record = args.record
    if args.report is not None and record is None:
        args.report.mkdir(parents=True, exist_ok=True)
        record = args.report / "replay.mcap"  # the report draws the replay from its recording
    try:
        result = replay(
            args.log,
            start=args.t_from or 0.0,
            stop=args.t_to,
            speed=speed,
            check=args.check,
            config=args.config,
            record=record,
            live=live,
            progress=None if args.json else progress,
            tolerance=args.tolerance,
            by_time=args.by_time,
            tolerances=tolerances_of(args),
            graph=args.graph,
            sets=args.set,
        )
    finally:
        progress.finish()
        if live is not None:
            live.close()
    plots = []
    if args.report is not None and record is not None and result.recording is not None:
        from whexar.record.diff_plots import write_diff_plots

        plots = write_diff_plots(args.log, result.recording, args.report, result.report)
    if args.json:
        print_json(summary(result))
    else:
        print(summary_text(result), flush=True)
        if record is not None:
            print(f"recording: {record}", flush=True)
        if plots:
            print(f"report: {len(plots)} plots in {args.report}", flush=True)
    return 0 if result.agrees else 1


def add_commands(commands: Commands) -> None:
    """Add this group's commands to the ``whexar`` command table."""
    cmd = commands.add_parser(
        "replay",
        help="play a recording back through the same actors; --check compares every message",
        description="Play a recording (MCAP) back: its servo-bus, sensor-link and IMU bytes "
        "go in through the same edges the real transports use (dynamixel-sdk's port, the "
        "frame decoder, the I²C calls), its motion commands are fed at their times, and "
        "the actors run on virtual time. The actors carry state from the start, so a "
        "replay always starts at the recording's start; --from is where pacing and the "
        "check begin. Exit status 1 when --check finds a divergence.",
    )
    cmd.add_argument("log", type=Path, metavar="LOG", help="the recording (.mcap)")
    cmd.add_argument(
        "--from", dest="t_from", type=instant, metavar="T", help="check and pace from T (s)"
    )
    cmd.add_argument("--to", dest="t_to", type=instant, metavar="T", help="stop at T (s)")
    pace = cmd.add_mutually_exclusive_group()
    pace.add_argument(
        "--speed", type=factor, metavar="X", help="X times real time (default: as fast as it goes)"
    )
    pace.add_argument(
        "--fast", action="store_true", help="as fast as it goes, even with --live (the default)"
    )
    cmd.add_argument(
        "--check",
        action="store_true",
        help="compare every message with the recorded one; exit 1 at the first divergence",
    )
    cmd.add_argument(
        "--tolerance",
        type=tolerance,
        default=FLOAT_TOLERANCE,
        metavar="X",
        help=f"floats agree within X, relative to the larger (default {FLOAT_TOLERANCE:g}: "
        "a log of a run on virtual time replays to the last bit; one recorded in real time "
        "carries its timers' jitter)",
    )
    cmd.add_argument(
        "--config",
        type=Path,
        metavar="FILE",
        help="replay with this robot configuration instead of the recorded one",
    )
    cmd.add_argument(
        "--by-time",
        action="store_true",
        help="compare by time, as a log of a real clock is (a report of every field, not "
        "the first difference), also for a log of virtual time",
    )
    add_tolerance_options(cmd)
    cmd.add_argument(
        "--graph",
        type=Path,
        metavar="FILE",
        help="replay this wiring file instead of the recorded one (an added reflex); its "
        "device actors are pointed at the recording",
    )
    cmd.add_argument(
        "--set",
        type=assignment,
        action="append",
        default=[],
        metavar="ACTOR.PARAM=VALUE",
        help="change a parameter of one actor for the replay (repeatable), as whexar run --set",
    )
    cmd.add_argument(
        "--report",
        type=Path,
        metavar="DIR",
        help="draw the recorded against the replayed joints and events into DIR (the replay "
        "is recorded there too, unless --record)",
    )
    cmd.add_argument("--record", type=Path, metavar="FILE.mcap", help="record the replay into FILE")
    cmd.add_argument(
        "--live",
        type=tcp_port,
        nargs="?",
        const=DEFAULT_LIVE_PORT,
        metavar="PORT",
        help="serve the replay to the Foxglove app on localhost:PORT (default 8765), "
        "at real time unless --speed or --fast",
    )
    cmd.add_argument("--json", action="store_true", help="print the summary as JSON")
    cmd.set_defaults(handler=_replay)
