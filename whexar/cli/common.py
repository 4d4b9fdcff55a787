"""What every command group shares: the handler type, JSON output, argument types."""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable
from typing import TypeAlias

Handler: TypeAlias = Callable[[argparse.Namespace], int]
"""A command: parsed arguments in, exit status out."""
Commands: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"
"""The ``whexar`` subcommand table each group adds its commands to."""


def print_json(value: object) -> None:
    """Print ``value`` as one line of JSON."""
    print(json.dumps(value, indent=None, sort_keys=False))


def seconds(value: str) -> float:
    """An argument type: a finite number of seconds > 0."""
    try:
        number = float(value)
    except ValueError:
        number = math.nan
    if not math.isfinite(number) or number <= 0:
        raise argparse.ArgumentTypeError(f"{value!r}: expected a number of seconds > 0")
    return number
