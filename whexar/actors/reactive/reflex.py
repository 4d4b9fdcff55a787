"""Reflexes as plug-ins: the :class:`Reflex` base class, and how a reflex is found by name.

Theory of operation
-------------------
A reflex is a plain class — its policy — deriving from :class:`Reflex`. It declares

* ``inputs``: the robot's streams it reads, by port name (:data:`STREAMS`: the legs'
  swing ends and states, the servo states and health, the force sensors, the ranges,
  the tilt, the IMU's samples, the body motion, the locomotion state);
* ``Params``: a pydantic model of its thresholds and gains (:class:`ReflexParams`:
  unknown keys refused, ranges checked), each with its source;
* ``priority``: its rank when two reflexes give one joint a goal in one cycle (the
  highest wins at the leg, whatever the order they came in);
* ``inhibits``: the reflexes it holds back while it is active (so that one reflex can
  be tested without disabling the others by hand, the thesis's 6.7.1 problem).

and turns inputs into commands: :meth:`Reflex.react` is called with every message of
its inputs, :meth:`Reflex.tick` every ``tick_s`` if it sets one; each returns the
commands to send — override goals for a leg (:meth:`Reflex.override` makes them), a
request to the coordinator (:meth:`Reflex.request`: a higher step, a halt, a heading
correction, to sit down), an event (a warning, on the runtime's event stream) or a
:class:`Shutdown` (the run stops). It sets :attr:`active`
(and :attr:`reason`) while it acts. No ``await``, no channel, no clock read: its tests
call it directly. The actor that runs it, one per reflex, is
:class:`~whexar.actors.reactive.shell.ReflexActor`.

A reflex is named ``package.module:Class`` or by its name in the ``whexar.reflexes``
entry-point group (:func:`resolve_reflex`); a wrong name is a :class:`LookupError`
saying what is wrong, and :func:`check_params` turns bad parameters into messages
naming the key, the value and what is allowed.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterable, Mapping, Sequence
from importlib.metadata import entry_points
from typing import Any, ClassVar, Final, NamedTuple

from pydantic import BaseModel, ConfigDict, ValidationError

from whexar.actors.messages import (
    BodyMotion,
    BodyTilt,
    ImuSample,
    JointGoal,
    JointGoals,
    LegLoads,
    LegState,
    LocomotionState,
    ObstacleRanges,
    ReflexRequest,
    ServoHealth,
    ServoStates,
    SwingEnded,
)
from whexar.config import RobotConfig
from whexar.errors import MISSING, Problem
from whexar.runtime.messages import Event, Message

ENTRY_POINTS: Final = "whexar.reflexes"
"""The entry-point group a reflex package registers its reflexes in (name → class)."""
WALKING: Final = frozenset({"walking", "hybrid"})
"""The coordinator's activities (:class:`LocomotionState`) in which the robot walks on."""

STREAMS: Final[Mapping[str, tuple[type[Message], str]]] = {
    "swings": (SwingEnded, "swings"),
    "legs": (LegState, "legs"),
    "servo_state": (ServoStates, "servo-state"),
    "health": (ServoHealth, "health"),
    "loads": (LegLoads, "loads"),
    "ranges": (ObstacleRanges, "ranges"),
    "tilt": (BodyTilt, "tilt"),
    "imu": (ImuSample, "imu"),
    "motion": (BodyMotion, "motion"),
    "locomotion": (LocomotionState, "locomotion"),
}
"""What a reflex may declare in ``inputs``: port → (message type, the robot graph's channel)."""
PRODUCERS: Final[Mapping[str, tuple[str, str]]] = {
    "imu": ("whexar.actors.sensing:ImuReader", "samples"),
}
"""Streams the robot's graph publishes only when a reflex reads them: port → (the actor
class whose output it is, that output), wired by :func:`~.layer.add_reflexes`."""


class Shutdown(NamedTuple):
    """What a reflex returns to stop the run: the robot is at rest, the servos' torque goes
    off (the battery reflex, once seated on an empty battery)."""

    reason: str


Command = JointGoals | ReflexRequest | Event | Shutdown
"""What a reflex returns: override goals for the legs, a request to the coordinator, an
event (a warning) or a :class:`Shutdown`."""


class ReflexParams(BaseModel):
    """Base of a reflex's ``Params``: unknown keys are refused, the model is frozen."""

    model_config = ConfigDict(extra="forbid", frozen=True)


class Reflex:
    """Base of a reflex's policy (module docstring).

    ``name`` is the reflex's name in the graph (its commands' ``source``), ``params`` its
    validated :attr:`Params`, ``cfg`` the robot configuration.
    """

    inputs: ClassVar[tuple[str, ...]] = ()
    """The streams it reads, names of :data:`STREAMS`."""
    Params: ClassVar[type[ReflexParams]] = ReflexParams
    priority: ClassVar[int] = 0
    """Its default rank at the legs (the configuration may set another)."""
    inhibits: ClassVar[tuple[str, ...]] = ()
    """The reflexes (by name) it holds back while active (the configuration may add)."""
    tick_s: ClassVar[float | None] = None
    """Period of :meth:`tick`, s; ``None``: it only reacts to messages."""

    def __init__(self, params: ReflexParams, *, name: str, cfg: RobotConfig) -> None:
        self.params = params
        self.name = name
        self.cfg = cfg
        self.active = False
        """True while it acts (it says so on ``reflex-activity``)."""
        self.reason = ""
        """Why it is active, in a few words (an event's text)."""

    def react(self, t: float, msg: Message) -> Iterable[Command]:
        """A message of one of its inputs arrived at ``t``: the commands to send."""
        return ()

    def tick(self, t: float) -> Iterable[Command]:
        """Called every :attr:`tick_s`: the commands to send."""
        return ()

    def override(self, t: float, leg: int, angles: Mapping[int, float]) -> JointGoals:
        """Override goals for leg ``leg``: joint → angle (rad), stamped ``t``; the shell
        sets their priority."""
        goals = tuple(
            JointGoal(t=t, source=self.name, leg=leg, joint=j, position_rad=a)
            for j, a in sorted(angles.items())
        )
        return JointGoals(t=t, source=self.name, goals=goals, reflex=True)

    def request(self, t: float, **asked: Any) -> ReflexRequest:
        """A request to the coordinator (:class:`ReflexRequest`'s fields: ``step_height_m``,
        ``halt``, ``yaw_rate_rad_s``, ``sit_down``, ``reason``), stamped ``t``."""
        return ReflexRequest(t=t, source=self.name, reflex=self.name, **asked)


def resolve_reflex(kind: str) -> type[Reflex]:
    """The reflex class named ``kind``: ``package.module:Class``, or a name registered in
    the ``whexar.reflexes`` entry-point group. Raises :class:`LookupError` saying what is
    wrong."""
    if ":" in kind:
        module_name, _, attr = kind.partition(":")
        if not module_name or not attr:
            raise LookupError(f"{kind!r}: expected 'package.module:Class'")
        try:
            module = importlib.import_module(module_name)
        except ImportError as exc:
            raise LookupError(
                f"{kind!r}: module {module_name!r} cannot be imported ({exc})"
            ) from None
        found = getattr(module, attr, None)
        if found is None:
            raise LookupError(f"{kind!r}: module {module_name!r} has no {attr!r}")
    else:
        named = {ep.name: ep for ep in entry_points(group=ENTRY_POINTS)}
        if kind not in named:
            known = ", ".join(sorted(named)) or "none installed"
            raise LookupError(
                f"{kind!r}: not 'package.module:Class' and not a reflex of the "
                f"{ENTRY_POINTS!r} entry points ({known})"
            )
        try:
            found = named[kind].load()
        except Exception as exc:  # a broken plug-in is named, not raised through
            raise LookupError(f"{kind!r}: its entry point cannot be loaded ({exc})") from None
    if not (isinstance(found, type) and issubclass(found, Reflex)):
        raise LookupError(f"{kind!r}: not a subclass of whexar.actors.reactive.Reflex")
    unknown = [i for i in found.inputs if i not in STREAMS]
    if unknown:
        raise LookupError(
            f"{kind!r}: unknown inputs {unknown}; a reflex reads {', '.join(STREAMS)}"
        )
    return found


def param_problems(cls: type[Reflex], params: Mapping[str, Any], at: str) -> list[Problem]:
    """What is wrong with ``params`` for ``cls.Params``: each bad key under ``at``, its
    value and what is allowed (an unknown key: the reflex's parameters)."""
    try:
        cls.Params.model_validate(dict(params))
    except ValidationError as exc:
        found = []
        for e in exc.errors(include_url=False):
            key = ".".join([at, *(str(p) for p in e["loc"])])
            if e["type"] == "extra_forbidden":
                known = ", ".join(cls.Params.model_fields) or "none"
                found.append(Problem(key, e["input"], f"a parameter of it ({known})"))
            else:
                value = params.get(str(e["loc"][0]), MISSING) if e["loc"] else MISSING
                found.append(Problem(key, value, e["msg"]))
        return found
    return []


def check_params(cls: type[Reflex], params: Mapping[str, Any]) -> ReflexParams:
    """``params`` validated by ``cls.Params``; a :class:`ValueError` names every bad key,
    its value and what is allowed."""
    problems = param_problems(cls, params, "params")
    if problems:
        raise ValueError("; ".join(str(p) for p in problems))
    return cls.Params.model_validate(dict(params))


def inhibitions(cls: type[Reflex], extra: Sequence[str] | None) -> tuple[str, ...]:
    """What a reflex holds back: its class's ``inhibits`` and the configuration's."""
    return tuple(dict.fromkeys((*cls.inhibits, *(extra or ()))))
