"""Fixtures of the recording tests: a recorded run of the servo bus, and a small JSON Schema
checker for the subset of JSON Schema that whexar and Foxglove's schemas use (the project
adds no validator dependency)."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from whexar.record.writer import Recorder
from whexar.runtime.messages import Message
from whexar.testing import Harness, run_actors
from whexar.testing.bus import bus_graph

SchemaCheck = Callable[[Mapping[str, Any], Any], list[str]]

_TYPES: dict[str, Callable[[Any], bool]] = {
    "object": lambda v: isinstance(v, dict),
    "array": lambda v: isinstance(v, list),
    "string": lambda v: isinstance(v, str),
    "boolean": lambda v: isinstance(v, bool),
    "integer": lambda v: isinstance(v, int) and not isinstance(v, bool),
    # NaN is written as null: the one documented exception (whexar.record.encoding).
    "number": lambda v: v is None or (isinstance(v, int | float) and not isinstance(v, bool)),
}


def check_schema(schema: Mapping[str, Any], value: Any, where: str = "$") -> list[str]:
    """What is wrong with ``value`` under ``schema`` (type, properties, required,
    additionalProperties, items, min/maxItems, enum, const, oneOf, minimum, maximum)."""
    problems: list[str] = []
    kind = schema.get("type")
    if kind is not None and not _TYPES[kind](value):
        return [f"{where}: {value!r:.40} is not {kind}"]
    if "enum" in schema and value not in schema["enum"]:
        problems.append(f"{where}: {value!r} not in {schema['enum']}")
    if "const" in schema and value != schema["const"]:
        problems.append(f"{where}: {value!r} is not {schema['const']!r}")
    if "oneOf" in schema:
        matches = [alt for alt in schema["oneOf"] if not check_schema(alt, value, where)]
        if len(matches) != 1:
            problems.append(f"{where}: {value!r} matches {len(matches)} of oneOf")
    if isinstance(value, int | float) and value is not None and not isinstance(value, bool):
        if "minimum" in schema and value < schema["minimum"]:
            problems.append(f"{where}: {value} < {schema['minimum']}")
        if "maximum" in schema and value > schema["maximum"]:
            problems.append(f"{where}: {value} > {schema['maximum']}")
    if isinstance(value, dict):
        props = schema.get("properties", {})
        for key in schema.get("required", []):
            if key not in value:
                problems.append(f"{where}: missing {key!r}")
        for key, item in value.items():
            if key in props:
                problems += check_schema(props[key], item, f"{where}.{key}")
            elif schema.get("additionalProperties") is False:
                problems.append(f"{where}: unexpected {key!r}")
    if isinstance(value, list):
        if "minItems" in schema and len(value) < schema["minItems"]:
            problems.append(f"{where}: fewer than {schema['minItems']} items")
        if "maxItems" in schema and len(value) > schema["maxItems"]:
            problems.append(f"{where}: more than {schema['maxItems']} items")
        if "items" in schema:
            for i, item in enumerate(value):
                problems += check_schema(schema["items"], item, f"{where}[{i}]")
    return problems


def foxglove_problems(schema: Mapping[str, Any], where: str = "$") -> list[str]:
    """What Foxglove's JSON Schema reader (``parseJsonSchema`` of Foxglove Studio's
    ``mcap-support``) would refuse: it takes one type per property, one item type per
    array (no arrays of arrays), and ``oneOf`` only of numeric constants."""
    if schema.get("type") != "object":
        return [f"{where}: not an object"]
    problems = []
    for name, prop in schema.get("properties", {}).items():
        here = f"{where}.{name}"
        if "oneOf" in prop:
            if not all(isinstance(alt.get("const"), int) for alt in prop["oneOf"]):
                problems.append(f"{here}: oneOf of non-numbers")
            continue
        kind = prop.get("type")
        if kind == "object":
            problems += foxglove_problems(prop, here)
        elif kind == "array":
            item = prop.get("items", {})
            if item.get("type") == "object":
                problems += foxglove_problems(item, here + "[]")
            elif item.get("type") not in ("boolean", "string", "number", "integer"):
                problems.append(f"{here}: array of {item.get('type')!r}")
            elif item.get("contentEncoding") is not None:
                problems.append(f"{here}: array of encoded strings")
        elif kind not in ("boolean", "string", "number", "integer"):
            problems.append(f"{here}: type {kind!r}")
    return problems


def same(a: Any, b: Any) -> bool:
    """Equal, with NaN equal to NaN and the types of numbers compared (repr is exact)."""
    return repr(a) == repr(b) and _nan_free_equal(a, b)


def _nan_free_equal(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    if isinstance(a, tuple) and isinstance(b, tuple):
        return len(a) == len(b) and all(_nan_free_equal(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, Message) and type(a) is type(b):
        return all(_nan_free_equal(getattr(a, f), getattr(b, f)) for f in a.__dataclass_fields__)
    return bool(a == b)


@pytest.fixture
def schema_problems() -> SchemaCheck:
    """:func:`check_schema`: what is wrong with a value under a JSON Schema."""
    return check_schema


@pytest.fixture
def foxglove_refuses() -> Callable[[Mapping[str, Any]], list[str]]:
    """:func:`foxglove_problems`: what Foxglove's JSON Schema reader would refuse."""
    return foxglove_problems


@pytest.fixture
def same_value() -> Callable[[Any, Any], bool]:
    """:func:`same`: equal, NaN included, number types compared."""
    return same


@dataclass(frozen=True)
class RecordedRun:
    """A short run of the servo bus (42 emulated servos and a goal source), recorded."""

    path: Path
    published: list[tuple[str, Message]]
    link_bytes: list[tuple[str, str, float, bytes]]


@pytest.fixture(scope="module")
def recorded_run(tmp_path_factory: pytest.TempPathFactory) -> RecordedRun:
    """Record 0.5 s of the bus graph, writing between cycles as a recording run would."""
    path = tmp_path_factory.mktemp("record") / "bus.mcap"
    links: list[tuple[str, str, float, bytes]] = []
    recorder = Recorder(
        path,
        metadata={"robot": "WHexaR", "command": "pytest"},
        attachments={"wiring.toml": "[[actors]]\nname = 'bus'\n", "blob.bin": b"\x00\x01"},
    )

    def link(name: str, direction: str, t: float, data: bytes) -> None:
        links.append((name, direction, t, data))
        recorder.link_bytes(name, direction, t, data)

    async def drain(h: Harness) -> None:
        while True:
            recorder.write_pending()
            await h.sleep(0.02)

    result = run_actors(
        bus_graph("emulator", wiggle={}),
        duration=0.5,
        scenario=drain,
        observers=[recorder],
        link_observer=link,
    )
    recorder.transform(0.25, "world", "base", (0.0, 0.0, 0.1), (0.0, 0.0, 0.0, 1.0))
    recorder.close()
    assert result.exit_code == 0
    published = [(e.channel, e.message) for e in result.log.entries]
    return RecordedRun(path, published, links)
