"""What every command group shares: the handler type, JSON output, argument types."""

from __future__ import annotations

import argparse
import contextlib
import math
import shutil
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, Final, TypeAlias

from whexar import _json
from whexar.errors import ConfigError, UsageError
from whexar.record.budget import RECORDINGS as RECORDINGS  # the commands' help names it
from whexar.record.budget import recordings_folder
from whexar.runtime.clock import wall_stamp

Handler: TypeAlias = Callable[[argparse.Namespace], int]
"""A command: parsed arguments in, exit status out."""
Commands: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"
"""The ``whexar`` subcommand table each group adds its commands to."""


def print_json(value: object, *, indent: int | None = None) -> None:
    """Print ``value`` as strict JSON, one line unless ``indent``: a float that is not
    finite is ``null``, never ``NaN`` or ``Infinity``, which strict parsers refuse
    (:mod:`whexar._json`, which every ``--json`` goes through)."""
    print(_json.dumps(value, indent=indent))


def print_problems(exc: ConfigError, stream: Any = None) -> None:
    """A checked file's problems: a count, then one a line (on stderr unless ``stream``)."""
    out = stream if stream is not None else sys.stderr
    count = len(exc.problems)
    print(f"{exc.source}: {count} problem{'s' if count != 1 else ''}", file=out)
    for problem in exc.problems:
        print(f"  {problem}", file=out)


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


def default_recording(name: str) -> Path:
    """Where a run of ``name`` is recorded unless told otherwise: a new file in the
    recordings folder (:data:`RECORDINGS`, made if missing), named after the run and
    the date."""
    folder = recordings_folder()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(
            f"cannot make {folder}/ for the recording: {exc.strerror or exc}; "
            "give --record FILE or --no-record"
        ) from None
    return folder / f"{Path(name).stem}-{wall_stamp()}.mcap"


CLEAR_LINE: Final = "\r\x1b[K"
"""Carriage return and erase to the end of the line: a status line is redrawn in place."""


class StatusLine:
    """A line on ``stream`` (default stderr) redrawn in place on a terminal, printed as
    lines otherwise (:attr:`live` says which): the base of the progress lines."""

    def __init__(self, stream: Any = None) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.live = bool(getattr(self.stream, "isatty", lambda: False)())

    def fitted(self, text: str) -> str:
        """``text`` to redraw: the line cleared first, cut to the terminal's width (a line
        that wraps cannot be redrawn in place)."""
        return CLEAR_LINE + text[: shutil.get_terminal_size().columns - 1]

    def finish(self) -> None:
        """End the live line so that what follows starts on a fresh one."""
        if self.live:
            self._write(CLEAR_LINE)

    def _write(self, text: str) -> None:
        with contextlib.suppress(OSError):  # a terminal that went away costs the line only
            self.stream.write(text)
            self.stream.flush()


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
