"""``whexar service install | status | logs``: ``whexar run`` as a systemd service.

``install`` fills in the unit shipped with the package (``whexar.service`` beside this
module): ``ExecStart`` runs this Python (so this virtual environment) on the wiring
file given, as the user given, from the folder it is run in (recordings go there);
``TimeoutStopSec`` is the graph's own stop bound with a margin. It writes the unit to
``/etc/systemd/system`` (or ``--dest``) and prints the ``systemctl`` commands that
enable it. ``status`` and ``logs`` call ``systemctl`` and ``journalctl``, and say so in
one line where systemd is absent.
"""

from __future__ import annotations

import argparse
import grp
import importlib.resources
import math
import os
import pwd
import shlex
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Final

from whexar.cli.common import Commands
from whexar.cli.run import assignment
from whexar.errors import ConfigError, Problem, UsageError

UNIT: Final = "whexar.service"
"""The unit's name, and the template's file name in this package."""
SYSTEM_UNITS: Final = Path("/etc/systemd/system")
"""Where an administrator's units go (systemd.unit(5), "Unit File Load Path")."""
GROUPS: Final = ("dialout", "input", "i2c")
"""Serial ports (servo adapter, sensor board), evdev (gamepad), I2C (IMU)."""
STOP_MARGIN_S: Final = 10.0
"""Added to the graph's stop bound: the process's own start and end."""


def unit_template() -> str:
    """The unit shipped with the package, its ``@FIELD@`` placeholders unfilled."""
    return importlib.resources.files("whexar.cli").joinpath(UNIT).read_text()


def render_unit(
    *, exec_start: str, working_directory: Path, user: str, groups: list[str], stop_s: float
) -> str:
    """The unit with its fields filled in."""
    fields = {
        "EXEC_START": exec_start,
        "WORKING_DIRECTORY": str(working_directory),
        "USER": user,
        "GROUPS": " ".join(groups),
        "TIMEOUT_STOP_S": str(math.ceil(stop_s)),
    }
    text = unit_template()
    for key, value in fields.items():
        text = text.replace(f"@{key}@", value)
    return text


def stop_bound_s(graph_path: Path) -> float:
    """The longest ``whexar run`` of ``graph_path`` may take to stop after SIGTERM: one
    ``stop_timeout_s`` per actor, the safe stop's as well (an escalation under way),
    the runtime's grace, and :data:`STOP_MARGIN_S`."""
    from whexar.runtime.supervisor import EXIT_GRACE_S
    from whexar.runtime.wiring import load_graph

    graph = load_graph(graph_path)
    steps = 2 * len(graph.actors) + 1
    return steps * graph.settings.stop_timeout_s + EXIT_GRACE_S + STOP_MARGIN_S


def _existing_groups(names: tuple[str, ...]) -> tuple[list[str], list[str]]:
    """``names`` split into the groups this host has and those it lacks (a unit naming a
    missing group fails to start)."""
    have, missing = [], []
    for name in names:
        try:
            grp.getgrnam(name)
            have.append(name)
        except KeyError:
            missing.append(name)
    return have, missing


def _run_set(value: str) -> str:
    """An argument type: a ``--set`` for ``whexar run``, refused now if malformed (not at
    the robot's next boot), kept as typed."""
    assignment(value)
    return value


def _default_user() -> str:
    """Who asked: the caller of sudo, else the user running this."""
    sudo = os.environ.get("SUDO_USER")
    return sudo if os.getuid() == 0 and sudo else pwd.getpwuid(os.getuid()).pw_name


def _install(args: argparse.Namespace) -> int:
    graph: Path = args.graph.resolve()
    if not graph.is_file():
        raise ConfigError(str(args.graph), [Problem("graph", str(args.graph), "a wiring file")])
    user: str = args.user or _default_user()
    try:
        pwd.getpwnam(user)
    except KeyError:
        raise UsageError(f"--user {user}: no such user on this host") from None
    groups, missing = _existing_groups(GROUPS)
    run_args = ["run", str(graph)]
    if args.config is not None:
        from whexar.config import load_config

        config: Path = args.config.resolve()
        load_config(config)  # a bad file is named now, not at the next boot
        run_args += ["--config", str(config)]
    for value in args.set:
        run_args += ["--set", value]
    exec_start = shlex.join([sys.executable, "-m", "whexar.cli", *run_args])
    text = render_unit(
        exec_start=exec_start,
        working_directory=Path.cwd(),
        user=user,
        groups=groups,
        stop_s=stop_bound_s(graph),
    )
    dest: Path = args.dest / UNIT
    try:
        dest.parent.mkdir(parents=True, exist_ok=True)
        dest.write_text(text)
    except PermissionError:
        print(
            f"whexar: cannot write {dest}: permission denied; run it with sudo, "
            f"or give --dest DIR and copy DIR/{UNIT} to {SYSTEM_UNITS}",
            file=sys.stderr,
        )
        return 1
    print(f"wrote {dest}")
    if missing:
        print(f"note: this host has no group {', '.join(missing)}; left out of the unit")
    if args.dest.resolve() != SYSTEM_UNITS:
        print(f"copy it into place: sudo cp {shlex.quote(str(dest))} {SYSTEM_UNITS}/")
    print("then:")
    print("  sudo systemctl daemon-reload")
    print(f"  sudo systemctl enable --now {UNIT}")
    print("  whexar service status     # systemctl status")
    print("  whexar service logs -f    # journalctl")
    return 0


SYSTEMD_BOOTED: Final = Path("/run/systemd/system")
"""Exists when systemd is the init system (sd_booted(3))."""


def _systemd_tool(name: str) -> str | None:
    """The path of ``systemctl`` or ``journalctl``, or ``None`` with one line saying why."""
    path = shutil.which(name)
    booted = SYSTEMD_BOOTED
    if path is None:
        print(f"whexar: systemd is absent here (no {name} on PATH)", file=sys.stderr)
    elif not booted.is_dir():
        print(f"whexar: systemd is not running here (no {booted}, sd_booted(3))", file=sys.stderr)
        return None
    return path


def _status(args: argparse.Namespace) -> int:
    tool = _systemd_tool("systemctl")
    if tool is None:
        return 1
    # systemctl status exits 3 for a unit that is not running: its own answer, passed on.
    return subprocess.call([tool, "status", "--no-pager", UNIT])


def _logs(args: argparse.Namespace) -> int:
    tool = _systemd_tool("journalctl")
    if tool is None:
        return 1
    command = [tool, "--no-pager", "-u", UNIT, "-n", str(args.lines)]
    if args.follow:
        command.append("-f")
    try:
        return subprocess.call(command)
    except KeyboardInterrupt:  # the end of -f
        return 0


def add_commands(commands: Commands) -> None:
    """Add this group's commands to the ``whexar`` command table."""
    service = commands.add_parser(
        "service",
        help="run whexar as a systemd service: install | status | logs",
        description="Install, inspect and read the logs of the whexar systemd unit "
        "(Type=notify, a watchdog fed by the control loop, rate-limited restarts).",
    )
    actions = service.add_subparsers(dest="action", required=True, metavar="ACTION")
    install = actions.add_parser(
        "install",
        help="write the unit for this install",
        description=f"Write {UNIT} with ExecStart running this Python on GRAPH, as USER, "
        "from the current folder (where recordings go), and print the systemctl commands.",
    )
    install.add_argument(
        "graph",
        type=Path,
        nargs="?",
        default=Path("config/graphs/walk.toml"),
        help="wiring file (default: config/graphs/walk.toml)",
    )
    install.add_argument(
        "--user",
        default=None,
        help="the user the service runs as (default: you, or the sudo caller)",
    )
    install.add_argument(
        "--dest",
        type=Path,
        default=SYSTEM_UNITS,
        metavar="DIR",
        help=f"folder to write {UNIT} into (default: {SYSTEM_UNITS})",
    )
    install.add_argument(
        "--config",
        type=Path,
        default=None,
        metavar="FILE",
        help="the robot configuration, passed to whexar run --config (checked now)",
    )
    install.add_argument(
        "--set",
        type=_run_set,
        action="append",
        default=[],
        metavar="ACTOR.PARAM=VALUE",
        help="passed to whexar run (repeatable), e.g. --set bus.port=/dev/ttyUSB0",
    )
    install.set_defaults(handler=_install)
    status = actions.add_parser("status", help=f"systemctl status {UNIT}")
    status.set_defaults(handler=_status)
    logs = actions.add_parser("logs", help=f"journalctl -u {UNIT}")
    logs.add_argument("-n", "--lines", type=int, default=100, help="lines to show (default 100)")
    logs.add_argument("-f", "--follow", action="store_true", help="keep printing new lines")
    logs.set_defaults(handler=_logs)
