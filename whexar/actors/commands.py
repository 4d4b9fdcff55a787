"""Where motion commands come from: a script, stdin, or a person at the keyboard.

Theory of operation
-------------------
:class:`CommandSource` turns what someone wants into
:class:`~whexar.actors.messages.MotionCommand` messages on its ``commands``
port, for the coordinator. Its ``source`` parameter chooses the front end:

* **a command script** (any value but the three words below: a file) — JSON
  lines, each one command with its time ``t`` in seconds since the start of
  the run::

      # forward in the tripod gait, turn left after 4.5 s, stop at 8 s
      {"t": 0, "vx_m_s": 0.1, "gait": "tripod"}
      {"t": 4.5, "yaw_rate_rad_s": 0.2}
      {"t": 8, "stop": true}

  The other keys are the fields of ``MotionCommand`` (not ``t`` or
  ``source``); blank lines and lines starting with ``#`` are skipped. The
  file is checked whole — with the wiring, and again when the actor starts,
  before it reports ready — and every problem is listed at once with its
  line, key, value and what is allowed (:func:`load_script`). The actor then
  sleeps on the runtime clock until each line's time and sends the command
  stamped with that time, so a script on virtual time gives the same run
  every time. After the last line it idles.
* ``stdin`` — the same JSON lines, read as they arrive; a ``t`` may be given
  but is ignored: a command applies when it is read. A bad line is one
  :class:`~whexar.actors.messages.CommandRefused` event and is skipped; the
  actor never fails on what it reads. End of input leaves it idle (a piped
  one-liner must not stop the robot). On virtual time stdin is not read at
  all — waiting on it would let virtual time run away — and one
  ``CommandRefused`` says so, unless the graph allows real I/O.
* ``keyboard`` — a person drives (:func:`key_command` has the keys). The
  terminal goes into cbreak mode, not raw: keys arrive one by one without
  echo, but Ctrl-C still raises SIGINT, which the runtime owns (its first
  SIGINT stops the run in order, a second one stops it safely at once). One
  status line on stderr (:func:`status_line`) shows the command and, when the
  ``state`` input is wired, the coordinator's
  :class:`~whexar.actors.messages.LocomotionState`. The terminal's settings
  are restored however the actor ends, and by its :meth:`~CommandSource.safe_stop`
  too, which a second Ctrl-C runs before the process exits without cleanup.
  Keys are read through the event loop (a watched descriptor), not a thread.
* ``none`` — nothing is sent (a graph driven by a scenario).

Every front end makes the same typed command, so the coordinator has one
path for all of them; the pure functions here (:func:`load_script`,
:func:`parse_command`, :func:`key_command`, :func:`status_line`,
:func:`split_keys`) are tested without a terminal or a loop.
"""

from __future__ import annotations

import codecs
import contextlib
import dataclasses
import json
import math
import os
import stat
import sys
import termios
import tty
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Final

import anyio
import anyio.lowlevel
from pydantic import AfterValidator

from whexar.actors.messages import CommandRefused, LocomotionState, MotionCommand
from whexar.errors import MISSING, ConfigError, Problem, UsageError
from whexar.kinematics.gait import GAIT_RANKING
from whexar.runtime.actor import Actor, ActorParams, Input, Output
from whexar.runtime.schema import Positive, read_text

# --------------------------------------------------------------------------- command fields

KEYWORDS: Final = ("stdin", "keyboard", "none")
"""The values of ``source`` that are no file."""

GAITS: Final = GAIT_RANKING[1:]
"""The walking gaits a command may choose (rank 0, riding on wheels, is a mode)."""

MODES: Final = ("walk", "ride", "hybrid")
"""The locomotion modes a command may choose."""

STDIN_ON_VIRTUAL_TIME: Final = "stdin is not read on virtual time; give --commands FILE"
"""The reason of the one ``CommandRefused`` a stdin source gives on virtual time."""

MAX_LINE_BYTES: Final = 65_536
"""Longest line read from stdin; a longer one is refused (input without newlines
must not grow the buffer without bound)."""

_SHOWN_CHARS = 80
"""A refused line is quoted up to this length."""


@dataclass(frozen=True)
class _Field:
    """What a JSON value of one ``MotionCommand`` field may be."""

    base: type | None
    """float, str or bool; ``None``: any JSON value (a field type this module does not know)."""
    nullable: bool
    choices: tuple[str, ...] = ()

    def problem(self, value: object) -> str | None:
        """What is allowed, if ``value`` is not; ``None`` if it is."""
        if value is None and self.nullable:
            return None
        if self.base is float:
            ok = _is_number(value)
            what = "a finite number"
        elif self.base is str:
            ok = isinstance(value, str) and (not self.choices or value in self.choices)
            what = f"one of {', '.join(self.choices)}" if self.choices else "a string"
        elif self.base is bool:
            ok = isinstance(value, bool)
            what = "true, false" if self.nullable else "true or false"
        else:
            return None
        if ok:
            return None
        return f"{what} or null" if self.nullable else what


def _is_number(value: object) -> bool:
    # JSON's true/false are Python bools, which are ints: not a number here.
    return (
        isinstance(value, int | float)
        and not isinstance(value, bool)
        and math.isfinite(float(value))
    )


def _motion_fields() -> dict[str, _Field]:
    """The keys a command line may have, read off ``MotionCommand`` (so they cannot drift)."""
    hints = typing.get_type_hints(MotionCommand)
    found: dict[str, _Field] = {}
    for field in dataclasses.fields(MotionCommand):
        if field.name in ("t", "source"):
            continue
        hint = hints[field.name]
        union = typing.get_origin(hint) in (typing.Union, types.UnionType)
        args = typing.get_args(hint) if union else (hint,)
        rest = [a for a in args if a is not type(None)]
        base = rest[0] if len(rest) == 1 and rest[0] in (float, str, bool) else None
        choices = {"gait": GAITS, "mode": MODES}.get(field.name, ())
        found[field.name] = _Field(base, type(None) in args, tuple(choices))
    return found


MOTION_FIELDS: Final = _motion_fields()
"""Every key of a command line but ``t``: the fields of ``MotionCommand``, in its order."""


def _shown(text: str) -> str:
    return text if len(text) <= _SHOWN_CHARS else text[: _SHOWN_CHARS - 1] + "…"


def _decode(text: str, where: str, problems: list[Problem]) -> dict[str, Any] | None:
    """One line as a JSON object, or ``None`` with its problem added."""
    repeated: list[str] = []

    def pairs(items: list[tuple[str, Any]]) -> dict[str, Any]:
        seen: dict[str, Any] = {}
        for key, value in items:
            if key in seen:
                repeated.append(key)
            seen[key] = value
        return seen

    try:
        data = json.loads(text, object_pairs_hook=pairs)
    except (json.JSONDecodeError, RecursionError) as exc:
        detail = (
            f"{exc.msg} at column {exc.colno}"
            if isinstance(exc, json.JSONDecodeError)
            else "nested too deeply"
        )
        problems.append(Problem(where, _shown(text), f"a JSON object ({detail})"))
        return None
    if not isinstance(data, dict):
        example = '{"t": 0, "vx_m_s": 0.1}'
        problems.append(Problem(where, _shown(text), f"a JSON object such as {example}"))
        return None
    for key in dict.fromkeys(repeated):
        problems.append(Problem(f"{where}: {key}", data[key], "a key given once per line"))
    return data


def _time(
    data: Mapping[str, Any], where: str, problems: list[Problem], *, required: bool
) -> float | None:
    if "t" not in data:
        if required:
            problems.append(
                Problem(
                    f"{where}: t",
                    MISSING,
                    "required key is missing: the command's time, seconds since the start "
                    "of the run",
                )
            )
        return None
    t = data["t"]
    if not _is_number(t) or t < 0:
        problems.append(
            Problem(f"{where}: t", t, "a finite number of seconds ≥ 0 since the start of the run")
        )
        return None
    return float(t)


def motion_fields(
    data: Mapping[str, Any], where: str, problems: list[Problem], *, sep: str = ": "
) -> dict[str, Any]:
    """The :class:`MotionCommand` fields of one command (every key but ``t``), checked
    against :data:`MOTION_FIELDS`; each bad key is a problem at ``where`` + ``sep`` + key
    (a script's ``line 3: vx_m_s``, a scenario's ``commands[2].vx_m_s``)."""
    fields: dict[str, Any] = {}
    for key, value in data.items():
        if key == "t":
            continue
        spec = MOTION_FIELDS.get(key)
        if spec is None:
            known = ", ".join(("t", *MOTION_FIELDS))
            problems.append(
                Problem(f"{where}{sep}{key}", value, f"unknown key; allowed here: {known}")
            )
            continue
        allowed = spec.problem(value)
        if allowed is not None:
            problems.append(Problem(f"{where}{sep}{key}", value, allowed))
        elif spec.base is float and value is not None:
            fields[key] = float(value)  # a JSON 1 is an int: messages hold floats
        else:
            fields[key] = value
    return fields


def parse_command(text: str, *, t: float, source: str, where: str = "command") -> MotionCommand:
    """One JSON line as a command valid at ``t``, made by ``source`` (the line's own ``t``
    must be a time but is not used: the caller says when the command applies).

    Raises :class:`~whexar.errors.ConfigError` naming ``where`` (``"stdin line 3"``)
    and every problem: bad JSON, an unknown key (the allowed ones listed), a value of
    the wrong type or outside its choices.
    """
    problems: list[Problem] = []
    data = _decode(text.strip(), where, problems)
    if data is None:
        raise ConfigError(where, problems)
    _time(data, where, problems, required=False)
    fields = motion_fields(data, where, problems)
    if problems:
        raise ConfigError(where, problems)
    return MotionCommand(t=t, source=source, **fields)


def load_script(path: str | Path, *, source: str = "commands") -> tuple[MotionCommand, ...]:
    """Read and check a command script; its commands in order, each stamped with its line's ``t``.

    The format is in the module docstring. Raises
    :class:`~whexar.errors.ConfigError` naming the file and listing every
    problem (``line 3: vx_m_s = 'fast': a finite number or null``): an
    unreadable file, a line that is no JSON object, a missing or bad ``t``, a
    ``t`` earlier than one before it, an unknown key, a value of the wrong type.
    """
    name = str(path)
    text = read_text(path, "a readable command script", encoding="utf-8-sig")
    problems: list[Problem] = []
    commands: list[MotionCommand] = []
    latest: tuple[float, int] | None = None  # the greatest t so far, and its line
    for number, raw in enumerate(text.split("\n"), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        where = f"line {number}"
        found: list[Problem] = []
        data = _decode(line, where, found)
        if data is None:
            problems.extend(found)
            continue
        t = _time(data, where, found, required=True)
        fields = motion_fields(data, where, found)
        if t is not None and latest is not None and t < latest[0]:
            found.append(
                Problem(
                    f"{where}: t",
                    data["t"],
                    f"at least {latest[0]:g}, the t of line {latest[1]}: "
                    "a script's times never go backwards",
                )
            )
        elif t is not None:
            latest = (t, number)
        problems.extend(found)
        if not found and t is not None:
            commands.append(MotionCommand(t=t, source=source, **fields))
    if problems:
        raise ConfigError(name, problems)
    return tuple(commands)


def _check_source(value: str) -> str:
    """Check a ``source`` parameter: a keyword, or a script without problems."""
    if value in KEYWORDS:
        return value
    try:
        load_script(value)
    except ConfigError as exc:
        found = "; ".join(str(p) for p in exc.problems)
        words = ", ".join(repr(k) for k in KEYWORDS)
        raise ValueError(f"{words} or a command script without problems; {found}") from None
    return value


SourceName = Annotated[str, AfterValidator(_check_source)]
"""A ``source`` parameter: ``stdin``, ``keyboard``, ``none`` or a command script file."""


# --------------------------------------------------------------------------- the keyboard

SPEED_STEP_M_S: Final = 0.02
"""Forward, backward and sideways speed change per key press."""
YAW_STEP_RAD_S: Final = 0.1
"""Turn rate change per key press."""
STEP_HEIGHT_STEP_M: Final = 0.01
"""Step height change per ``+`` or ``-``."""
MAX_SPEED_M_S: Final = 0.5
MAX_YAW_RATE_RAD_S: Final = 2.0
STEP_HEIGHT_RANGE_M: Final = (0.01, 0.2)
# The coordinator clamps a command to what the robot can do (and says so with an
# event); these limits only keep a held key from winding the keyboard's own
# numbers far past that, so that a few presses always bring it back.

STATUS_PERIOD_S: Final = 0.1
"""Shortest time between two redraws of the status line for a new state (keys redraw at once)."""

HELP: Final = (
    "keys: arrows/WASD speed and turn, Q/E sideways, 1-4 tripod/tetrapod/ripple/wave, "
    "k walk, r ride, h hybrid, +/- step height, f flip, space stop, x quit, Ctrl-C stop the run"
)

CLEAR_LINE: Final = "\r\x1b[K"
"""Carriage return and erase to the end of the line: where the status line is redrawn."""

_ARROWS: Final = {"A": "up", "B": "down", "C": "right", "D": "left"}


@dataclass(frozen=True)
class KeyboardState:
    """What the keyboard has asked for so far (the robot's actual state is the coordinator's)."""

    vx_m_s: float = 0.0
    vy_m_s: float = 0.0
    yaw_rate_rad_s: float = 0.0
    gait: str | None = None
    """``None`` until a gait key is pressed: the coordinator's choice stands."""
    mode: str | None = None
    step_height_m: float = 0.06
    upside_down: bool = False
    quit: bool = False
    """``x`` was pressed: the run should end."""


def _stepped(value: float, step: float, limit: float) -> float:
    # Rounded so that n presses up and n down give exactly 0 again.
    return round(min(limit, max(-limit, value + step)), 6)


def _velocity(state: KeyboardState, *, t: float, source: str) -> MotionCommand:
    # Each velocity key sends all three: the keyboard owns the whole velocity.
    return MotionCommand(
        t=t,
        source=source,
        vx_m_s=state.vx_m_s,
        vy_m_s=state.vy_m_s,
        yaw_rate_rad_s=state.yaw_rate_rad_s,
    )


_MOVES: Final = {
    "up": (SPEED_STEP_M_S, 0.0, 0.0),
    "w": (SPEED_STEP_M_S, 0.0, 0.0),
    "down": (-SPEED_STEP_M_S, 0.0, 0.0),
    "s": (-SPEED_STEP_M_S, 0.0, 0.0),
    "q": (0.0, SPEED_STEP_M_S, 0.0),
    "e": (0.0, -SPEED_STEP_M_S, 0.0),
    "left": (0.0, 0.0, YAW_STEP_RAD_S),
    "a": (0.0, 0.0, YAW_STEP_RAD_S),
    "right": (0.0, 0.0, -YAW_STEP_RAD_S),
    "d": (0.0, 0.0, -YAW_STEP_RAD_S),
}
"""Velocity keys: the change of (vx, vy, yaw rate) they make; y and yaw are positive to the left."""

_MODE_KEYS: Final = {"k": "walk", "r": "ride", "h": "hybrid"}


def key_command(
    key: str, current: KeyboardState, *, t: float = 0.0, source: str = "keyboard"
) -> tuple[KeyboardState, MotionCommand | None]:
    """What pressing ``key`` asks for: the keyboard's new state and the command to send, if any.

    ``key`` is a character or an arrow's name (``up``, ``down``, ``left``,
    ``right``; see :func:`split_keys`); letters count in either case.

    * ↑/``w``, ↓/``s``: forward speed ±0.02 m/s; ←/``a``, →/``d``: turn rate
      ±0.1 rad/s (left is positive); ``q``, ``e``: sideways ±0.02 m/s (left,
      right). Each sends the whole velocity.
    * ``1``–``4``: gait tripod, tetrapod, ripple, wave; ``k`` walk, ``r`` ride,
      ``h`` hybrid.
    * ``+`` (or ``=``), ``-``: step height ±0.01 m; ``f``: turn over (upside_down).
    * space: stop — velocity zero and ``stop``; ``x``: the same, and ``quit``.

    Any other key changes nothing and sends nothing. The command is stamped
    ``t`` and ``source``.
    """
    name = key if len(key) > 1 else key.lower()
    move = _MOVES.get(name)
    if move is not None:
        dvx, dvy, dyaw = move
        state = dataclasses.replace(
            current,
            vx_m_s=_stepped(current.vx_m_s, dvx, MAX_SPEED_M_S),
            vy_m_s=_stepped(current.vy_m_s, dvy, MAX_SPEED_M_S),
            yaw_rate_rad_s=_stepped(current.yaw_rate_rad_s, dyaw, MAX_YAW_RATE_RAD_S),
        )
        return state, _velocity(state, t=t, source=source)
    if name in (" ", "x"):
        state = dataclasses.replace(
            current, vx_m_s=0.0, vy_m_s=0.0, yaw_rate_rad_s=0.0, quit=name == "x"
        )
        command = MotionCommand(
            t=t, source=source, vx_m_s=0.0, vy_m_s=0.0, yaw_rate_rad_s=0.0, stop=True
        )
        return state, command
    if name in ("1", "2", "3", "4"):
        gait = GAITS[int(name) - 1]
        return dataclasses.replace(current, gait=gait), MotionCommand(t=t, source=source, gait=gait)
    if name in _MODE_KEYS:
        mode = _MODE_KEYS[name]
        return dataclasses.replace(current, mode=mode), MotionCommand(t=t, source=source, mode=mode)
    if name in ("+", "=", "-"):
        step = STEP_HEIGHT_STEP_M if name != "-" else -STEP_HEIGHT_STEP_M
        low, high = STEP_HEIGHT_RANGE_M
        height = round(min(high, max(low, current.step_height_m + step)), 6)
        return dataclasses.replace(current, step_height_m=height), MotionCommand(
            t=t, source=source, step_height_m=height
        )
    if name == "f":
        flipped = not current.upside_down
        return dataclasses.replace(current, upside_down=flipped), MotionCommand(
            t=t, source=source, upside_down=flipped
        )
    return current, None


def split_keys(text: str) -> tuple[list[str], str]:
    """Split what the terminal sent into keys; returns the keys and an unfinished tail.

    An arrow's escape sequence (``ESC [ A`` and its modified and application-mode
    forms ``ESC [ 1 ; 5 A``, ``ESC O A``) becomes ``up``, ``down``, ``right`` or
    ``left``; any other escape sequence becomes ``"\\x1b"`` (no key of ours). An
    escape sequence cut off at the end of ``text`` is the tail: prepend it to
    what comes next.
    """
    keys: list[str] = []
    i = 0
    n = len(text)
    while i < n:
        char = text[i]
        if char != "\x1b":
            keys.append(char)
            i += 1
            continue
        if i + 1 >= n:
            return keys, text[i:]
        kind = text[i + 1]
        if kind == "O":  # SS3: one final character
            if i + 2 >= n:
                return keys, text[i:]
            keys.append(_ARROWS.get(text[i + 2], "\x1b"))
            i += 3
        elif kind == "[":  # CSI: parameters and intermediates, then a final byte
            j = i + 2
            while j < n and 0x20 <= ord(text[j]) <= 0x3F:
                j += 1
            if j >= n:
                return keys, text[i:]
            keys.append(_ARROWS.get(text[j], "\x1b"))
            i = j + 1
        else:  # Alt+key or a lone Esc: no key of ours; the next character counts alone
            keys.append("\x1b")
            i += 1
    return keys, ""


def status_line(
    current: KeyboardState, state: LocomotionState | None = None, *, width: int | None = None
) -> str:
    """The keyboard's one status line: the command asked for, and the robot's state if known.

    ``width`` (the terminal's columns) cuts the line one short of it, so that
    it never wraps: a wrapped line could not be redrawn in place.
    """
    flipped = " flipped" if current.upside_down else ""
    parts = [
        f"cmd vx {current.vx_m_s:+.2f} vy {current.vy_m_s:+.2f} yaw {current.yaw_rate_rad_s:+.2f}",
        f"{current.gait or 'gait -'} {current.mode or 'mode -'} "
        f"step {current.step_height_m * 100:.0f} cm{flipped}",
    ]
    if state is None:
        parts.append("no locomotion state")
    else:
        vx, vy, yaw = state.twist
        swing = ",".join(str(leg) for leg in state.swing_legs) or "-"
        parts.append(
            f"{state.activity} {state.gait} {state.mode} "
            f"twist {vx:+.2f} {vy:+.2f} {yaw:+.2f} "
            f"margin {state.margin_m * 1000:.0f} mm swing {swing}"
        )
    line = " | ".join(parts)
    if width is not None and len(line) >= width:
        line = line[: max(0, width - 1)]
    return line


# --------------------------------------------------------------------------- stdin


class LineReader:
    """Reads lines from a file descriptor through the event loop, without a thread.

    A pipe, a socket or a terminal is waited on as the loop's watched
    descriptor; a regular file (``< script.jsonl``) or a device such as
    ``/dev/null`` cannot be watched (epoll refuses them) and never blocks, so
    it is read directly, with a checkpoint between reads so others still run.
    """

    def __init__(self, fd: int, *, limit: int = MAX_LINE_BYTES) -> None:
        self.fd = fd
        self.limit = limit
        mode = os.fstat(fd).st_mode
        self._watched = stat.S_ISFIFO(mode) or stat.S_ISSOCK(mode) or os.isatty(fd)
        self._buffer = bytearray()
        self._eof = False
        self._skipping = False  # inside a line that was too long: drop it up to its end

    async def readline(self) -> bytes | None:
        """The next line without its newline, or ``None`` at end of input.

        A line longer than ``limit`` bytes comes back as its first
        ``limit + 1`` bytes (tell it by its length); the rest of it is dropped.
        """
        while True:
            end = self._buffer.find(b"\n")
            if end >= 0:
                line = bytes(self._buffer[: min(end, self.limit + 1)])
                del self._buffer[: end + 1]
                if self._skipping:
                    self._skipping = False
                    continue
                return line
            if len(self._buffer) > self.limit:
                head = bytes(self._buffer[: self.limit + 1])
                self._buffer.clear()
                if not self._skipping:
                    self._skipping = True
                    return head
            if self._eof:
                line = bytes(self._buffer)
                self._buffer.clear()
                return line if line and not self._skipping else None
            chunk = await self._read()
            if chunk is None:
                continue
            if chunk:
                self._buffer += chunk
            else:
                self._eof = True

    async def _read(self) -> bytes | None:
        """Bytes read, ``b""`` at end of input, ``None`` when nothing was there after all."""
        if self._watched:
            await anyio.wait_readable(self.fd)
        else:
            await anyio.lowlevel.checkpoint()
        try:
            return os.read(self.fd, 65_536)
        except BlockingIOError:  # someone made the descriptor non-blocking: wait again
            return None
        except OSError:  # EIO: the terminal hung up; as good as the end of input
            return b""


def _stdin_fd() -> int | None:
    """The descriptor of stdin, or ``None`` when there is none (closed, or replaced by a test)."""
    stream = sys.stdin
    if stream is None:
        return None
    try:
        return stream.fileno()
    except (AttributeError, OSError, ValueError):
        return None


# --------------------------------------------------------------------------- the actor


class CommandSource(Actor):
    """Sends motion commands from a script, stdin or the keyboard (see the module docstring)."""

    class Params(ActorParams):
        source: SourceName = "stdin"
        """``stdin``, ``keyboard``, ``none``, or the path of a command script (JSON lines)."""
        step_height_m: Positive = 0.06
        """The step height the keyboard's ``+`` and ``-`` start from (the default
        configuration's ``locomotion.step_height_mm``)."""

    params: Params
    commands = Output(MotionCommand)
    state = Input(LocomotionState, optional=True)
    """The coordinator's state, for the keyboard's status line."""

    _tty_fd: int = -1
    _tty_saved: list[Any] | None = None
    """The terminal's settings before cbreak mode, while they need restoring."""

    async def run(self) -> None:
        source = self.params.source
        if source == "none":
            self.ready()
            await anyio.sleep_forever()
        elif source == "stdin":
            await self._stdin()
        elif source == "keyboard":
            await self._keyboard()
        else:
            await self._script(source)

    async def safe_stop(self, reason: str) -> None:
        """Give the terminal its settings back: a second Ctrl-C ends the process without cleanup."""
        self._restore_terminal()

    # ----------------------------------------------------------------- script

    async def _script(self, path: str) -> None:
        # Checked again here: the file may have changed since the wiring was.
        script = load_script(path, source=self.name)
        self.ready()
        for command in script:
            await self.clock.sleep_until(command.t)
            await self.commands.send(command)
        await anyio.sleep_forever()

    # ----------------------------------------------------------------- stdin

    def _refuse(self, command: str, reason: str) -> None:
        self.emit(CommandRefused(t=self.now(), source=self.name, command=command, reason=reason))

    async def _stdin(self) -> None:
        if self.clock.virtual and not self.clock.real_io:
            # Not an error: a graph with the default source still runs on virtual time.
            self.ready()
            self._refuse("stdin", STDIN_ON_VIRTUAL_TIME)
            await anyio.sleep_forever()
            return
        self.clock.uses_real_io("stdin")
        fd = _stdin_fd()
        if fd is None:
            self.ready()
            self._refuse("stdin", "this process has no stdin to read")
            await anyio.sleep_forever()
            return
        reader = LineReader(fd)
        self.ready()
        number = 0
        while (raw := await reader.readline()) is not None:
            number += 1
            where = f"stdin line {number}"
            text = raw.decode("utf-8", errors="replace").strip()
            if len(raw) > reader.limit:
                self._refuse(_shown(text), f"{where}: a line of at most {reader.limit} bytes")
                continue
            if not text or text.startswith("#"):
                continue
            try:
                command = parse_command(text, t=self.now(), source=self.name, where=where)
            except ConfigError as exc:
                self._refuse(_shown(text), "; ".join(str(p) for p in exc.problems))
                continue
            await self.commands.send(command)
        await anyio.sleep_forever()

    # ----------------------------------------------------------------- keyboard

    async def _keyboard(self) -> None:
        self.clock.uses_real_io("keyboard (the terminal on stdin)")
        fd = _stdin_fd()
        if fd is None or not os.isatty(fd):
            raise UsageError(
                "source = 'keyboard' needs a terminal on stdin; give a command script "
                "or 'stdin' to read commands from a pipe"
            )
        self._keys = KeyboardState(step_height_m=self.params.step_height_m)
        self._state: LocomotionState | None = None
        self._drawn_at = -math.inf
        try:
            self._tty_fd = fd
            self._tty_saved = termios.tcgetattr(fd)
            # cbreak, not raw: keys arrive at once and unechoed, but ISIG stays on,
            # so Ctrl-C is still SIGINT for the runtime.
            tty.setcbreak(fd)
            self._write(HELP + "\n")
            self._draw()
            self.ready()
            async with anyio.create_task_group() as tg:
                if self.state.connected:
                    tg.start_soon(self._follow_state)
                await self._read_keys(fd)
                await anyio.sleep_forever()
        finally:
            self._restore_terminal()  # synchronous: no cancellation can cut it short

    async def _read_keys(self, fd: int) -> None:
        decoder = codecs.getincrementaldecoder("utf-8")(errors="replace")
        tail = ""
        while True:
            await anyio.wait_readable(fd)
            try:
                data = os.read(fd, 1024)
            except BlockingIOError:
                continue
            except OSError:  # EIO: the terminal hung up
                data = b""
            if not data:
                # Nobody can steer any more: do not leave the robot moving.
                self._keys, stop = key_command(" ", self._keys, t=self.now(), source=self.name)
                if stop is not None:
                    await self.commands.send(stop)
                return
            keys, tail = split_keys(tail + decoder.decode(data))
            for key in keys:
                self._keys, command = key_command(key, self._keys, t=self.now(), source=self.name)
                if command is not None:
                    await self.commands.send(command)
                if self._keys.quit:
                    self.request_stop("x pressed on the keyboard")
            self._draw()

    async def _follow_state(self) -> None:
        async for state in self.state:
            self._state = state
            # A state arrives every control cycle; the line is redrawn at a pace a
            # person can read, and a key redraws it at once anyway.
            if self.now() - self._drawn_at >= STATUS_PERIOD_S:
                self._draw()

    def _draw(self) -> None:
        try:
            width: int | None = os.get_terminal_size(sys.stderr.fileno()).columns
        except (AttributeError, OSError, ValueError):
            width = None
        # A terminal that does not know its size says 0 columns: then do not cut.
        self._write(CLEAR_LINE + status_line(self._keys, self._state, width=width or None))
        self._drawn_at = self.now()

    @staticmethod
    def _write(text: str) -> None:
        with contextlib.suppress(OSError, ValueError):  # stderr closed: the robot still runs
            sys.stderr.write(text)
            sys.stderr.flush()

    def _restore_terminal(self) -> None:
        saved, self._tty_saved = self._tty_saved, None
        if saved is None:
            return
        with contextlib.suppress(termios.error, OSError):
            termios.tcsetattr(self._tty_fd, termios.TCSADRAIN, saved)
        self._write(CLEAR_LINE)
