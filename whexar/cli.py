"""``whexar`` command line.

Exit codes: 0 success; 1 a configuration with problems, a benchmark that
missed its target, or a bus scan that found no servo (or could not open its
port); 2 bad input (an unknown leg, an unreachable target, a malformed
option); 3 ``whexar run`` stopped after an actor was escalated.
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
from whexar.errors import ConfigError, UsageError
from whexar.robot import LEG_NAMES, POSITIONING_JOINTS, leg_index
from whexar.runtime.messages import Message
from whexar.runtime.wiring import EVENTS_CHANNEL

if TYPE_CHECKING:
    from whexar.bench import Report
    from whexar.kinematics.geometry import LegGeometry

Handler = Callable[[argparse.Namespace], int]


def _print_json(value: object) -> None:
    print(json.dumps(value, indent=None, sort_keys=False))


def _geometry(args: argparse.Namespace) -> LegGeometry:
    from whexar.config import default_geometry, load_config

    if args.config is None:
        return default_geometry()
    return load_config(args.config).leg_geometry()


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
    feet = leg_to_body(stance_feet(cfg.stance(args.stance)), cfg.leg_geometry())
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
    from whexar.runtime.clock import run as run_loop
    from whexar.runtime.supervisor import Runtime
    from whexar.runtime.wiring import load_graph

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
        _print_json(report.json)
    else:
        print(report.render())
    return 0 if report.passed else 1


# --------------------------------------------------------------------------- servo bus


def _baud(value: str) -> int:
    from whexar.bus.scan import BAUDRATES

    try:
        rate = int(value)
    except ValueError:
        rate = -1
    if rate not in BAUDRATES:
        allowed = ", ".join(str(b) for b in BAUDRATES)
        raise argparse.ArgumentTypeError(f"{value!r}: allowed baud rates: {allowed}")
    return rate


def _fault_line(t: float, text: str) -> None:
    print(f"{t:10.3f}  {text}", flush=True)


def _emulate(args: argparse.Namespace) -> int:
    import signal
    import threading
    from types import FrameType

    from whexar.bus.emulator.chain import ServoChain
    from whexar.bus.emulator.faults import FaultInjector, load_fault_plan
    from whexar.bus.emulator.pty import PtyEmulator
    from whexar.bus.emulator.timing import TimingModel
    from whexar.config import RobotConfig, load_config

    cfg = RobotConfig() if args.servos is None else load_config(args.servos)
    plan = None if args.faults is None else load_fault_plan(args.faults)
    baud = cfg.bus.baudrate if args.baud is None else args.baud
    # The robot's servos hold the configured Return Delay Time in EEPROM.
    chain = ServoChain.for_models(
        cfg.servos(),
        timing=TimingModel(baudrate=baud),
        fast_sync_read=args.fast_sync_read,
        return_delay_us=cfg.bus.return_delay_time_us,
    )
    if plan is not None:
        FaultInjector(plan, on_log=_fault_line).attach(chain)
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        with PtyEmulator(chain, realtime=not args.no_realtime) as emulator:
            print(
                f"servo emulator: {len(chain.servos)} servos on {emulator.path} at {baud} bps",
                flush=True,
            )
            timing = "answers at once" if args.no_realtime else "answers in real time"
            faults = f"fault plan {args.faults}" if plan is not None else "no faults"
            fast = "fast sync read on" if args.fast_sync_read else "fast sync read off"
            print(f"{timing}; {fast}; {faults}; stop with SIGINT or SIGTERM", flush=True)
            while not stop.wait(0.5):
                pass
        stats = emulator.stats
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    print(
        f"stopped: {stats.requests} requests, {stats.garbage_bytes} garbage bytes, "
        f"{stats.partial_packets} partial packets, {stats.errors} errors",
        flush=True,
    )
    return 0


def _bus_scan(args: argparse.Namespace) -> int:
    from whexar.bus.scan import scan
    from whexar.errors import DeviceGoneError

    try:
        found = scan(args.port, args.baud)
    except DeviceGoneError as exc:
        print(f"whexar: {exc}", file=sys.stderr)
        return 1
    if args.json:
        _print_json([servo.as_dict() for servo in found])
    elif found:
        print(f"{'ID':>3}  {'model':<8} {'firmware':>8}  hardware errors")
        for servo in found:
            print(
                f"{servo.id:>3}  {servo.model:<8} {servo.firmware:>8}  {servo.hardware_error_text}"
            )
        print(f"{len(found)} servo{'s' if len(found) != 1 else ''} on {args.port}")
    if not found:
        print(f"no servo answered on {args.port} at {args.baud} bps", file=sys.stderr)
    return 0 if found else 1


# --------------------------------------------------------------------------- sensor board


def _sensors(args: argparse.Namespace) -> int:
    from whexar.monitor import observer
    from whexar.runtime.clock import run as run_loop
    from whexar.runtime.supervisor import Runtime
    from whexar.runtime.wiring import build_graph
    from whexar.testing.sensors import sensor_graph

    params: dict[str, object] = {}
    if args.baud is not None:
        params["baudrate"] = args.baud
    if args.config is not None:
        params["config"] = str(args.config)
    if args.protocol is not None:
        params["protocol"] = args.protocol
    graph = build_graph(sensor_graph(args.port, params, outputs=("frames",)))

    def write(line: str) -> None:
        print(line, flush=True)

    runtime = Runtime(graph, handle_signals=True, observer=observer(args.json, write))
    if not args.json:
        print(f"reading {args.port}; stop with Ctrl-C", flush=True)

    async def main() -> int:
        return await runtime.run(duration=args.duration)

    return run_loop(main)


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
    bench_bus = bench_cmds.add_parser(
        "bus", help="servo bus cycle rates per read plan, CPU per cycle, real time over a pty"
    )
    bench_bus.add_argument("--json", action="store_true", help="print the figures as JSON")
    bench_bus.set_defaults(handler=_bench)
    bench_sensors = bench_cmds.add_parser(
        "sensors", help="sensor frame decoding speed and frame-to-message latency (real time)"
    )
    bench_sensors.add_argument("--json", action="store_true", help="print the medians as JSON")
    bench_sensors.set_defaults(handler=_bench)

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

    emulate = commands.add_parser(
        "emulate",
        help="serve emulated servos on a pseudo-terminal until SIGINT/SIGTERM",
        description="Emulate the robot's servo bus (Protocol 2.0) on a pseudo-terminal, "
        "in real time: each reply is written when the modelled bus would deliver it. "
        "The first line names the pty; open it like a serial port (dynamixel-sdk, "
        "whexar bus scan --port …). Fault lines follow as faults start and end. Exit "
        "status 0 after SIGINT/SIGTERM, 1 if the configuration or the fault plan has "
        "problems.",
    )
    emulate.add_argument(
        "--servos",
        type=Path,
        default=None,
        metavar="CONFIG",
        help="robot configuration giving the servos (default: the thesis robot)",
    )
    emulate.add_argument(
        "--faults",
        type=Path,
        default=None,
        metavar="FILE",
        help="fault plan, e.g. config/faults/noisy-bus.toml",
    )
    emulate.add_argument(
        "--baud", type=_baud, default=None, help="modelled bus rate (default: the config's)"
    )
    emulate.add_argument(
        "--no-realtime", action="store_true", help="answer at once instead of in bus time"
    )
    emulate.add_argument(
        "--fast-sync-read",
        action="store_true",
        help="let the servos answer Fast Sync Read (unconfirmed on MX firmware)",
    )
    emulate.set_defaults(handler=_emulate)

    bus = commands.add_parser("bus", help="the Dynamixel servo bus")
    bus_cmds = bus.add_subparsers(dest="bus_command", required=True, metavar="ACTION")
    bus_scan = bus_cmds.add_parser(
        "scan",
        help="list the servos that answer on a port",
        description="Broadcast-ping a Protocol 2.0 bus and read each servo's model, "
        "firmware version and Hardware Error Status. Exit status 0 when at least one "
        "servo answered, 1 when none did or the port cannot be opened.",
    )
    bus_scan.add_argument("--port", required=True, help="e.g. /dev/ttyUSB0 or an emulator's pty")
    bus_scan.add_argument("--baud", type=_baud, default=1_000_000, help="default: 1000000")
    bus_scan.add_argument("--json", action="store_true", help="print one JSON list")
    bus_scan.set_defaults(handler=_bus_scan)

    sensors = commands.add_parser(
        "sensors",
        help="print the sensor board's frames as they arrive",
        description="Read the sensor board (firmware/PROTOCOL.md) through the real sensor "
        "reader and print each decoded frame: raw counts, IR distances (eq. 5.5), FSR "
        "counts and contact flags, roll and pitch, sequence number; and a line for every "
        "link event, sequence gap and rejected frame. Runs until SIGINT/SIGTERM or "
        "--duration. Exit status 0 after a clean stop.",
    )
    sensors.add_argument(
        "--port", required=True, help="e.g. /dev/ttyACM0, the pty of whexar-sim, or 'emulator'"
    )
    sensors.add_argument(
        "--baud", type=int, default=None, help="default: sensor_board.baudrate (1000000)"
    )
    sensors.add_argument(
        "--config", type=Path, default=None, help="robot configuration (calibrations, thresholds)"
    )
    sensors.add_argument(
        "--protocol",
        choices=("checked", "thesis"),
        default=None,
        help="checked: frames need seq and crc (default); thesis: plain frames too",
    )
    sensors.add_argument("--json", action="store_true", help="one JSON object per line")
    sensors.add_argument(
        "--duration", type=_seconds, default=None, help="stop after this many seconds"
    )
    sensors.set_defaults(handler=_sensors)
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
