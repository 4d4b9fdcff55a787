"""The base message type, its registry, and the runtime's own events.

Each message carries ``t``, the runtime-clock time it is valid for (a sensor
sample's time, a goal's cycle, an event's moment — copper-rs's "time of
validity"), and ``source``, the name of the actor that made it. Wiring
configuration names message types by their class name; :func:`message`
registers a class under that name, so an extension defines its own messages
with the same decorator and no change to the core.

Why frozen dataclasses and not pydantic models
----------------------------------------------
Measured on this machine (``whexar bench runtime`` prints the creation
cost again, for :class:`Heartbeat`):

=====================================  ===========  ============
                                       creation     field read
=====================================  ===========  ============
frozen dataclass (slots, kw_only)      ~0.9 µs      ~33 ns
pydantic ``BaseModel`` (frozen)        ~1.25 µs     ~60 ns
pydantic ``model_construct``           ~2.7 µs      ~60 ns
=====================================  ===========  ============

Messages are made and read in the hot path of every control cycle, by code
whose types mypy already checks. Validation belongs at the edges (the
configuration, the protocol codecs), where pydantic is used. Dataclasses
are also plain to hash and compare, and their ``repr`` is the stable text
that the message-log hash of :mod:`whexar.testing` is built from. So
messages are frozen, slotted, keyword-only dataclasses. Fields hold
immutable values (numbers, strings, tuples), never numpy arrays, so that a
message cannot change after it is sent.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, TypeVar, cast, dataclass_transform

from whexar.runtime.errors import UsageError

M = TypeVar("M", bound="Message")
_AnyType = TypeVar("_AnyType", bound=type)

MESSAGE_TYPES: dict[str, type[Message]] = {}
"""Registered message types by class name (what wiring configuration refers to)."""


@dataclass_transform(frozen_default=True, kw_only_default=True)
def message(cls: _AnyType) -> _AnyType:
    """Class decorator: make ``cls`` a frozen message dataclass and register its name."""
    made: Any = dataclass(frozen=True, slots=True, kw_only=True)(cls)
    name = made.__name__
    known = MESSAGE_TYPES.get(name)
    if known is not None and known.__qualname__ != made.__qualname__:
        raise UsageError(
            f"message type {name!r} is already registered by {known.__module__}; "
            "message names must be unique"
        )
    if name != "Message" and not issubclass(made, Message):
        raise UsageError(f"@message class {name!r} must derive from Message")
    MESSAGE_TYPES[name] = made
    return cast(_AnyType, made)


@message
class Message:
    """Base of every message: valid for runtime time ``t`` (s), made by actor ``source``."""

    t: float
    source: str


# --------------------------------------------------------------------------- generic


@message
class Heartbeat(Message):
    """A periodic sign of life, numbered from 0 (also the token of the runtime bench)."""

    seq: int


# --------------------------------------------------------------------------- events


@message
class Event(Message):
    """Base of what the runtime reports about itself on the ``events`` channel."""


@message
class ActorStarting(Event):
    """The runtime is starting incarnation ``incarnation`` (0 first) of ``actor``."""

    actor: str
    incarnation: int


@message
class ActorReady(Event):
    """``actor`` reported its resources open; the next actor may start."""

    actor: str
    incarnation: int


@message
class ActorFailed(Event):
    """``actor`` raised ``error`` (type and text) while ``phase`` was start, run or safe_stop.

    ``traceback`` is the formatted traceback of what was raised (empty for a
    failure that raised nothing: a start that timed out, a ``run()`` that
    returned before ready).
    """

    actor: str
    incarnation: int
    phase: str
    error: str
    traceback: str = ""


@message
class ActorRestarted(Event):
    """``actor`` starts again after a failure: ``failures`` within its policy's window."""

    actor: str
    incarnation: int
    failures: int


@message
class ActorEscalated(Event):
    """``actor`` failed more than its policy allows; the runtime stops safely."""

    actor: str
    failures: int
    window_s: float


@message
class ActorDisabled(Event):
    """``actor`` failed more than its policy allows and stays down; the run goes on
    (its policy says ``exhausted = "disable"``). ``error`` is its last failure."""

    actor: str
    failures: int
    window_s: float
    error: str


@message
class ActorStopped(Event):
    """``actor`` ended: ``reason`` is stop, returned, escalated or disabled; ``timed_out`` if
    it overran."""

    actor: str
    reason: str
    timed_out: bool = False


@message
class StopRequested(Event):
    """Something asked the runtime to stop (a signal, the end of a run, an escalation)."""

    reason: str


@message
class SafeStop(Event):
    """The safe-stop hooks ran (after an escalation) before the actors were stopped."""

    reason: str


@message
class TickOverrun(Event):
    """A control cycle of ``actor`` took ``elapsed_s`` against a period of ``period_s``.

    ``skipped`` deadlines were dropped so the ticker stays on its grid.
    """

    actor: str
    cycle: int
    period_s: float
    elapsed_s: float
    skipped: int
