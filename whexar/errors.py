"""One error tree for the whole project.

Three families, as h11 and httpcore separate them:

* :class:`UsageError` — the caller asked for something wrong (a malformed
  configuration, a NaN coordinate, an unreachable foot target). Fix the input.
* :class:`DeviceError` — a device answered wrongly (bad CRC, an error bit in a
  status packet, a corrupted sensor frame). The runtime turns these into events.
* :class:`DeviceGoneError` — a device stopped answering or its port vanished;
  :class:`PortUnavailableError` — a port missing, busy or not permitted when a
  run starts (:class:`~whexar.runtime.errors.DeviceUnavailableError`: the runtime
  stops instead of restarting, and prints no traceback).

The root of the tree (:class:`WhexarError`, :class:`UsageError`,
:class:`ConfigError` and its :class:`Problem` list) belongs to the actor
runtime, which stands alone (:mod:`whexar.runtime.errors`); it is named here
too, so that every package above the runtime imports its errors from this
one module. Library exceptions are translated into these at the edge of the
project.
"""

from __future__ import annotations

from whexar.runtime.errors import (
    MISSING,
    ConfigError,
    DeviceUnavailableError,
    Problem,
    UsageError,
    WhexarError,
)

__all__ = [
    "MISSING",
    "ConfigError",
    "DeviceError",
    "DeviceGoneError",
    "DeviceUnavailableError",
    "JointLimitError",
    "KinematicsError",
    "PortUnavailableError",
    "Problem",
    "UnreachableError",
    "UsageError",
    "WhexarError",
]


class DeviceError(WhexarError):
    """A device answered, but wrongly."""


class DeviceGoneError(WhexarError):
    """A device or its port stopped answering."""


class PortUnavailableError(DeviceGoneError, DeviceUnavailableError):
    """A port that cannot be opened at start: absent, busy or not permitted."""


class KinematicsError(UsageError):
    """A kinematic request cannot be satisfied as asked."""


class UnreachableError(KinematicsError):
    """A foot target lies outside the leg's workspace."""


class JointLimitError(KinematicsError):
    """A solution exists only with a joint outside its limits (Table 5.2)."""
