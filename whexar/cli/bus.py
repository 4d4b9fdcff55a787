"""``whexar emulate`` and ``whexar bus …``: the servo emulator (and the sensor board's) on a
pty, a bus scan."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from whexar.cli.common import Commands, print_json

if TYPE_CHECKING:
    from whexar.config import RobotConfig
    from whexar.sensors.board_pty import BoardPty


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
    board = _board_pty(cfg) if args.board else None

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
            if board is not None:
                spec = cfg.sensor_board
                print(
                    f"sensor board emulator: on {board.path} at {spec.baudrate} bps, "
                    f"{spec.frame_rate_hz:g} frames/s until rate=N#",
                    flush=True,
                )
            print(f"{timing}; {fast}; {faults}; stop with SIGINT or SIGTERM", flush=True)
            while not stop.wait(0.5):
                if board is not None and board.error is not None:
                    raise board.error
        stats = emulator.stats
    finally:
        if board is not None:
            board.close()
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
        print_json([servo.as_dict() for servo in found])
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


def _board_pty(cfg: RobotConfig) -> BoardPty:
    """The configuration's sensor board, emulated on its own pty (level, legs unloaded)."""
    from whexar.actors.sensing import emulated_board
    from whexar.sensors.board_pty import BoardPty

    return BoardPty(emulated_board(cfg.sensor_board))


def add_commands(commands: Commands) -> None:
    """Add this group's commands to the ``whexar`` command table."""
    emulate = commands.add_parser(
        "emulate",
        help="serve emulated servos on a pseudo-terminal until SIGINT/SIGTERM",
        description="Emulate the robot's servo bus (Protocol 2.0) on a pseudo-terminal, "
        "in real time: each reply is written when the modelled bus would deliver it. "
        "The first line names the pty; open it like a serial port (dynamixel-sdk, "
        "whexar bus scan --port …). Fault lines follow as faults start and end. Exit "
        "status 0 after SIGINT/SIGTERM, 1 if the configuration or the fault plan has "
        "problems. With --board, a line names a second pty: the sensor board's.",
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
    emulate.add_argument(
        "--board",
        action="store_true",
        help="also emulate the sensor board (firmware/PROTOCOL.md) on a second pty, in "
        "real time: for whexar doctor --board-port, whexar sensors --port, whexar run "
        "--set sensors.port=PTY",
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
