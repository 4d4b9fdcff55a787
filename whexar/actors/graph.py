"""The robot's actor graph: one definition, the edges swapped by name.

``config/graphs/walk.toml`` is the robot — the bus scheduler, the sensor and
IMU readers, six legs, the coordinator and a command source — and the only
place its actors and channels are written down. Whatever runs the robot
loads it: ``whexar run`` on the robot or on the emulators, the simulation,
the benchmarks, the tests. Only the *edges* change (the copper-rs way): the
servo port of ``bus``, the board port of ``sensors``, the I²C device of
``imu``, the front end of ``commands`` — each set by actor name, as
``--set ACTOR.PARAM=VALUE`` sets it on the command line.

:func:`robot_graph` returns the wiring document with those swaps made, the
configuration file given to every actor that reads one, and, for a harness
or a replay that publishes a channel itself (``feeds``), the actors that
publish nothing else left out. Channels nobody publishes any more are
unwired from their subscribers' inputs, so the document stays valid. The
reflexes written as ``[[reflexes]]`` — in the graph file or the robot
configuration — become actors of their own (:func:`with_reflexes`).
"""

from __future__ import annotations

import copy
import fnmatch
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, Final

from whexar.actors.reactive import add_reflexes, merged, parse_entries
from whexar.actors.reactive.layer import REFLEX_ACTOR
from whexar.config import load_config
from whexar.runtime.errors import UsageError
from whexar.runtime.schema import read_toml
from whexar.runtime.wiring import actor_names, set_param

GRAPH_DIR: Final = Path(__file__).resolve().parents[2] / "config" / "graphs"
"""The shipped wiring files: the repository's ``config/graphs`` folder."""
ROBOT_GRAPH: Final = GRAPH_DIR / "walk.toml"
"""The robot's graph."""
EDGES: Final = {"bus": "port", "sensors": "port", "imu": "device", "commands": "source"}
"""The robot's edge actors and the parameter that names each one's device or front end."""
CONFIGURED: Final = (
    "bus",
    "sensors",
    "imu",
    "leg-*",
    "coordinator",
    "commands",
    "terrain",
    "gait-selector",
    "reflex-*",
)
"""The robot graph's actors that read the robot configuration (their ``config``
parameter), as shell patterns of their names."""

_cache: dict[Path, dict[str, Any]] = {}


def _read(path: Path) -> dict[str, Any]:
    found = _cache.get(path)
    if found is None:
        found = _cache[path] = read_toml(path)
    return copy.deepcopy(found)


def robot_graph(
    *,
    bus: str | None = None,
    sensors: str | None = None,
    imu: str | None = None,
    commands: str | None = None,
    config: str | Path | None = None,
    params: Mapping[str, Mapping[str, Any]] | None = None,
    feeds: Iterable[str] = (),
    leave_out: Iterable[str] = (),
    path: str | Path = ROBOT_GRAPH,
) -> dict[str, Any]:
    """The robot's wiring document with its edges swapped.

    ``bus``, ``sensors``, ``imu`` and ``commands`` set the device (or command
    front end) of the edge actor of that name (:data:`EDGES`); absent, the
    graph file's own value stays (the emulators). ``config`` is the robot
    configuration file every actor that reads one gets. ``params`` sets any
    other parameter: actor name (a shell pattern such as ``leg-*``) → {param:
    value}. ``feeds`` names channels a harness or a replay publishes itself:
    an actor whose outputs all go to fed channels is left out, like each
    actor of ``leave_out`` and each reflex whose inputs nobody publishes any
    more; a channel left with no publisher is unwired from its subscribers
    (their inputs must be optional, or the wiring says so).
    """
    source = str(path)
    doc = _read(Path(path))
    with_reflexes(doc, source=source, config=config)
    names = actor_names(doc)
    for actor, value in (("bus", bus), ("sensors", sensors), ("imu", imu), ("commands", commands)):
        if value is not None:
            set_param(doc, f"{actor}.{EDGES[actor]}", value, source=source, option=actor)
    if config is not None:
        for name in names:
            if any(fnmatch.fnmatchcase(name, pattern) for pattern in CONFIGURED):
                set_param(doc, f"{name}.config", str(config), source=source, option="config")
    for pattern, values in (params or {}).items():
        matched = [n for n in names if fnmatch.fnmatchcase(n, pattern)]
        if not matched:
            raise UsageError(f"{source}: no actor matches {pattern!r}; its actors: {names}")
        for name in matched:
            for key, value in values.items():
                set_param(doc, f"{name}.{key}", value, source=source, option="params")
    _leave_out(doc, set(leave_out), set(feeds), source)
    return doc


def with_reflexes(doc: dict[str, Any], *, source: str, config: str | Path | None) -> None:
    """The graph document ``doc`` with its ``[[reflexes]]`` and the robot configuration's
    (``config``'s) made into actors (:func:`~whexar.actors.reactive.add_reflexes`); an
    entry of the configuration replaces the graph's of the same name."""
    graph = parse_entries(doc.pop("reflexes"), "reflexes", source) if "reflexes" in doc else []
    own = []
    if config is not None:
        own = [(f"{config}: reflexes[{i}]", e) for i, e in enumerate(load_config(config).reflexes)]
    entries = merged(graph, own)
    if entries:
        add_reflexes(doc, entries, source=source, config=str(config) if config else None)


def _leave_out(doc: dict[str, Any], names: set[str], feeds: set[str], source: str) -> None:
    unknown = names - set(actor_names(doc))
    if unknown:
        raise UsageError(f"{source}: no actors {sorted(unknown)} to leave out")
    kept = []
    for actor in doc["actors"]:
        outputs = set(actor.get("outputs", {}).values())
        if actor["name"] in names or (outputs and outputs <= feeds):
            continue
        kept.append(actor)
    published = {ch for a in kept for ch in a.get("outputs", {}).values()} | feeds
    # A reflex whose inputs are no longer published cannot do its work: it goes too.
    kept = [
        a
        for a in kept
        if a.get("class") != REFLEX_ACTOR
        or all(ch in published for p, ch in a.get("inputs", {}).items() if p != "activity_in")
    ]
    doc["actors"] = kept
    published = {ch for a in kept for ch in a.get("outputs", {}).values()} | feeds
    for actor in kept:
        inputs = actor.get("inputs", {})
        for port, channel in list(inputs.items()):
            if channel not in published:
                del inputs[port]
    used = published | {ch for a in kept for ch in a.get("inputs", {}).values()}
    doc["channels"] = {n: c for n, c in doc.get("channels", {}).items() if n in used}
