"""What every command group shares: the handler type, JSON output, argument types."""

from __future__ import annotations

import argparse
import json
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Final, TypeAlias

from whexar.errors import UsageError
from whexar.runtime.clock import wall_stamp

Handler: TypeAlias = Callable[[argparse.Namespace], int]
"""A command: parsed arguments in, exit status out."""
Commands: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"
"""The ``whexar`` subcommand table each group adds its commands to."""


def print_json(value: object) -> None:
    """Print ``value`` as one line of JSON."""
    print(json.dumps(value, indent=None, sort_keys=False))


def _number(value: str, allowed: Callable[[float], bool], expected: str) -> float:
    try:
        number = float(value)
    except ValueError:
        number = math.nan
    if not math.isfinite(number) or not allowed(number):
        raise argparse.ArgumentTypeError(f"{value!r}: expected {expected}")
    return number


def seconds(value: str) -> float:
    """An argument type: a finite number of seconds > 0."""
    return _number(value, lambda x: x > 0, "a number of seconds > 0")


def instant(value: str) -> float:
    """An argument type: a time in seconds ≥ 0 (``--from``, ``--to``)."""
    return _number(value, lambda x: x >= 0, "a time in seconds ≥ 0")


def tolerance(value: str) -> float:
    """An argument type: a tolerance ≥ 0 (``--tolerance``)."""
    return _number(value, lambda x: x >= 0, "a tolerance ≥ 0, e.g. 1e-6")


def factor(value: str) -> float:
    """An argument type: a speed factor > 0 (``--speed``; 1 is real time)."""
    return _number(value, lambda x: x > 0, "a factor > 0 (1 = real time)")


RECORDINGS: Final = "recordings"
"""The folder runs are recorded into by default, relative to the working directory;
the environment variable ``WHEXAR_RECORDINGS`` names another."""


def default_recording(name: str) -> Path:
    """Where a run of ``name`` is recorded unless told otherwise: a new file under
    :data:`RECORDINGS` (made if missing), named after the run and the date."""
    folder = Path(os.environ.get("WHEXAR_RECORDINGS") or RECORDINGS)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(
            f"cannot make {folder}/ for the recording: {exc.strerror or exc}; "
            "give --record FILE or --no-record"
        ) from None
    return folder / f"{Path(name).stem}-{wall_stamp()}.mcap"


DEFAULT_LIVE_PORT: Final = 8765
"""The live view's port unless given (Foxglove's default)."""


def tcp_port(value: str) -> int:
    """An argparse type: a TCP port number, 0 (any free port) to 65535."""
    try:
        number = int(value)
    except ValueError:
        number = -1
    if not 0 <= number <= 65535:
        raise argparse.ArgumentTypeError(f"{value!r}: expected a port number 0–65535")
    return number
