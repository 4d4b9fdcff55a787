"""One error tree for the whole project.

Three families, as h11 and httpcore separate them:

* :class:`UsageError` — the caller asked for something wrong (a malformed
  configuration, a NaN coordinate, an unreachable foot target). Fix the input.
* :class:`DeviceError` — a device answered wrongly (bad CRC, an error bit in a
  status packet, a corrupted sensor frame). The runtime turns these into events.
* :class:`DeviceGoneError` — a device stopped answering or its port vanished.

Library exceptions are translated into these at the edge of the project.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass


class WhexarError(Exception):
    """Base of every error whexar raises on purpose."""


class UsageError(WhexarError, ValueError):
    """The caller's input is wrong; the message names the offending value."""


class DeviceError(WhexarError):
    """A device answered, but wrongly."""


class DeviceGoneError(WhexarError):
    """A device or its port stopped answering."""


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


class KinematicsError(UsageError):
    """A kinematic request cannot be satisfied as asked."""


class UnreachableError(KinematicsError):
    """A foot target lies outside the leg's workspace."""


class JointLimitError(KinematicsError):
    """A solution exists only with a joint outside its limits (Table 5.2)."""
