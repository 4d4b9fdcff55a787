"""The actor graph: which actors run, in what order, and which channels join them.

Theory of operation
-------------------
The whole graph is configuration, in one place (copper-rs's
``copperconfig.ron``)::

    [runtime]
    stop_timeout_s = 1.0

    [[actors]]                       # start order = file order
    name = "pulse"
    class = "whexar.testing:Pulse"   # "package.module:Class"
    params = { period_s = 0.01 }
    outputs = { out = "beats" }      # port -> channel (or a list of channels)

    [[actors]]
    name = "sink"
    class = "whexar.testing:Sink"
    inputs = { inp = "beats" }       # port -> channel

    [channels.beats]
    message = "Heartbeat"            # a registered message type
    policy = "latest"                # latest | backpressure | queue
    capacity = 1

The built-in channel ``events`` carries the runtime's
:class:`~whexar.runtime.messages.Event` values; any actor may subscribe to it.

:func:`build_graph` checks the wiring before anything runs and raises
:class:`WiringError` listing every problem, each naming the actor, port and
channel: an unknown actor class or message type, a port the class does not
have, a channel whose type does not fit the port, a required port left
unwired, a channel someone subscribes to that nobody publishes, a command
(``backpressure``) channel with two owners, a channel nobody uses.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import Field, ValidationError

from whexar.runtime.actor import Actor, ActorParams, Input, Output
from whexar.runtime.channels import Policy, capacity_or_default
from whexar.runtime.errors import MISSING, ConfigError, Problem
from whexar.runtime.messages import MESSAGE_TYPES, Event, Message
from whexar.runtime.schema import (
    NonNegative,
    Positive,
    Section,
    format_path,
    problem_from_error,
    read_toml,
)

EVENTS_CHANNEL = "events"
"""The built-in channel of runtime events; its publisher is the runtime."""

RUNTIME = "runtime"
"""The ``source`` of messages the runtime itself makes."""

Name = Annotated[str, Field(pattern=r"^[A-Za-z_][A-Za-z0-9_.-]*$", max_length=64)]


class WiringError(ConfigError):
    """The actor graph is wired wrongly; :attr:`problems` names each actor, port and channel."""


# --------------------------------------------------------------------------- specification


class RestartPolicy(Section):
    """Restart a failed actor up to ``max_restarts`` times within ``window_s``; then
    escalate (the runtime stops safely) or, with ``exhausted = "disable"``, leave the
    actor down while the rest runs on (an actor the robot can do without: a reflex)."""

    max_restarts: int = Field(3, ge=0)
    window_s: Positive = 10.0
    delay_s: NonNegative = 0.1
    """Pause before a restart, so a failing device is not hammered."""
    exhausted: Literal["escalate", "disable"] = "escalate"
    """What a failure past ``max_restarts`` does: stop the run, or disable the actor."""


class RuntimeSettings(Section):
    """How the runtime treats every actor."""

    stop_timeout_s: Positive = 1.0
    """Time each actor gets to finish once told to stop (and for safe-stop hooks)."""
    ready_timeout_s: Positive = 5.0
    """Time an actor may take from start to ready before that counts as a failure."""
    events_capacity: int = Field(1024, ge=1)
    """Buffer of the ``events`` channel per subscriber (a queue: overflow is counted)."""
    restart: RestartPolicy = RestartPolicy()
    """Default restart policy; an actor's own ``restart`` table overrides it."""
    real_io_on_virtual_time: bool = False
    """Allow real I/O (a device, a pty, a worker thread) on virtual time; refused otherwise.

    Virtual time runs away while real I/O is pending, so only a graph that
    means it (a pty in a test, a replay reading a file) says ``true``.
    """


class ActorSpec(Section):
    """One actor instance in the graph."""

    name: Name
    class_: str = Field(alias="class")
    """Import path of the actor class, ``package.module:Class``."""
    params: dict[str, Any] = Field(default_factory=dict)
    inputs: dict[str, Name] = Field(default_factory=dict)
    outputs: dict[str, Name | list[Name]] = Field(default_factory=dict)
    restart: RestartPolicy | None = None


class ChannelSpec(Section):
    """One named channel."""

    message: str
    """Registered message type name (``Heartbeat``), or ``package.module:Class``."""
    policy: Policy
    capacity: int | None = Field(None, ge=1, le=1_000_000)
    """Buffer per subscriber; default 1 for latest, 16 for backpressure, 256 for queue."""


class GraphSpec(Section):
    """The whole actor graph, as written in the wiring file."""

    runtime: RuntimeSettings = RuntimeSettings()
    actors: list[ActorSpec] = Field(default_factory=list)
    channels: dict[Name, ChannelSpec] = Field(default_factory=dict)


# --------------------------------------------------------------------------- resolved graph


@dataclass(frozen=True)
class ActorNode:
    """One actor, resolved: its class, validated params, and its ports' channels."""

    name: str
    cls: type[Actor]
    params: ActorParams
    inputs: Mapping[str, str | None]
    outputs: Mapping[str, tuple[str, ...]]
    restart: RestartPolicy


@dataclass(frozen=True)
class ChannelNode:
    """One channel, resolved, with who publishes and who subscribes."""

    name: str
    message_type: type[Message]
    policy: Policy
    capacity: int
    publishers: tuple[str, ...]
    subscribers: tuple[str, ...]


@dataclass(frozen=True)
class Graph:
    """A checked actor graph, ready for :class:`~whexar.runtime.supervisor.Runtime`."""

    settings: RuntimeSettings
    actors: tuple[ActorNode, ...]
    channels: Mapping[str, ChannelNode]

    def actor(self, name: str) -> ActorNode:
        """The node of actor ``name``."""
        for node in self.actors:
            if node.name == name:
                return node
        raise KeyError(name)


def _import(path: str, what: str) -> object:
    """``package.module:Name`` → the object; raises ``LookupError`` saying what is wrong."""
    module_name, sep, attr = path.partition(":")
    if not sep or not module_name or not attr:
        raise LookupError(f"{what} as 'package.module:Name'")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise LookupError(f"{what}; module {module_name!r} cannot be imported ({exc})") from None
    try:
        return getattr(module, attr)
    except AttributeError:
        raise LookupError(f"{what}; module {module_name!r} has no {attr!r}") from None


def _resolve_class(path: str) -> type[Actor]:
    found = _import(path, "an actor class")
    if not (isinstance(found, type) and issubclass(found, Actor)):
        raise LookupError(f"an actor class; {path!r} is not a subclass of whexar Actor")
    return found


def _resolve_message(name: str) -> type[Message]:
    if ":" in name:
        found = _import(name, "a message type")
        if not (isinstance(found, type) and issubclass(found, Message)):
            raise LookupError(f"a message type; {name!r} is not a Message")
        return found
    try:
        return MESSAGE_TYPES[name]
    except KeyError:
        known = ", ".join(sorted(MESSAGE_TYPES))
        raise LookupError(f"a registered message type ({known}) or 'package.module:Name'") from None


class _Checker:
    """Collects every problem of one graph; resolution continues past each one."""

    def __init__(self, spec: GraphSpec, external: Mapping[str, str]) -> None:
        self.spec = spec
        self.external = external
        self.problems: list[Problem] = []
        self.types: dict[str, type[Message]] = {EVENTS_CHANNEL: Event}
        self.publishers: dict[str, list[str]] = {EVENTS_CHANNEL: [RUNTIME]}
        self.subscribers: dict[str, list[str]] = {EVENTS_CHANNEL: []}
        # Channels named by a port that could not be wired: whether they lack
        # a publisher is then a consequence, not a problem of its own.
        self.doubtful: set[str] = set()

    def problem(self, path: Sequence[object], value: object, allowed: str) -> None:
        self.problems.append(Problem(format_path(path), value, allowed))

    def channels(self) -> None:
        for name, ch in self.spec.channels.items():
            if name == EVENTS_CHANNEL:
                self.problem(("channels", name), name, "a name other than the built-in 'events'")
                continue
            try:
                self.types[name] = _resolve_message(ch.message)
            except LookupError as exc:
                self.problem(("channels", name, "message"), ch.message, str(exc))
            self.publishers[name] = []
            self.subscribers[name] = []
        for name, publisher in self.external.items():
            if name in self.publishers:
                self.publishers[name].append(publisher)
            else:
                self.problem(
                    ("channels", name), MISSING, f"a declared channel (fed by {publisher})"
                )

    def actor(self, spec: ActorSpec, seen: set[str]) -> ActorNode | None:
        at: tuple[object, ...] = ("actors", spec.name)
        if spec.name in seen:
            self.problem((*at, "name"), spec.name, "a name no other actor has")
        seen.add(spec.name)
        try:
            cls = _resolve_class(spec.class_)
        except LookupError as exc:
            self.problem((*at, "class"), spec.class_, str(exc))
            for value in (*spec.inputs.values(), *spec.outputs.values()):
                self.doubtful.update([value] if isinstance(value, str) else value)
            return None
        params = self.params(cls, spec, at)
        ports = cls.ports()
        inputs = self.inputs(spec, ports, at)
        outputs = self.outputs(spec, ports, at)
        if params is None:
            return None
        return ActorNode(
            name=spec.name,
            cls=cls,
            params=params,
            inputs=inputs,
            outputs=outputs,
            restart=spec.restart or self.spec.runtime.restart,
        )

    def params(
        self, cls: type[Actor], spec: ActorSpec, at: tuple[object, ...]
    ) -> ActorParams | None:
        try:
            return cls.Params.model_validate(spec.params)
        except ValidationError as exc:
            for error in exc.errors(include_url=False):
                problem = problem_from_error(error, cls.Params, (*at, "params"))
                self.problems.append(problem)
            return None

    def _link(
        self,
        ports: Mapping[str, Input[Any] | Output[Any]],
        kind: type[Input[Any]] | type[Output[Any]],
        port: str,
        channel: str,
        at: tuple[object, ...],
    ) -> bool:
        """Check one port → channel link: the port exists, the channel too, the types fit."""
        declared = ports.get(port)
        if not isinstance(declared, kind):
            self.doubtful.add(channel)
            names = [n for n, p in ports.items() if isinstance(p, kind)]
            self.problem(
                (*at, port),
                channel,
                f"a port of the class; its {kind.__name__.lower()}s: {', '.join(names) or 'none'}",
            )
            return False
        if channel not in self.types:
            if channel not in self.spec.channels:  # an unknown name, not a bad message type
                known = ", ".join(sorted({EVENTS_CHANNEL, *self.spec.channels}))
                self.problem((*at, port), channel, f"a declared channel ({known})")
            return False
        carried = self.types[channel]
        wanted = declared.message_type
        # An input takes the channel's type or a subclass; an output may send a subclass.
        fits = issubclass(carried, wanted) if kind is Input else issubclass(wanted, carried)
        if not fits:
            self.doubtful.add(channel)
            self.problem(
                (*at, port),
                channel,
                f"a channel of {wanted.__name__}; channel {channel!r} carries {carried.__name__}",
            )
        return fits

    def _unwired(
        self,
        spec: ActorSpec,
        ports: Mapping[str, Input[Any] | Output[Any]],
        kind: type[Input[Any]] | type[Output[Any]],
        wired: Mapping[str, object],
        at: tuple[object, ...],
    ) -> list[str]:
        """The optional ports of ``kind`` not in ``wired``; a required one is a problem."""
        optional = []
        for port, declared in ports.items():
            if not isinstance(declared, kind) or port in wired:
                continue
            if declared.optional:
                optional.append(port)
            else:
                self.problem(
                    (*at, port),
                    None,
                    f"a channel of {declared.message_type.__name__}: {kind.__name__.lower()} "
                    f"{port!r} of actor {spec.name!r} is required but not wired",
                )
        return optional

    def inputs(
        self,
        spec: ActorSpec,
        ports: Mapping[str, Input[Any] | Output[Any]],
        at: tuple[object, ...],
    ) -> dict[str, str | None]:
        wired: dict[str, str | None] = {}
        for port, channel in spec.inputs.items():
            if self._link(ports, Input, port, channel, (*at, "inputs")):
                wired[port] = channel
                self.subscribers[channel].append(spec.name)
        for port in self._unwired(spec, ports, Input, spec.inputs, (*at, "inputs")):
            wired[port] = None
        return wired

    def outputs(
        self,
        spec: ActorSpec,
        ports: Mapping[str, Input[Any] | Output[Any]],
        at: tuple[object, ...],
    ) -> dict[str, tuple[str, ...]]:
        wired: dict[str, tuple[str, ...]] = {}
        for port, value in spec.outputs.items():
            good: list[str] = []
            for channel in [value] if isinstance(value, str) else value:
                if channel == EVENTS_CHANNEL:
                    self.problem(
                        (*at, "outputs", port),
                        channel,
                        "a channel other than 'events' "
                        "(only the runtime publishes there; actors call emit())",
                    )
                elif self._link(ports, Output, port, channel, (*at, "outputs")):
                    good.append(channel)
                    self.publishers[channel].append(spec.name)
            wired[port] = tuple(good)
        for port in self._unwired(spec, ports, Output, spec.outputs, (*at, "outputs")):
            wired[port] = ()
        return wired

    def channel_nodes(self) -> dict[str, ChannelNode]:
        nodes: dict[str, ChannelNode] = {}
        settings = self.spec.runtime
        for name, message_type in self.types.items():
            pubs = tuple(self.publishers.get(name, ()))
            subs = tuple(self.subscribers.get(name, ()))
            if name == EVENTS_CHANNEL:
                nodes[name] = ChannelNode(
                    name, Event, Policy.QUEUE, settings.events_capacity, pubs, subs
                )
                continue
            ch = self.spec.channels[name]
            at = ("channels", name)
            if subs and not pubs and name not in self.doubtful:
                self.problem(
                    at,
                    ch.message,
                    f"a publisher; subscribed by {_names(subs)} but no actor publishes "
                    f"{ch.message} on channel {name!r}",
                )
            if ch.policy is Policy.BACKPRESSURE and len(pubs) > 1:
                self.problem(
                    (*at, "policy"),
                    ch.policy.value,
                    f"one owner for a command (backpressure) channel; {name!r} is published "
                    f"by {_names(pubs)}",
                )
            if not subs and not pubs and name not in self.doubtful:
                self.problem(at, ch.message, "a channel some actor uses; no actor wires it")
            nodes[name] = ChannelNode(
                name,
                message_type,
                ch.policy,
                capacity_or_default(ch.policy, ch.capacity),
                pubs,
                subs,
            )
        return nodes


def _names(actors: Sequence[str]) -> str:
    return ", ".join(f"actor {a!r}" for a in actors)


def _named_location(loc: tuple[object, ...], data: Mapping[str, Any]) -> tuple[object, ...]:
    """``("actors", 2, …)`` → ``("actors", "<name>", …)`` when entry 2 has a name."""
    if len(loc) >= 2 and loc[0] == "actors" and isinstance(loc[1], int):
        actors = data.get("actors")
        if isinstance(actors, list) and loc[1] < len(actors):
            entry = actors[loc[1]]
            if isinstance(entry, Mapping) and isinstance(entry.get("name"), str):
                return ("actors", entry["name"], *loc[2:])
    return loc


def parse_graph(data: Mapping[str, Any], source: str = "<graph>") -> GraphSpec:
    """Validate a wiring document's structure (keys, types, ranges)."""
    try:
        return GraphSpec.model_validate(data)
    except ValidationError as exc:
        problems = []
        for error in exc.errors(include_url=False):
            problem = problem_from_error(error, GraphSpec)
            named = _named_location(tuple(error["loc"]), data)
            if named != tuple(error["loc"]):
                problem = Problem(format_path(named), problem.value, problem.allowed)
            problems.append(problem)
        raise WiringError(source, problems) from None


def build_graph(
    spec: GraphSpec | Mapping[str, Any],
    *,
    source: str = "<graph>",
    external: Mapping[str, str] | None = None,
) -> Graph:
    """Resolve and check a graph; raises :class:`WiringError` listing every problem.

    ``external`` names channels published from outside the actor graph (a
    test harness feeding messages): channel → publisher name.
    """
    if not isinstance(spec, GraphSpec):
        spec = parse_graph(spec, source)
    checker = _Checker(spec, external or {})
    checker.channels()
    nodes: list[ActorNode] = []
    seen: set[str] = set()
    for actor_spec in spec.actors:
        node = checker.actor(actor_spec, seen)
        if node is not None:
            nodes.append(node)
    channels = checker.channel_nodes()
    if checker.problems:
        raise WiringError(source, checker.problems)
    return Graph(settings=spec.runtime, actors=tuple(nodes), channels=channels)


def load_graph(path: str | Path, *, external: Mapping[str, str] | None = None) -> Graph:
    """Read, validate and resolve a TOML wiring file."""
    return build_graph(read_toml(path), source=str(path), external=external)


def actor_names(data: Mapping[str, Any]) -> list[str]:
    """The names of a wiring document's actors, in order."""
    actors = data.get("actors")
    if not isinstance(actors, list):
        return []
    return [a["name"] for a in actors if isinstance(a, dict) and isinstance(a.get("name"), str)]


def set_param(
    data: dict[str, Any], target: str, value: object, *, source: str, option: str = "--set"
) -> None:
    """Set parameter ``target`` (``ACTOR.PARAM``, or ``ACTOR.TABLE.KEY``) of a wiring document.

    The actor is the longest actor name of the graph that ``target`` starts
    with (names may hold dots). An unknown actor is a
    :class:`~whexar.runtime.errors.ConfigError` listing the graph's actors.
    """
    names = actor_names(data)
    actor = max(
        (n for n in names if target.startswith(f"{n}.") and len(target) > len(n) + 1),
        key=len,
        default=None,
    )
    if actor is None:
        known = ", ".join(names) or "none"
        raise ConfigError(
            source,
            [
                Problem(
                    option, target, f"ACTOR.PARAM with an actor of the graph; its actors: {known}"
                )
            ],
        )
    *tables, key = target[len(actor) + 1 :].split(".")
    for entry in data["actors"]:
        if not (isinstance(entry, dict) and entry.get("name") == actor):
            continue
        table: object = entry.setdefault("params", {})
        walked = f"actors.{actor}.params"
        for name in (*tables, None):
            if not isinstance(table, dict):
                raise ConfigError(
                    source,
                    [Problem(option, target, f"a key inside a table; {walked} is not a table")],
                )
            if name is None:
                table[key] = value
            else:
                table = table.setdefault(name, {})
                walked += f".{name}"
