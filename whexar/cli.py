"""``whexar`` command line.

Exit codes: 0 success; 1 a configuration with problems, or a benchmark that
missed its target; 2 bad input (an unknown leg, an unreachable target, a
malformed option); 3 ``whexar run`` stopped after an actor was escalated.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from whexar import __version__
from whexar.actors.messages import Message
from whexar.actors.wiring import EVENTS_CHANNEL
from whexar.errors import ConfigError, UsageError
from whexar.robot import LEG_NAMES, POSITIONING_JOINTS, leg_index

if TYPE_CHECKING:
    from whexar.bench import Report
    from whexar.kinematics.geometry import LegGeometry

Handler = Callable[[argparse.Namespace], int]


def _print_json(value: object) -> None:
    print(json.dumps(value, indent=None, sort_keys=False))


def _geometry(args: argparse.Namespace) -> LegGeometry:
    from whexar.config import load_config
    from whexar.kinematics.geometry import LegGeometry, default_geometry

    if args.config is None:
        return default_geometry()
    return LegGeometry.from_config(load_config(args.config))


# --------------------------------------------------------------------------- config


def _config_check(args: argparse.Namespace) -> int:
    from whexar.config import load_config

    try:
        load_config(args.file)
    except ConfigError as exc:
        count = len(exc.problems)
        print(f"{exc.source}: {count} problem{'s' if count != 1 else ''}")
        for problem in exc.problems:
            print(f"  {problem}")
        return 1
    print("ok")
    return 0


def _config_schema(args: argparse.Namespace) -> int:
    from whexar.config import config_schema

    print(json.dumps(config_schema(), indent=2))
    return 0


# --------------------------------------------------------------------------- kinematics


def _seconds(value: str) -> float:
    try:
        number = float(value)
    except ValueError:
        number = math.nan
    if not math.isfinite(number) or number <= 0:
        raise argparse.ArgumentTypeError(f"{value!r}: expected a number of seconds > 0")
    return number


def _leg(value: str) -> int:
    try:
        return leg_index(value)
    except UsageError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _kin_ik(args: argparse.Namespace) -> int:
    from whexar.kinematics.leg import ik

    geometry = _geometry(args)
    target = np.array([args.x, args.y, args.z]) / 1000.0
    solution = ik(
        target,
        geometry,
        pitch=math.radians(args.pitch),
        target=args.target,
        clamp=args.clamp,
    )
    values = solution.degrees
    degrees = {
        name: round(float(v), 4) + 0.0 for name, v in zip(POSITIONING_JOINTS, values, strict=True)
    }
    if args.json:
        out: dict[str, object] = dict(degrees)
        if args.clamp:
            out["clamped"] = bool(solution.clamped)
        _print_json(out)
        return 0
    print(
        f"leg {args.leg} ({LEG_NAMES[args.leg]}), {args.target} at "
        f"({args.x:g}, {args.y:g}, {args.z:g}) mm, pitch {args.pitch:g}°"
    )
    for name, value in degrees.items():
        print(f"  {name:<11}{value:9.2f}°")
    if args.clamp and solution.any_clamped:
        print("  clamped: the target is out of reach or a joint hit its limit")
    return 0


def _kin_fk(args: argparse.Namespace) -> int:
    from whexar.kinematics.leg import fk

    geometry = _geometry(args)
    angles = np.radians(np.array(args.angles, dtype=np.float64))
    point = fk(angles, geometry, point=args.point) * 1000.0
    xyz = {axis: round(float(v), 4) + 0.0 for axis, v in zip("xyz", point, strict=True)}
    if args.json:
        _print_json(xyz)
        return 0
    print(
        f"leg {args.leg} ({LEG_NAMES[args.leg]}), {args.point} at "
        f"({xyz['x']:.2f}, {xyz['y']:.2f}, {xyz['z']:.2f}) mm in the leg frame"
    )
    return 0


def _kin_gait(args: argparse.Namespace) -> int:
    from whexar.config import RobotConfig, load_config
    from whexar.kinematics.body import leg_to_body, stance_feet
    from whexar.kinematics.gait import GAIT_RANKING, gait
    from whexar.kinematics.stability import gait_stability_margin
    from whexar.kinematics.trajectory import FootTrajectory

    chosen = gait(args.name)
    if args.width < 16:
        raise UsageError(f"--width {args.width}; allowed: 16 characters or more")
    cfg = RobotConfig() if args.config is None else load_config(args.config)
    feet = leg_to_body(stance_feet(cfg.stance(args.stance)))
    trajectory = FootTrajectory(args.step_mm / 1000, args.height_mm / 1000, chosen.duty_factor)
    margin, at = gait_stability_margin(chosen, feet, trajectory)
    if args.json:
        _print_json(
            {
                "gait": chosen.name,
                "duty_factor": chosen.duty_factor,
                "offsets": dict(zip(LEG_NAMES, chosen.offsets, strict=True)),
                "groups": [list(g) for g in chosen.groups],
                "stability_rank": chosen.stability_rank,
                "min_margin_mm": round(margin * 1000, 2),
                "min_margin_phase": round(at, 4),
            }
        )
        return 0
    width = args.width
    phases = np.arange(width) / width
    swinging = chosen.in_swing(phases)
    print(
        f"{chosen.name}: duty factor {chosen.duty_factor:.2f}, "
        f"groups {' | '.join('+'.join(g) for g in chosen.groups)}"
    )
    print(f"stability rank {chosen.stability_rank} in {' < '.join(GAIT_RANKING)}")
    ticks = [" "] * width
    for k in range(4):
        label = f"{k / 4:g}"
        pos = k * width // 4
        ticks[pos : pos + len(label)] = list(label)
    print("       " + "".join(ticks) + "1")
    for leg, row in zip(LEG_NAMES, swinging.T, strict=True):
        print(f"  {leg}   " + "".join("^" if up else "_" for up in row))
    print("       ^ swing   _ stance (thesis Fig. 3.3)")
    print(
        f"smallest static stability margin {1000 * margin:.1f} mm at phase {at:.3f} "
        f"({args.stance} stance, step {args.step_mm:g} mm)"
    )
    return 0


# --------------------------------------------------------------------------- runtime


def _event_line(channel: str, msg: Message) -> None:
    if channel != EVENTS_CHANNEL:
        return
    fields = ", ".join(
        f"{name}={getattr(msg, name)!r}"
        for name in msg.__dataclass_fields__
        if name not in ("t", "source")
    )
    print(f"{msg.t:10.3f}  {type(msg).__name__:<15} {fields}", flush=True)


def _run(args: argparse.Namespace) -> int:
    from whexar.actors.clock import run as run_loop
    from whexar.actors.runtime import Runtime
    from whexar.actors.wiring import load_graph

    graph = load_graph(args.graph)
    runtime = Runtime(graph, handle_signals=True, observer=None if args.quiet else _event_line)

    async def main() -> int:
        return await runtime.run(duration=args.duration)

    code = run_loop(main, virtual=args.virtual)
    print(f"stopped: {runtime.stop_reason}", flush=True)
    if not args.quiet:
        for stats in runtime.stats():
            dropped = ", ".join(f"{k} {v}" for k, v in stats.dropped.items() if v)
            print(
                f"channel {stats.channel}: {stats.published} published"
                + (f", dropped for {dropped}" if dropped else ""),
                flush=True,
            )
    return code


# --------------------------------------------------------------------------- benchmarks


def _bench(args: argparse.Namespace) -> int:
    """Run the suite ``args.bench_command`` (a module of :mod:`whexar.bench`)."""
    import importlib

    suite = importlib.import_module(f"whexar.bench.{args.bench_command}")
    report: Report = suite.run(progress=None if args.json else print)
    if args.json:
        _print_json(report.figures)
    else:
        print(report.render())
    return 0 if report.passed else 1


# --------------------------------------------------------------------------- parser


def build_parser() -> argparse.ArgumentParser:
    """The whole ``whexar`` command tree."""
    parser = argparse.ArgumentParser(
        prog="whexar", description="WHexaR, the wheeled hexapod: runtime and tools."
    )
    parser.add_argument("--version", action="version", version=f"whexar {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    config = commands.add_parser("config", help="check the robot configuration")
    config_cmds = config.add_subparsers(dest="config_command", required=True, metavar="ACTION")
    check = config_cmds.add_parser("check", help="validate a TOML configuration file")
    check.add_argument("file", type=Path, help="e.g. config/whexar.toml")
    check.set_defaults(handler=_config_check)
    schema = config_cmds.add_parser("schema", help="print the JSON Schema of the file")
    schema.set_defaults(handler=_config_schema)

    kin = commands.add_parser("kin", help="leg kinematics in the thesis's leg frame (mm, degrees)")
    kin_cmds = kin.add_subparsers(dest="kin_command", required=True, metavar="ACTION")
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--leg", type=_leg, required=True, help="leg 0–5 or RF, LF, RM, LM, RR, LR")
    common.add_argument("--json", action="store_true", help="print one JSON object")
    common.add_argument(
        "--config", type=Path, default=None, help="robot configuration (default: the thesis robot)"
    )
    ik_cmd = kin_cmds.add_parser(
        "ik",
        parents=[common],
        help="joint angles for a foot target",
        description="Inverse kinematics. X outward, Y down, Z forward from the coxa joint, "
        "in mm, in the leg's own frame (left legs are mirror images, so every leg gives "
        "the same angles for the same leg-frame target). Prints coxa, trochanter, femur, "
        "tibia and tarsus in degrees "
        "(Table 6.5's convention).",
    )
    ik_cmd.add_argument("x", type=float, help="mm outward")
    ik_cmd.add_argument("y", type=float, help="mm down")
    ik_cmd.add_argument("z", type=float, help="mm forward")
    ik_cmd.add_argument(
        "--pitch", type=float, default=0.0, help="body pitch the trochanter follows, degrees"
    )
    ik_cmd.add_argument(
        "--target",
        choices=("tarsus", "contact"),
        default="tarsus",
        help="which point X Y Z gives: the tarsus joint (thesis) or the wheel contact",
    )
    ik_cmd.add_argument(
        "--clamp", action="store_true", help="clamp to the workspace and limits instead of failing"
    )
    ik_cmd.set_defaults(handler=_kin_ik)
    fk_cmd = kin_cmds.add_parser(
        "fk",
        parents=[common],
        help="foot position for joint angles",
        description="Forward kinematics. Angles in degrees, Table 6.5's convention; prints "
        "x, y, z in mm in the leg frame.",
    )
    fk_cmd.add_argument(
        "angles", type=float, nargs=5, metavar="Q", help="coxa trochanter femur tibia tarsus"
    )
    fk_cmd.add_argument(
        "--point",
        choices=("tarsus", "contact"),
        default="tarsus",
        help="the tarsus joint (thesis) or the wheel contact",
    )
    fk_cmd.set_defaults(handler=_kin_fk)
    gait_cmd = kin_cmds.add_parser(
        "gait",
        help="phase chart and stability margin of a gait",
        description="Draw which leg swings when over one cycle, and the smallest static "
        "stability margin of the gait in a stance.",
    )
    gait_cmd.add_argument("name", help="tripod, tetrapod, ripple or wave")
    gait_cmd.add_argument("--stance", default="default", help="stance preset (default: default)")
    gait_cmd.add_argument("--step-mm", type=float, default=100.0, help="step length, mm")
    gait_cmd.add_argument("--height-mm", type=float, default=40.0, help="step height, mm")
    gait_cmd.add_argument("--width", type=int, default=48, help="chart width in characters")
    gait_cmd.add_argument("--json", action="store_true", help="print one JSON object")
    gait_cmd.add_argument(
        "--config", type=Path, default=None, help="robot configuration (default: the thesis robot)"
    )
    gait_cmd.set_defaults(handler=_kin_gait)

    bench = commands.add_parser("bench", help="measure speed against the targets")
    bench_cmds = bench.add_subparsers(dest="bench_command", required=True, metavar="SUITE")
    bench_kin = bench_cmds.add_parser("kin", help="inverse kinematics speed")
    bench_kin.add_argument("--json", action="store_true", help="print the medians as JSON")
    bench_kin.set_defaults(handler=_bench)
    bench_runtime = bench_cmds.add_parser("runtime", help="message passing and virtual time")
    bench_runtime.add_argument("--json", action="store_true", help="print the medians as JSON")
    bench_runtime.set_defaults(handler=_bench)

    run_cmd = commands.add_parser(
        "run",
        help="run an actor graph until SIGINT/SIGTERM (or --duration)",
        description="Start the actors of a wiring file in order, supervise them, and stop "
        "them in reverse order on SIGINT/SIGTERM or after --duration. Prints every runtime "
        "event. Exit status 0 after a clean stop, 3 after an escalation, 1 if the wiring "
        "has problems.",
    )
    run_cmd.add_argument("graph", type=Path, help="wiring file, e.g. config/graphs/demo.toml")
    run_cmd.add_argument(
        "--duration", type=_seconds, default=None, help="stop after this many seconds"
    )
    run_cmd.add_argument(
        "--virtual",
        action="store_true",
        help="run on virtual time (idle time is skipped); give --duration",
    )
    run_cmd.add_argument("--quiet", action="store_true", help="do not print runtime events")
    run_cmd.set_defaults(handler=_run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``whexar`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    handler: Handler = args.handler
    try:
        return handler(args)
    except ConfigError as exc:
        print(f"whexar: {exc}", file=sys.stderr)
        return 1
    except UsageError as exc:
        print(f"whexar: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
