"""The runtime's errors: the root of the project's one error tree.

The runtime stands alone, so the base of the tree lives here and
:mod:`whexar.errors` builds the device and kinematics families on it (and is
where the rest of the project imports every error from):

* :class:`WhexarError` — base of every error raised on purpose;
* :class:`UsageError` — the caller asked for something wrong (a bad wiring
  file, a negative period, an unknown device name); the message names the
  offending value;
* :class:`ConfigError` — a configuration document with one or more
  :class:`Problem`\\ s, each naming its key path, the value found and what is
  allowed.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass


class WhexarError(Exception):
    """Base of every error whexar raises on purpose."""


class DeviceUnavailableError(WhexarError):
    """A device the run needs is missing, busy or not permitted, found at an actor's
    start: no restart helps until someone plugs it in, frees it or grants access, and
    the message says which and how. The runtime stops the run instead of restarting the
    actor, without a traceback (tracebacks are for bugs)."""


class UsageError(WhexarError, ValueError):
    """The caller's input is wrong; the message names the offending value."""


@dataclass(frozen=True)
class Problem:
    """One thing wrong with a configuration: where, what was found, what is allowed."""

    path: str
    value: object
    allowed: str

    def __str__(self) -> str:
        shown = "(missing)" if self.value is MISSING else repr(self.value)
        where = self.path or "(top level)"
        return f"{where} = {shown}: {self.allowed}"


class _Missing:
    def __repr__(self) -> str:
        return "(missing)"


MISSING: object = _Missing()
"""Stands for the value of a key that is absent from a configuration."""


class ConfigError(UsageError):
    """A configuration has one or more problems; :attr:`problems` lists them all."""

    def __init__(self, source: str, problems: Sequence[Problem]) -> None:
        self.source = source
        self.problems = tuple(problems)
        lines = "\n".join(f"  {p}" for p in self.problems)
        count = len(self.problems)
        super().__init__(f"{source}: {count} problem{'s' if count != 1 else ''}\n{lines}")
