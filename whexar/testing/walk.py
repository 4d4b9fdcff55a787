"""The locomotion stack on the servo emulator, for tests.

:func:`walk_graph` is the robot's one graph (``config/graphs/walk.toml``) with
its sensor readers left out: the bus scheduler on an emulated chain, the six
leg actors and the coordinator; the ``commands`` channel is left for a
scenario to feed (:func:`run_walk` plays timed :class:`MotionCommand` values
into it), and optionally a ``reflex`` channel into every leg.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Final

from whexar.actors.graph import robot_graph
from whexar.actors.messages import MotionCommand
from whexar.runtime.harness import Harness, RunResult, run_actors
from whexar.runtime.messages import Message

REFLEX_CHANNEL: Final = {"message": "JointGoals", "policy": "queue"}
"""The channel a test wires into every leg's ``reflex`` input and feeds."""


def walk_graph(
    port: str = "emulator",
    *,
    config: str | None = None,
    bus_params: Mapping[str, Any] | None = None,
    leg_params: Mapping[str, Any] | None = None,
    reflex: bool = False,
    tilt: bool = False,
    stop_timeout_s: float | None = None,
) -> dict[str, Any]:
    """The robot's graph (:func:`~whexar.actors.graph.robot_graph`) without its sensors: the
    bus on ``port``, six legs, the coordinator; ``commands`` fed.

    With no sensor board the legs sense no contact (``contact = "none"``, unless
    ``leg_params`` says otherwise) and the coordinator no tilt. ``reflex`` wires a ``reflex``
    channel into every leg and ``tilt`` a ``tilt`` channel (:class:`BodyTilt`) into the
    coordinator, both for a scenario to feed.
    """
    feeds = ["commands", "tilt"] if tilt else ["commands"]
    doc = robot_graph(
        bus=port,
        config=config,
        params={
            "bus": dict(bus_params or {}),
            "leg-*": {"contact": "none", **(leg_params or {})},
        },
        leave_out=("sensors", "imu"),
        feeds=feeds,
    )
    if reflex:
        for actor in doc["actors"]:
            if actor["name"].startswith("leg-"):
                actor["inputs"]["reflex"] = "reflex"
        doc["channels"]["reflex"] = dict(REFLEX_CHANNEL)
    if stop_timeout_s is not None:
        doc["runtime"]["stop_timeout_s"] = stop_timeout_s
    return doc


def run_walk(
    commands: Sequence[tuple[float, MotionCommand]] = (),
    *,
    duration: float,
    graph: Mapping[str, Any] | None = None,
    messages: Sequence[tuple[float, str, Message]] = (),
) -> RunResult:
    """Run :func:`walk_graph` for ``duration`` s of virtual time, feeding ``commands``
    ((time, command) pairs) into the ``commands`` channel and ``messages`` ((time,
    channel, message) triples) into theirs, all in time order."""
    doc = dict(graph) if graph is not None else walk_graph()
    feeds = ["commands"] + [n for n in ("reflex", "tilt") if n in doc["channels"]]
    timeline = sorted(
        [(t, "commands", cmd) for t, cmd in commands] + list(messages), key=lambda e: e[0]
    )

    async def scenario(h: Harness) -> None:
        for t, channel, msg in timeline:
            await h.sleep_until(t)
            await h.feed(channel, msg)

    return run_actors(doc, duration=duration, scenario=scenario, feeds=feeds)


def command(**fields: Any) -> MotionCommand:
    """A :class:`MotionCommand` from the harness, at time 0 (the channel stamps nothing)."""
    return MotionCommand(t=0.0, source="harness", **fields)
