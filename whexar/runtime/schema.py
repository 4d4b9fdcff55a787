"""Configuration documents: strict pydantic sections, key paths, problems, TOML files.

The runtime's wiring files, the robot configuration (:mod:`whexar.config`)
and the fault plans are all validated the same way:

1. per key — types, ranges, allowed values, unknown keys (pydantic), each
   error turned into a :class:`~whexar.runtime.errors.Problem` by
   :func:`problem_from_error`: the key path as TOML spells it
   (``legs[1].servo_ids[0]``), the value found and what is allowed;
2. relations — a :class:`Section` lists what is wrong across its keys in
   :meth:`Section.problems`, and a :class:`CheckedSection` document root runs
   those checks itself when it is built in code.

Every problem is collected before anything is raised, so one bad key never
hides another (:class:`~whexar.runtime.errors.ConfigError` lists them all).

A tagged union whose members are told apart by their shape (a preset's name
or a table) names its tags in angle brackets, ``Tag("<name>")``: pydantic puts
the tag into an error's location, and :func:`problem_from_error` leaves such
parts out of the key path.
"""

from __future__ import annotations

import re
import tomllib
import types
import typing
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Annotated, Any, Self

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, model_validator

from whexar.runtime.errors import MISSING, ConfigError, Problem

Finite = Annotated[float, Field(allow_inf_nan=False)]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegative = Annotated[float, Field(ge=0, allow_inf_nan=False)]


class Section(BaseModel):
    """Base of every configuration model: strict keys, immutable values."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    def problems(self, at: str) -> list[Problem]:
        """Relational problems inside this section; ``at`` is its key path."""
        return []


class CheckedSection(Section):
    """A document root that checks its own relations when built directly in code.

    The loaders (``load_config``, ``parse_fault_plan``) validate with
    ``context={"defer_relations": True}`` and collect :meth:`problems` with
    their key paths themselves; anything else gets them as one ValueError.
    """

    @model_validator(mode="after")
    def _relations(self, info: ValidationInfo) -> Self:
        if isinstance(info.context, dict) and info.context.get("defer_relations"):
            return self
        found = self.problems("")
        if found:
            raise ValueError("; ".join(str(p) for p in found))
        return self


def loads(loader: Callable[[str], object], what: str) -> Callable[[str], str]:
    """A validator for a key that names a file: ``loader`` must read it without a problem.

    ``Annotated[str, AfterValidator(loads(load_config, "a robot configuration"))]``
    makes a bad file one more problem of the document that names it (an
    actor's params are checked with the wiring, before anything runs),
    quoting the file's own problems.
    """

    def check(path: str) -> str:
        try:
            loader(path)
        except ConfigError as exc:
            found = "; ".join(str(p) for p in exc.problems)
            raise ValueError(f"{what} without problems; {exc.source}: {found}") from None
        return path

    return check


# --------------------------------------------------------------------------- key paths and problems


def _key(part: object) -> str:
    """One component of a key path, quoted as TOML would need it."""
    if isinstance(part, int):
        return f"[{part}]"
    text = str(part)
    return text if re.fullmatch(r"[A-Za-z0-9_]+", text) else f'"{text}"'


def format_path(loc: Sequence[object]) -> str:
    """``("legs", 1, "servo_ids", 0)`` → ``legs[1].servo_ids[0]``."""
    out = ""
    for part in loc:
        piece = _key(part)
        out += piece if piece.startswith("[") or not out else f".{piece}"
    return out


def _model_at(root: type[BaseModel], loc: Sequence[object]) -> type[BaseModel] | None:
    """The model class that a location inside a ``root`` document points into."""
    annotation: object = root
    for part in loc:
        annotation = _unwrap(annotation)
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            field = annotation.model_fields.get(str(part))
            if field is None:
                return None
            annotation = field.annotation
        else:
            args = typing.get_args(annotation)
            if not args:
                return None
            annotation = args[-1] if typing.get_origin(annotation) is dict else args[0]
    annotation = _unwrap(annotation)
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    return None


def _unwrap(annotation: object) -> object:
    """Strip ``Optional``/``Annotated`` so a field's model class shows through."""
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _unwrap(typing.get_args(annotation)[0])
    if origin in (typing.Union, types.UnionType):
        members = [_unwrap(a) for a in typing.get_args(annotation) if a is not type(None)]
        if len(members) == 1:
            return members[0]
        # A name or a table (a scenario's terrain, bus.plan): keys can only be the table's.
        models = [m for m in members if isinstance(m, type) and issubclass(m, BaseModel)]
        return models[0] if len(models) == 1 else annotation
    return annotation


def _is_tag(part: object) -> bool:
    return isinstance(part, str) and part.startswith("<") and part.endswith(">")


def problem_from_error(
    error: Mapping[str, Any],
    root: type[BaseModel],
    prefix: Sequence[object] = (),
) -> Problem:
    """One pydantic error as a :class:`Problem`; ``root`` is the model validated.

    ``prefix`` is prepended to the error's location (a nested document
    validated on its own, such as an actor's ``params``).
    """
    loc = tuple(error["loc"])
    # The tag of a union told apart by shape ("<name>", "<table>") is no key.
    loc = tuple(p for p in loc if not _is_tag(p))
    # pydantic locates a bad dict key as (..., key, "[key]"): name the key itself.
    key_itself = bool(loc) and loc[-1] == "[key]"
    if key_itself:
        loc = loc[:-1]
    path = format_path((*prefix, *loc))
    kind = error["type"]
    if kind == "missing":
        return Problem(path, MISSING, "required key is missing")
    if kind == "extra_forbidden":
        parent = _model_at(root, loc[:-1])
        fields = parent.model_fields.items() if parent is not None else ()
        known = ", ".join(field.alias or name for name, field in fields)
        return Problem(path, error.get("input"), f"unknown key; allowed here: {known}")
    message = str(error["msg"]).removeprefix("Value error, ")
    if key_itself:
        message = f"a valid key name: {message}"
    return Problem(path, error.get("input"), message)


def _syntax_problem(exc: tomllib.TOMLDecodeError, text: str) -> Problem:
    match = re.search(r"line (\d+), column (\d+)", str(exc))
    if match is None:
        return Problem("(file)", MISSING, f"valid TOML: {exc}")
    line = int(match.group(1))
    lines = text.splitlines()
    shown = lines[line - 1].strip() if 0 < line <= len(lines) else ""
    return Problem(f"line {line}", shown, f"valid TOML: {exc}")


def read_text(path: str | Path, what: str, *, encoding: str = "utf-8") -> str:
    """The text of the file ``what`` names (``"a readable TOML file"``); a missing or
    unreadable file, or one that is not text, is a :class:`ConfigError` saying so."""
    source = str(path)
    try:
        return Path(path).read_text(encoding=encoding)
    except OSError as exc:
        reason = exc.strerror or str(exc)
        raise ConfigError(source, [Problem("(file)", source, f"{what} ({reason})")]) from None
    except UnicodeDecodeError as exc:
        raise ConfigError(
            source, [Problem("(file)", source, f"UTF-8 text ({exc.reason} at byte {exc.start})")]
        ) from None


def read_toml(path: str | Path) -> dict[str, Any]:
    """Read a TOML file; a missing file or a syntax error is a :class:`ConfigError`."""
    source = str(path)
    text = read_text(path, "a readable TOML file")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(source, [_syntax_problem(exc, text)]) from None


def builtin_names(folder: Path) -> tuple[str, ...]:
    """The names of the TOML files in ``folder`` (built-in scenarios, shipped campaigns)."""
    return tuple(sorted(p.stem for p in folder.glob("*.toml")))


def builtin_path(
    name_or_path: str | Path, folder: Path, kind: str, shipped: str = "built-in"
) -> Path:
    """A file named by the user: a bare name (no folder, no ``.toml``) is ``folder/NAME.toml``,
    anything else a path. An unknown bare name is a :class:`ConfigError` listing the
    ``shipped`` files of this ``kind`` (``"scenario"``) there are."""
    text = str(name_or_path)
    if isinstance(name_or_path, Path) or "/" in text or text.endswith(".toml"):
        return Path(name_or_path)
    path = folder / f"{text}.toml"
    if not path.is_file():
        known = ", ".join(builtin_names(folder)) or "(none)"
        allowed = f"a {kind} file or a {shipped} {kind}: {known}"
        raise ConfigError(text, [Problem(f"({kind})", text, allowed)])
    return path
