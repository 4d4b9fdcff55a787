"""Command scripts and command lines: JSON in, checked :class:`MotionCommand` out.

A command is one JSON object: the fields of
:class:`~whexar.actors.messages.MotionCommand` it changes (not ``t`` or
``source``); a script is JSON lines, each a command with its time ``t`` in
seconds since the start of the run (blank lines and ``#`` comments skipped).
:func:`load_script` checks a file whole and lists every problem at once —
line, key, value, what is allowed; :func:`parse_command` checks one line.
Plain functions, no I/O beyond reading the file.
"""

from __future__ import annotations

import dataclasses
import json
import math
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Final

from pydantic import AfterValidator

from whexar.actors.messages import MotionCommand
from whexar.errors import MISSING, ConfigError, Problem
from whexar.kinematics.gait import AUTO_GAIT, GAIT_RANKING
from whexar.runtime.schema import read_text

KEYWORDS: Final = ("stdin", "keyboard", "gamepad", "none")
"""The values of ``source`` that are no file (and ``gamepad:DEVICE``, :data:`GAMEPAD_PREFIX`)."""

GAMEPAD_PREFIX: Final = "gamepad:"
"""``source = "gamepad:DEVICE"``: the gamepad on DEVICE (a path, or ``pipe:NAME``)."""

GAITS: Final = (*GAIT_RANKING[1:], AUTO_GAIT)
"""The gaits a command may choose: the walking ones (rank 0, riding on wheels, is a mode)
and ``auto``, the gait selector's choice."""

MODES: Final = ("walk", "ride", "hybrid")
"""The locomotion modes a command may choose."""

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


def shown(text: str) -> str:
    """``text`` as a refusal quotes it: cut to a readable length."""
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
        problems.append(Problem(where, shown(text), f"a JSON object ({detail})"))
        return None
    if not isinstance(data, dict):
        example = '{"t": 0, "vx_m_s": 0.1}'
        problems.append(Problem(where, shown(text), f"a JSON object such as {example}"))
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
    """Check a ``source`` parameter: a keyword, a gamepad, or a script without problems."""
    if value in KEYWORDS or (value.startswith(GAMEPAD_PREFIX) and value != GAMEPAD_PREFIX):
        return value
    try:
        load_script(value)
    except ConfigError as exc:
        found = "; ".join(str(p) for p in exc.problems)
        words = ", ".join(repr(k) for k in KEYWORDS)
        raise ValueError(
            f"{words}, '{GAMEPAD_PREFIX}DEVICE' or a command script without problems; {found}"
        ) from None
    return value


SourceName = Annotated[str, AfterValidator(_check_source)]
"""A ``source`` parameter: ``stdin``, ``keyboard``, ``gamepad[:DEVICE]``, ``none`` or a command
script file."""
