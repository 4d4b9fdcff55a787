"""``whexar sim``: run the simulated WHexaR on a scenario; summary, report, video, viewer.

The scenario (``--scenario``, a built-in name or a TOML file; default
``course``) is checked whole before anything runs: a bad one prints every
problem and exits with status 1, like ``whexar config check``. Then the full
runtime drives the MuJoCo world on virtual time (:mod:`whexar.sim.run`).

While it runs, one progress line on stderr is redrawn in place (``\\r``):
simulated time, position, speed over the last second, what the scenario's
commands have asked for so far (mode, gait), the latest command and, when the
body tilts past 60°, FALLEN. The runtime's own state is not visible from
outside a run, so the line shows the command timeline, not the coordinator's
activity; the report's gait diagram has the activity. When stderr is no
terminal, a line is printed every 10 s of simulated time instead.

At the end: the summary as text, or with ``--json`` one JSON object with exactly
:data:`SUMMARY_KEYS`: how far the robot got (``progress_m``, start to end;
``progress_along_m``, along the course, the heading it started with), the length of
its path (``distance_m``, sway included), … in strict JSON: a figure with no finite
value is ``null`` (``cost_of_transport`` when the body did not move;
``min_stability_margin_m`` when the robot was never on its legs or, at some cycle, had
fewer than three feet down and so no support polygon, which the text shows as −inf).
``--report DIR`` writes the plots and tables (:mod:`whexar.sim.report`), ``--video
FILE.mp4`` renders the run headless (:mod:`whexar.sim.video`), ``--view`` shows it in
MuJoCo's viewer, paced to real time, where a display exists.

Every run is recorded (:mod:`whexar.record`): into ``--record FILE.mcap``, by
default a new file under ``recordings/`` named after the scenario and the date;
``--no-record`` records nothing. The summary ends with the recording's path.
``--live [PORT]`` serves what is recorded to the Foxglove app
(:mod:`whexar.record.live`) and paces the run to real time.

``--config FILE`` runs a robot configuration of your own (the one the robot runs,
say) in place of the scenario's, or of the experiments' base scenario's.

``--experiments`` runs the thesis's experiments instead (the campaign
``config/campaigns/experiments.toml`` on one worker process per CPU, a
progress line on stderr): the report goes into ``--report DIR`` (default
:data:`EXPERIMENTS_REPORT`), the table of the simulation's figures beside the
thesis's is printed, or with ``--json`` one object
``{"experiments": [{"name", "unit", "thesis", "sim"}, …], "agreement": {…}, "config": …}``
(:mod:`whexar.campaign.experiments`).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from whexar.cli.common import (
    DEFAULT_LIVE_PORT,
    RECORDINGS,
    Commands,
    StatusLine,
    default_recording,
    print_json,
    print_problems,
    seconds,
    tcp_port,
)
from whexar.errors import ConfigError, UsageError
from whexar.runtime.clock import monotonic, wait_until

if TYPE_CHECKING:
    from whexar.sim.run import Sample
    from whexar.sim.scenario import Scenario
    from whexar.sim.world import SimWorld

SUMMARY_KEYS: Final = (
    "progress_m",
    "progress_along_m",
    "distance_m",
    "mean_speed_mps",
    "energy_j",
    "cost_of_transport",
    "min_stability_margin_m",
    "gait_changes",
    "gait_selections",
    "reflex_activations",
    "falls",
    "sim_seconds",
    "stopped_by",
    "wall_seconds",
    "realtime_factor",
    "state_hash",
)
"""The keys of ``whexar sim --json``, in order."""
REDRAW_S: Final = 0.1
"""Shortest wall time between two redraws of the progress line."""
LOG_EVERY_S: Final = 10.0
"""Simulated seconds between two progress lines when stderr is no terminal."""
FALLEN_TILT_RAD: Final = math.radians(60.0)
EXPERIMENTS: Final = "experiments"
"""The shipped campaign ``--experiments`` runs (``config/campaigns/experiments.toml``)."""
EXPERIMENTS_REPORT: Final = Path("experiments-report")
"""Where ``--experiments`` writes its report unless ``--report`` says otherwise."""


def _seed(value: str) -> int:
    try:
        number = int(value)
    except ValueError:
        number = -1
    if number < 0:
        raise argparse.ArgumentTypeError(f"{value!r}: expected an integer ≥ 0")
    return number


class Progress(StatusLine):
    """The live progress line: an ``on_sample`` callback writing to ``stream``."""

    def __init__(self, scenario: Scenario, stream: Any = None) -> None:
        from whexar.sim.scenario import describe_command

        super().__init__(stream)
        self.timeline = [(t, cmd, describe_command(cmd)) for t, cmd in scenario.commands]
        self.duration = scenario.duration_s
        self.mode = "walk"
        self.gait: str = scenario.config.locomotion.gait
        self.latest = "standing up"
        self._k = 0
        self._recent: deque[Sample] = deque()
        self._drawn_at = -math.inf
        self._logged_at = -math.inf
        self._wall = monotonic()

    def __call__(self, sample: Sample, world: SimWorld) -> None:
        """Take one sample; redraw the line when it is due."""
        while self._k < len(self.timeline) and self.timeline[self._k][0] <= sample.t + 1e-9:
            _, cmd, label = self.timeline[self._k]
            self.mode = cmd.mode or self.mode
            self.gait = cmd.gait or self.gait
            self.latest = f"t={self.timeline[self._k][0]:g}: {label}"
            self._k += 1
        self._recent.append(sample)
        while self._recent and self._recent[0].t < sample.t - 1.0:
            self._recent.popleft()
        if self.live:
            now = monotonic()
            if now - self._drawn_at >= REDRAW_S:
                self._drawn_at = now
                self._write(self.fitted(self.line(sample)))
        elif sample.t - self._logged_at >= LOG_EVERY_S:
            self._logged_at = sample.t
            self._write(self.line(sample) + "\n")

    def line(self, s: Sample) -> str:
        """The progress line for sample ``s``."""
        first = self._recent[0] if self._recent else s
        dt = s.t - first.t
        speed = math.hypot(s.x - first.x, s.y - first.y) / dt if dt > 0 else 0.0
        fallen = "  FALLEN" if max(abs(s.roll), abs(s.pitch)) > FALLEN_TILT_RAD else ""
        rtf = s.t / max(1e-9, monotonic() - self._wall)
        doing = s.activity or f"{self.mode}/{self.gait}"
        event = f"  {s.event}" if s.event else ""
        return (
            f"t {s.t:6.1f}/{self.duration:g} s  x {s.x:+6.2f} y {s.y:+6.2f} m  "
            f"{speed:4.2f} m/s  {doing}  {rtf:4.1f}x  [{self.latest}]{event}{fallen}"
        )


class Pace:
    """Holds a run to real time: each sample waits until as much wall time has passed
    (for a person watching: ``--view``, ``--live``)."""

    def __init__(self) -> None:
        self._start: float | None = None
        self._t0 = 0.0

    def __call__(self, sample: Sample, world: SimWorld | None = None) -> None:
        """Wait until real time reaches this sample."""
        if self._start is None:
            self._start, self._t0 = monotonic(), sample.t
        wait_until(self._start + (sample.t - self._t0))


class Viewer:
    """MuJoCo's passive viewer on the running world, paced to real time."""

    def __init__(self) -> None:
        self._handle: Any = None
        self._pace = Pace()

    def __call__(self, sample: Sample, world: SimWorld) -> None:
        """Show the world at this sample; sleep until real time catches up."""
        import mujoco.viewer

        if self._handle is None:
            self._handle = mujoco.viewer.launch_passive(world.model, world.data)
        if not self._handle.is_running():
            return
        self._handle.sync()
        self._pace(sample)

    def close(self) -> None:
        """Close the window."""
        if self._handle is not None:
            self._handle.close()


def _callbacks(*found: Callable[[Sample, SimWorld], None] | None) -> Callable[..., None]:
    callbacks = [c for c in found if c is not None]

    def each(sample: Sample, world: SimWorld) -> None:
        for c in callbacks:
            c(sample, world)

    return each


def _shown(path: Path) -> str:
    """``path`` as short as it reads: from the working folder when it lies under it."""
    full = path.resolve()
    try:
        return str(full.relative_to(Path.cwd()))
    except ValueError:
        return str(full)


def summary_text(name: str, summary: dict[str, Any], config: Path | None = None) -> str:
    """The summary for the terminal: one figure a line, with units; the header names the
    robot configuration file the run read, if not the defaults."""
    from whexar.sim.report import FIGURES, format_figure

    lines = [f"whexar sim: {name}" + (f", robot configuration {_shown(config)}" if config else "")]
    width = max(len(FIGURES[key][0]) for key in SUMMARY_KEYS) + 2  # the longest label, a gap
    for key in SUMMARY_KEYS:
        label = FIGURES[key][0]
        value = summary.get(key)
        if key == "stopped_by" and value is None:
            continue  # it ran its course: nothing to say
        shown = str(value) if key == "state_hash" else format_figure(key, value)
        lines.append(f"  {label:<{width}}{shown}")
    return "\n".join(lines)


def _experiments(args: argparse.Namespace) -> int:
    """``--experiments``: the thesis's experiments as a campaign, the table of figures."""
    from whexar.campaign import load_campaign, run_campaign
    from whexar.campaign.experiments import figures, json_document, table_text
    from whexar.cli.campaign import FAILED_STATUS, CampaignProgress, summary_lines

    alone = ("video", "view", "live", "record", "duration", "seed", "spread")
    given = [f"--{name}" for name in alone if getattr(args, name) not in (None, False)]
    if given:
        raise UsageError(f"--experiments runs its own campaign: drop {', '.join(given)}")
    try:
        campaign = load_campaign(EXPERIMENTS, config=args.config)
    except ConfigError as exc:
        print_problems(exc)
        return 1
    out = args.report if args.report is not None else EXPERIMENTS_REPORT
    progress = CampaignProgress(campaign.name)
    try:
        result = run_campaign(campaign, out, progress=progress)
    finally:
        progress.finish()
    for line in summary_lines(result):
        print(line, file=sys.stderr)
    found = figures(result.rows)
    if args.json:
        print_json(json_document(found, campaign.config))
    else:
        print(table_text(found))
    return FAILED_STATUS if result.failed else 0


def _sim(args: argparse.Namespace) -> int:
    from whexar.sim.scenario import load_scenario

    if args.experiments:
        return _experiments(args)
    if args.view and args.video:
        raise UsageError("--view and --video need different OpenGL back ends: choose one")
    if args.view and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise UsageError(
            "--view needs a display (DISPLAY is not set); "
            "render the run with --video FILE.mp4 instead"
        )
    try:
        scenario = load_scenario(args.scenario, config=args.config)
    except ConfigError as exc:
        print_problems(exc)
        return 1
    scenario = scenario.with_overrides(
        duration_s=args.duration, seed=args.seed, spread=True if args.spread else None
    )
    recorder = None
    if args.video is not None:
        from whexar.sim.video import VideoRecorder, select_gl

        select_gl()  # before the world imports mujoco: its OpenGL back end is chosen then
        recorder = VideoRecorder(args.video)
    viewer = Viewer() if args.view else None
    progress = Progress(scenario)
    log = None if args.no_record else args.record or default_recording(scenario.name)
    live = None
    if args.live is not None:
        from whexar.record.live import LiveView

        live = LiveView(args.live)
        print(f"live view: {live.url} (Foxglove: open a WebSocket connection)", file=sys.stderr)
    pace = Pace() if live is not None and viewer is None else None
    try:
        result = scenario.run(
            on_sample=_callbacks(progress, recorder, viewer, pace), record=log, live=live
        )
    finally:
        progress.finish()
        if live is not None:
            live.close()
        if recorder is not None:
            recorder.close()
        if viewer is not None:
            viewer.close()
    summary = result.summary()
    if args.report is not None:
        from whexar.sim.report import write_report

        written = write_report(
            result,
            args.report,
            commands=scenario.commands,
            name=scenario.name,
            description=scenario.description,
        )
        print(f"report: {len(written)} files in {args.report}/", file=sys.stderr)
    if recorder is not None:
        print(
            f"video: {args.video} ({recorder.frames} frames; rendering them is in the wall time)",
            file=sys.stderr,
        )
    if result.recording is not None:
        from whexar.record.budget import report_line

        for line in filter(None, map(report_line, result.events)):
            print(line, file=sys.stderr)  # the recordings deleted, a stop
        print(f"recording: {result.recording}", file=sys.stderr)
    if args.json:
        print_json({key: summary.get(key) for key in SUMMARY_KEYS})
    else:
        print(summary_text(scenario.name, summary, scenario.config_path))
    return 0


def add_commands(commands: Commands) -> None:
    """Add this group's commands to the ``whexar`` command table."""
    sim = commands.add_parser(
        "sim",
        help="run the simulated WHexaR (MuJoCo) on a scenario",
        description="Run the full runtime against the simulated WHexaR on a scenario "
        "(config/scenarios/*.toml): a summary, and optionally plots, a video, the viewer.",
    )
    sim.add_argument(
        "--scenario",
        default="course",
        metavar="NAME|FILE",
        help="a built-in scenario (course, obstacles, slope, wheels) or a TOML file; "
        "default: course",
    )
    sim.add_argument(
        "--config",
        type=Path,
        metavar="FILE",
        help="a robot configuration in place of the scenario's (with --experiments: of "
        "every run's); default: the scenario's, else the thesis robot",
    )
    sim.add_argument(
        "--duration", type=seconds, metavar="S", help="simulated seconds (default: the scenario's)"
    )
    sim.add_argument(
        "--seed",
        type=_seed,
        metavar="N",
        help="seed of the scenario's random terrain features and, with --spread, of the "
        "robot's parts (default: the scenario's)",
    )
    sim.add_argument(
        "--spread",
        action="store_true",
        help="draw the robot's parts from the seed within their datasheets' spread "
        "(sensor gains and offsets, friction, masses, backlash, reply delays; "
        "default: the scenario's spread key, off unless it says so)",
    )
    sim.add_argument(
        "--report",
        type=Path,
        metavar="DIR",
        help="write PNG plots and a summary (with --experiments: the experiments' report, "
        f"default {EXPERIMENTS_REPORT}/)",
    )
    sim.add_argument(
        "--experiments",
        action="store_true",
        help="run the thesis's experiments (config/campaigns/experiments.toml) and print "
        "the simulation's figures beside the thesis's",
    )
    sim.add_argument("--video", type=Path, metavar="FILE.mp4", help="render the run (H.264)")
    sim.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    sim.add_argument(
        "--view", action="store_true", help="watch it in MuJoCo's viewer (needs a display)"
    )
    recording = sim.add_mutually_exclusive_group()
    recording.add_argument(
        "--record",
        type=Path,
        metavar="FILE.mcap",
        help=f"record every message and byte into FILE (default: {RECORDINGS}/SCENARIO-DATE.mcap)",
    )
    recording.add_argument("--no-record", action="store_true", help="do not record the run")
    sim.add_argument(
        "--live",
        type=tcp_port,
        nargs="?",
        const=DEFAULT_LIVE_PORT,
        metavar="PORT",
        help="serve the run to the Foxglove app on localhost:PORT (default 8765), "
        "paced to real time",
    )
    sim.set_defaults(handler=_sim)
