"""``whexar run``: run an actor graph from a wiring file, printing the runtime's events.

One line per event; a failure (``ActorFailed``) is followed by its traceback,
indented under it.

The wiring file can be changed for one run without editing it:
``--set ACTOR.PARAM=VALUE`` overrides a parameter of one actor before the
graph is built and checked (VALUE is read as a TOML value — ``3``, ``true``,
``"x"`` — or else taken as a plain string). ``--commands FILE`` and
``--keyboard`` are short for ``--set commands.source=FILE`` and
``--set commands.source=keyboard``, ``--gamepad [DEVICE]`` for
``--set commands.source=gamepad[:DEVICE]``: the graph's actor named ``commands`` (a
:class:`~whexar.actors.commands.CommandSource`) then plays a command script,
reads the keyboard or a gamepad. ``--config FILE`` gives every actor that reads
the robot configuration that file (``--set ACTOR.config=FILE`` for each). While
the keyboard's status line is on the terminal, each event line first clears it;
the actor redraws it at its next update.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import textwrap
import tomllib
from fnmatch import fnmatchcase
from pathlib import Path
from typing import TYPE_CHECKING

from whexar.cli.common import (
    CLEAR_LINE,
    DEFAULT_LIVE_PORT,
    RECORDINGS,
    Commands,
    default_recording,
    seconds,
    tcp_port,
)
from whexar.errors import ConfigError, Problem, UsageError
from whexar.runtime.messages import ActorFailed, Message
from whexar.runtime.notify import Notifier, ServiceNotes, service_observer, watchdog_period_s
from whexar.runtime.wiring import EVENTS_CHANNEL, actor_names, set_param

if TYPE_CHECKING:
    from whexar.config import RobotConfig
    from whexar.record.live import LiveView
    from whexar.record.sidecar import AnyRecorder
    from whexar.runtime.channels import Observer
    from whexar.runtime.wiring import Graph

COMMANDS_ACTOR = "commands"
"""The actor ``--commands``, ``--keyboard`` and ``--gamepad`` set the ``source`` of."""

_BELOW = " " * 12
"""Indent of what follows an event line (a traceback), under the event's name."""


def _event_printer(prefix: str = "", shown: list[Message] | None = None) -> Observer:
    """An observer printing each runtime event as one line, each line starting with
    ``prefix``; the recorder's events printed (a deletion, a stop) go into ``shown``."""
    from whexar.actors.messages import RecordingDeleted, RecordingStopped

    recorder_events = (RecordingDeleted, RecordingStopped)

    def print_event(channel: str, msg: Message) -> None:
        if channel != EVENTS_CHANNEL:
            return
        if shown is not None and isinstance(msg, recorder_events):
            shown.append(msg)
        fields = ", ".join(
            f"{name}={getattr(msg, name)!r}"
            for name in msg.__dataclass_fields__
            if name not in ("t", "source", "traceback")
        )
        # The runtime calls this inside its own bookkeeping (a stop request too): a
        # terminal that went away must cost the event line, not the stop.
        with contextlib.suppress(OSError):
            print(f"{prefix}{msg.t:10.3f}  {type(msg).__name__:<15} {fields}", flush=True)
            if isinstance(msg, ActorFailed) and msg.traceback:
                print(prefix + textwrap.indent(msg.traceback.rstrip("\n"), _BELOW), flush=True)

    return print_event


# --------------------------------------------------------------------------- overrides


def assignment(value: str) -> tuple[str, object]:
    """An argument type: ``ACTOR.PARAM=VALUE`` → (``ACTOR.PARAM``, VALUE read as TOML)."""
    target, sep, text = value.partition("=")
    target = target.strip()
    if not sep or "." not in target or target.startswith(".") or target.endswith("."):
        raise argparse.ArgumentTypeError(f"{value!r}: expected ACTOR.PARAM=VALUE")
    return target, toml_value(text)


def toml_value(text: str) -> object:
    """``text`` read as a TOML value (``3``, ``0.5``, ``true``, ``"x"``, ``[1, 2]``), else itself.

    So ``port=/dev/ttyUSB0`` needs no quotes, and ``name="3"`` is the string.
    """
    try:
        return tomllib.loads(f"value = {text}")["value"]
    except tomllib.TOMLDecodeError:
        return text


def _overrides(args: argparse.Namespace) -> list[tuple[str, object, str]]:
    """Every override the options ask for, in order: (target, value, option)."""
    found = [(target, value, "--set") for target, value in args.set]
    if args.commands is not None:
        path: Path = args.commands
        if not path.is_file():
            raise ConfigError(
                str(path), [Problem("--commands", str(path), "an existing command script file")]
            )
        found.append((f"{COMMANDS_ACTOR}.source", str(path), "--commands"))
    if args.keyboard:
        found.append((f"{COMMANDS_ACTOR}.source", "keyboard", "--keyboard"))
    if args.gamepad is not None:
        pad = f"gamepad:{args.gamepad}" if args.gamepad else "gamepad"
        found.append((f"{COMMANDS_ACTOR}.source", pad, "--gamepad"))
    return found


def _stdin_is_a_terminal() -> bool:
    try:
        return sys.stdin is not None and sys.stdin.isatty()
    except (AttributeError, OSError, ValueError):
        return False


def load_run_graph(args: argparse.Namespace) -> Graph:
    """The wiring file of ``args.graph`` with the options' overrides, built and checked."""
    from whexar.actors.graph import CONFIGURED, with_reflexes
    from whexar.config import load_config
    from whexar.runtime.schema import read_toml
    from whexar.runtime.wiring import build_graph

    if args.keyboard and args.virtual:
        raise UsageError(
            "--keyboard reads a person's keys in real time; it cannot run with --virtual "
            "(give --commands FILE for a run on virtual time)"
        )
    if args.keyboard and not _stdin_is_a_terminal():
        raise UsageError("--keyboard needs a terminal on stdin; pipe commands with stdin instead")
    if args.gamepad is not None and args.virtual:
        raise UsageError(
            "--gamepad reads a person's gamepad in real time; it cannot run with --virtual "
            "(give --commands FILE for a run on virtual time)"
        )
    overrides = _overrides(args)
    if args.config is not None:
        load_config(args.config)  # a bad file is named, key by key, before any actor starts
    source = str(args.graph)
    data = read_toml(args.graph)
    with_reflexes(data, source=source, config=args.config)  # [[reflexes]]: their actors
    if args.config is None and not overrides:
        return build_graph(data, source=source)
    names = actor_names(data)
    chosen = [
        option
        for option, given in (
            ("--commands", args.commands is not None),
            ("--keyboard", args.keyboard),
            ("--gamepad", args.gamepad is not None),
        )
        if given
    ]
    if chosen and COMMANDS_ACTOR not in names:
        option = chosen[0]
        raise ConfigError(
            source,
            [
                Problem(
                    option,
                    COMMANDS_ACTOR,
                    f"a graph with an actor named {COMMANDS_ACTOR!r} "
                    f"(whexar.actors.commands:CommandSource); its actors: "
                    f"{', '.join(names) or 'none'}",
                )
            ],
        )
    if args.config is not None:
        # Before the --set options, so that one of them can still change an actor's.
        configured = [n for n in names if any(fnmatchcase(n, p) for p in CONFIGURED)]
        if not configured:
            raise ConfigError(
                source,
                [
                    Problem(
                        "--config",
                        str(args.config),
                        f"a graph with actors that read a robot configuration "
                        f"({', '.join(CONFIGURED)}); its actors: {', '.join(names) or 'none'}",
                    )
                ],
            )
        overrides = [(f"{n}.config", str(args.config), "--config") for n in configured] + overrides
    for target, value, option in overrides:
        set_param(data, target, value, source=source, option=option)
    return build_graph(data, source=source)


# --------------------------------------------------------------------------- the command


def _run(args: argparse.Namespace) -> int:
    import anyio

    from whexar.runtime.channels import fan_out
    from whexar.runtime.clock import run as run_loop
    from whexar.runtime.supervisor import Runtime

    graph = load_run_graph(args)
    shown: list[Message] = []
    """The recorder's events printed while the runtime ran."""
    printer = None if args.quiet else _event_printer(CLEAR_LINE if args.keyboard else "", shown)
    live = None
    if args.live is not None:
        from whexar.record.live import LiveView

        live = LiveView(args.live)
        print(f"live view: {live.url} (Foxglove: open a WebSocket connection)", flush=True)
    recorder = None if args.no_record and live is None else _recorder(args, graph, live)
    observers: list[Observer] = [o for o in (printer, recorder) if o is not None]
    notifier = Notifier()
    if notifier.enabled:  # under systemd: READY, WATCHDOG from the cycles, STOPPING
        # The run's clock, read when a message is published (the runtime exists by then).
        observers.append(
            service_observer(_service_notes(graph), notifier, lambda: runtime.clock.now())
        )
    runtime = Runtime(
        graph,
        handle_signals=True,
        observer=fan_out(*observers) if observers else None,
        link_observer=None if recorder is None else recorder.link_bytes,
    )

    async def main() -> int:
        if recorder is None:
            return await runtime.run(duration=args.duration)
        failure: BaseException | None = None
        code = 0
        async with anyio.create_task_group() as tg:
            # The recorder writes between cycles, on the runtime's clock, a bounded
            # time at a time (whexar.record.writer.WRITE_BUDGET_S), and keeps its budget:
            # each deletion and a stop is an event, printed as the others.
            tg.start_soon(lambda: recorder.run(lambda s: runtime.clock.sleep(s), runtime=runtime))
            try:
                code = await runtime.run(duration=args.duration)
            except BaseException as exc:  # raised as it is, not in a task group's wrapping
                failure = exc
            tg.cancel_scope.cancel()
        if failure is not None:
            raise failure
        return code

    try:
        code = run_loop(main, virtual=args.virtual)
    finally:
        if recorder is not None:
            recorder.close()
            if printer is not None:
                # The budget's last checks end with the run (a recording process tells of
                # its first one when it can): what the runtime did not see is printed now.
                for event in recorder.events:
                    if not any(event is seen for seen in shown):
                        printer(EVENTS_CHANNEL, event)
            if not args.no_record:
                stopped = "" if recorder.stopped is None else f" (stopped: {recorder.stopped})"
                print(f"recording: {recorder.path}{stopped}", flush=True)
        if live is not None:
            live.close()
        notifier.close()
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


def _service_notes(graph: Graph) -> ServiceNotes:
    """What to tell systemd for ``graph``: progress is the bus scheduler's cycles (each
    publishes :class:`~whexar.actors.messages.ServoStates`); a graph without a servo bus
    (a demonstration) counts any message but the runtime's events."""
    from whexar.actors.messages import ServoStates
    from whexar.runtime.messages import Message

    bus = any(issubclass(ch.message_type, ServoStates) for ch in graph.channels.values())
    return ServiceNotes(
        actors=frozenset(node.name for node in graph.actors),
        watchdog_s=watchdog_period_s(os.environ, os.getpid()),
        progress=(ServoStates,) if bus else (Message,),
    )


def _recorder(args: argparse.Namespace, graph: Graph, live: LiveView | None) -> AnyRecorder:
    """The run's recorder: the wiring file and the robot configuration attached, the
    command line in its metadata; it feeds the live view, and records to nowhere with
    ``--no-record``."""
    from whexar.record.runs import run_recorder

    if args.no_record:
        path: Path | str = os.devnull
    else:
        path = args.record or default_recording(args.graph.stem)
    config, cfg = _robot_config(graph)
    metadata = {
        "kind": "run",
        "clock": "virtual" if args.virtual else "real",
        "graph": str(args.graph),
        "command": " ".join(sys.argv),
    }
    if args.duration is not None:
        metadata["duration_s"] = repr(float(args.duration))
    wiring = {f"wiring{args.graph.suffix}": args.graph.read_bytes()}
    return run_recorder(path, cfg, config, wiring, metadata, live, urdf=_urdf(cfg))


def _urdf(cfg: RobotConfig) -> str | None:
    """The robot's URDF for Foxglove's 3D view, where the simulation's packages are
    installed (it compiles the model); the robot's plain install records without it."""
    try:
        from whexar.sim.urdf import build_urdf

        return build_urdf(cfg)
    except ImportError:  # MuJoCo, of whexar[sim]
        return None


def _robot_config(graph: Graph) -> tuple[Path | None, RobotConfig]:
    """The robot configuration the graph's actors read (the first ``config`` an actor
    names; the built-in thesis robot when none does), and its file."""
    from whexar.config import RobotConfig, load_config

    for node in graph.actors:
        path = getattr(node.params, "config", None)
        if isinstance(path, str | Path):
            return Path(path), load_config(path)
    return None, RobotConfig()


def add_commands(commands: Commands) -> None:
    """Add this group's commands to the ``whexar`` command table."""
    run_cmd = commands.add_parser(
        "run",
        help="run an actor graph until SIGINT/SIGTERM (or --duration)",
        description="Start the actors of a wiring file in order, supervise them, and stop "
        "them in reverse order on SIGINT/SIGTERM or after --duration, each step bounded by "
        "stop_timeout_s; a second SIGINT runs the safe stop and exits at once (status 130). "
        "Prints every runtime event, and the traceback of every failure. Exit status 0 after "
        "a clean stop, 3 after an escalation, 1 if the wiring has problems, 2 if virtual time "
        "refused real I/O (allow it with [runtime] real_io_on_virtual_time = true), 4 if a "
        "device was missing, busy or not permitted at start (no restart; whexar doctor says "
        "how to fix it).",
    )
    run_cmd.add_argument("graph", type=Path, help="wiring file, e.g. config/graphs/demo.toml")
    run_cmd.add_argument(
        "--duration", type=seconds, default=None, help="stop after this many seconds"
    )
    run_cmd.add_argument(
        "--virtual",
        action="store_true",
        help="run on virtual time (idle time is skipped); give --duration",
    )
    run_cmd.add_argument("--quiet", action="store_true", help="do not print runtime events")
    run_cmd.add_argument(
        "--config",
        type=Path,
        default=None,
        metavar="FILE",
        help="the robot configuration every actor that reads one gets (the robot graph's "
        "bus, sensors, imu, legs, coordinator, commands): --set ACTOR.config=FILE for each",
    )
    run_cmd.add_argument(
        "--set",
        type=assignment,
        action="append",
        default=[],
        metavar="ACTOR.PARAM=VALUE",
        help="override a parameter of one actor of the wiring file (repeatable); VALUE is "
        'read as TOML (3, true, "x") or else taken as a string',
    )
    source = run_cmd.add_mutually_exclusive_group()
    source.add_argument(
        "--commands",
        type=Path,
        default=None,
        metavar="FILE",
        help="play this command script (JSON lines with a time t each): "
        f"--set {COMMANDS_ACTOR}.source=FILE",
    )
    source.add_argument(
        "--keyboard",
        action="store_true",
        help="drive from the keyboard (arrows/WASD, space stops, x quits; real time only): "
        f"--set {COMMANDS_ACTOR}.source=keyboard",
    )
    source.add_argument(
        "--gamepad",
        nargs="?",
        const="",
        default=None,
        metavar="DEVICE",
        help="drive with a gamepad (/dev/input/eventN; without DEVICE the [gamepad] "
        "section's; hold the dead-man, LB/L1, to drive; real time only): "
        f"--set {COMMANDS_ACTOR}.source=gamepad:DEVICE",
    )
    recording = run_cmd.add_mutually_exclusive_group()
    recording.add_argument(
        "--record",
        type=Path,
        metavar="FILE.mcap",
        help="record every message and every byte of the device links into FILE "
        f"(default: {RECORDINGS}/GRAPH-DATE.mcap)",
    )
    recording.add_argument("--no-record", action="store_true", help="do not record the run")
    run_cmd.add_argument(
        "--live",
        type=tcp_port,
        nargs="?",
        const=DEFAULT_LIVE_PORT,
        metavar="PORT",
        help="serve the run to the Foxglove app on localhost:PORT (default 8765)",
    )
    run_cmd.set_defaults(handler=_run)
