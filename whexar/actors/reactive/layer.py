"""``[[reflexes]]`` made into actors of the robot's graph.

A reflex is written down once — in the graph file or in the robot
configuration, as a ``[[reflexes]]`` entry (:class:`~whexar.config.ReflexEntry`):
its class, name, rank and parameters. :func:`add_reflexes` checks each (its class
found, its parameters valid, its inputs published in the graph) and adds to the
graph document, for each, an actor ``reflex-NAME`` running it
(:class:`~whexar.actors.reactive.shell.ReflexActor`) with its inputs wired to
the robot's channels, plus what they share: the ``overrides`` channel, wired to
every leg's ``reflex`` input, ``reflex-requests``, wired to the coordinator's
``requests`` input, and ``reflex-activity``. A reflex that keeps
failing is disabled and the robot walks on (:data:`RESTART`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Final

from pydantic import ValidationError

from whexar.actors.reactive.reflex import PRODUCERS, STREAMS, param_problems, resolve_reflex
from whexar.config import ReflexEntry
from whexar.errors import ConfigError, Problem
from whexar.runtime.schema import format_path, problem_from_error

REFLEX_ACTOR: Final = "whexar.actors.reactive:ReflexActor"
LEG_ACTOR: Final = "whexar.actors.locomotion:LegActor"
OVERRIDES: Final = "overrides"
"""The channel of the reflexes' override goals, which every leg's ``reflex`` input reads."""
REQUESTS: Final = "reflex-requests"
"""The channel of the reflexes' requests, which the coordinator's ``requests`` input reads."""
COORDINATOR: Final = "whexar.actors.locomotion:Coordinator"
ACTIVITY: Final = "reflex-activity"
"""The channel of the reflexes' activity (who holds whom back)."""
RESTART: Final[Mapping[str, Any]] = {
    "max_restarts": 3,
    "window_s": 10.0,
    "delay_s": 0.5,
    "exhausted": "disable",
}
"""A reflex's restart policy: three restarts in 10 s, then it is disabled, the robot goes on."""


def parse_entries(data: object, at: str, source: str) -> list[tuple[str, ReflexEntry]]:
    """A ``[[reflexes]]`` array (under key ``at``) checked: (key path, entry) pairs; a
    :class:`ConfigError` names each bad key."""
    if not isinstance(data, list):
        raise ConfigError(source, [Problem(at, data, "an array of tables ([[reflexes]])")])
    problems: list[Problem] = []
    out: list[tuple[str, ReflexEntry]] = []
    for i, item in enumerate(data):
        try:
            out.append((format_path((at, i)), ReflexEntry.model_validate(item)))
        except ValidationError as exc:
            problems.extend(
                problem_from_error(e, ReflexEntry, (at, i)) for e in exc.errors(include_url=False)
            )
    if problems:
        raise ConfigError(source, problems)
    return out


def entry_name(entry: ReflexEntry) -> str:
    """An entry's name: its ``name``, else its entry point's name or its class's, in lower
    case (``battery``; ``my_pkg.reflexes:ReachDown`` → ``reachdown``)."""
    if entry.name is not None:
        return entry.name
    return entry.type.rpartition(":")[2].lower()


def merged(*layers: Sequence[tuple[str, ReflexEntry]]) -> list[tuple[str, ReflexEntry]]:
    """The entries of several layers (the graph's, then the configuration's), a later
    entry replacing an earlier one of the same name where it stood: the configuration can
    retune a reflex of the graph, or leave it out with ``enabled = false``."""
    out: dict[str, tuple[str, ReflexEntry]] = {}
    for layer in layers:
        for at, entry in layer:
            out[entry_name(entry)] = (at, entry)
    return list(out.values())


def add_reflexes(
    doc: dict[str, Any],
    entries: Sequence[tuple[str, ReflexEntry]],
    *,
    source: str,
    config: str | None = None,
) -> None:
    """Add an actor for each enabled entry to the graph document ``doc`` (module docstring).

    ``entries`` are (key path, entry) pairs, the path naming the entry in errors;
    ``config`` is the robot configuration file the reflexes read. Raises
    :class:`ConfigError` listing every problem, before anything is added.
    """
    actors: list[dict[str, Any]] = doc.setdefault("actors", [])
    channels: dict[str, Any] = doc.setdefault("channels", {})
    taken = {a.get("name") for a in actors}
    problems: list[Problem] = []
    added: list[dict[str, Any]] = []
    for at, entry in entries:
        if not entry.enabled:
            continue
        try:
            cls = resolve_reflex(entry.type)
        except LookupError as exc:
            problems.append(Problem(f"{at}.type", entry.type, f"a reflex class: {exc}"))
            continue
        problems.extend(param_problems(cls, entry.params, f"{at}.params"))
        name = entry_name(entry)
        actor = f"reflex-{name}"
        if actor in taken:
            problems.append(
                Problem(f"{at}.name", name, f"a name no other actor has ({actor!r} is taken)")
            )
        taken.add(actor)
        for port in cls.inputs:
            channel = STREAMS[port][1]
            if channel not in channels and port in PRODUCERS:
                _publish(doc, port)
            if channel not in channels:
                problems.append(
                    Problem(
                        f"{at}.type",
                        entry.type,
                        f"a reflex whose inputs the graph publishes (it reads {port!r}, "
                        f"and the graph has no channel {channel!r})",
                    )
                )
        params: dict[str, Any] = {"reflex": entry.type, "params": dict(entry.params)}
        if entry.priority is not None:
            params["priority"] = entry.priority
        if entry.inhibits:
            params["inhibits"] = list(entry.inhibits)
        if config is not None:
            params["config"] = config
        added.append(
            {
                "name": actor,
                "class": REFLEX_ACTOR,
                "params": params,
                "inputs": {port: STREAMS[port][1] for port in cls.inputs}
                | {"activity_in": ACTIVITY},
                "outputs": {"override": OVERRIDES, "request": REQUESTS, "activity": ACTIVITY},
                "restart": dict(RESTART),
            }
        )
    if problems:
        raise ConfigError(source, problems)
    if not added:
        return
    actors.extend(added)
    channels.setdefault(OVERRIDES, {"message": "JointGoals", "policy": "queue"})
    channels.setdefault(REQUESTS, {"message": "ReflexRequest", "policy": "queue"})
    channels.setdefault(ACTIVITY, {"message": "ReflexActivity", "policy": "queue"})
    for a in actors:
        if a.get("class") == LEG_ACTOR:
            a.setdefault("inputs", {}).setdefault("reflex", OVERRIDES)
        elif a.get("class") == COORDINATOR:
            a.setdefault("inputs", {}).setdefault("requests", REQUESTS)


def _publish(doc: dict[str, Any], port: str) -> None:
    """Wire the output that publishes stream ``port`` (:data:`PRODUCERS`), if its actor is in
    the graph and leaves it unwired: a stream nobody read was not published."""
    cls, output = PRODUCERS[port]
    message, channel = STREAMS[port]
    for a in doc.get("actors", []):
        if a.get("class") == cls and output not in a.get("outputs", {}):
            a.setdefault("outputs", {})[output] = channel
            doc["channels"][channel] = {"message": message.__name__, "policy": "queue"}
            return
