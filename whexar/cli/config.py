"""``whexar config …``: check a robot configuration file, print its JSON Schema."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from whexar.cli.common import Commands, print_json, print_problems
from whexar.errors import ConfigError


def _config_check(args: argparse.Namespace) -> int:
    from whexar.config import load_config

    try:
        load_config(args.file)
    except ConfigError as exc:
        print_problems(exc, sys.stdout)
        return 1
    print("ok")
    return 0


def _config_schema(args: argparse.Namespace) -> int:
    from whexar.config import config_schema

    print_json(config_schema(), indent=2)
    return 0


def add_commands(commands: Commands) -> None:
    """Add this group's commands to the ``whexar`` command table."""
    config = commands.add_parser("config", help="check the robot configuration")
    config_cmds = config.add_subparsers(dest="config_command", required=True, metavar="ACTION")
    check = config_cmds.add_parser("check", help="validate a TOML configuration file")
    check.add_argument("file", type=Path, help="e.g. config/whexar.toml")
    check.set_defaults(handler=_config_check)
    schema = config_cmds.add_parser("schema", help="print the JSON Schema of the file")
    schema.set_defaults(handler=_config_schema)
