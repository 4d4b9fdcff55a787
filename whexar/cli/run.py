"""``whexar run``: run an actor graph from a wiring file, printing the runtime's events.

One line per event; a failure (``ActorFailed``) is followed by its traceback,
indented under it.
"""

from __future__ import annotations

import argparse
import textwrap
from pathlib import Path

from whexar.cli.common import Commands, seconds
from whexar.runtime.messages import ActorFailed, Message
from whexar.runtime.wiring import EVENTS_CHANNEL

_BELOW = " " * 12
"""Indent of what follows an event line (a traceback), under the event's name."""


def _event_line(channel: str, msg: Message) -> None:
    if channel != EVENTS_CHANNEL:
        return
    fields = ", ".join(
        f"{name}={getattr(msg, name)!r}"
        for name in msg.__dataclass_fields__
        if name not in ("t", "source", "traceback")
    )
    print(f"{msg.t:10.3f}  {type(msg).__name__:<15} {fields}", flush=True)
    if isinstance(msg, ActorFailed) and msg.traceback:
        print(textwrap.indent(msg.traceback.rstrip("\n"), _BELOW), flush=True)


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
        "refused real I/O (allow it with [runtime] real_io_on_virtual_time = true).",
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
    run_cmd.set_defaults(handler=_run)
