"""The locomotion stack on the servo emulator, for tests and benchmarks.

:func:`walk_graph` wires a bus scheduler on an emulated chain, the six leg
actors and the coordinator; the ``commands`` channel is left for a scenario
to feed (:func:`run_walk` plays timed :class:`MotionCommand` values into it),
and optionally a ``reflex`` channel into every leg.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from whexar.actors.messages import MotionCommand
from whexar.robot import LEG_NAMES
from whexar.testing.harness import Harness, RunResult, run_actors

WALK_CHANNELS: dict[str, dict[str, Any]] = {
    "goals": {"message": "JointGoals", "policy": "queue"},
    "servo-state": {"message": "ServoStates", "policy": "latest"},
    "steps": {"message": "StepCommand", "policy": "queue"},
    "motion": {"message": "BodyMotion", "policy": "latest"},
    "legs": {"message": "LegState", "policy": "queue"},
    "locomotion": {"message": "LocomotionState", "policy": "latest"},
    "commands": {"message": "MotionCommand", "policy": "queue"},
    "reflex": {"message": "JointGoals", "policy": "queue"},
}


def walk_graph(
    port: str = "emulator",
    *,
    config: str | None = None,
    bus_params: Mapping[str, Any] | None = None,
    leg_params: Mapping[str, Any] | None = None,
    reflex: bool = False,
    stop_timeout_s: float = 3.0,
) -> dict[str, Any]:
    """A wiring document: bus on ``port``, six legs, the coordinator; ``commands`` fed."""
    cfg = {"config": config} if config else {}
    actors: list[dict[str, Any]] = [
        {
            "name": "bus",
            "class": "whexar.actors.bus:BusScheduler",
            "params": {"port": port, **cfg, **(bus_params or {})},
            "inputs": {"goals": "goals"},
            "outputs": {"state": "servo-state"},
        }
    ]
    for leg in LEG_NAMES:
        inputs = {"servo_state": "servo-state", "steps": "steps", "motion": "motion"}
        if reflex:
            inputs["reflex"] = "reflex"
        actors.append(
            {
                "name": f"leg-{leg}",
                "class": "whexar.actors.leg:LegActor",
                "params": {"leg": leg, "contact": "none", **cfg, **(leg_params or {})},
                "inputs": inputs,
                "outputs": {"goals": "goals", "state": "legs"},
            }
        )
    actors.append(
        {
            "name": "coordinator",
            "class": "whexar.actors.coordinator:Coordinator",
            "params": dict(cfg),
            "inputs": {"servo_state": "servo-state", "commands": "commands", "legs": "legs"},
            "outputs": {"steps": "steps", "motion": "motion", "state": "locomotion"},
        }
    )
    names = [n for n in WALK_CHANNELS if reflex or n != "reflex"]
    return {
        "runtime": {"stop_timeout_s": stop_timeout_s, "ready_timeout_s": 10.0},
        "actors": actors,
        "channels": {n: WALK_CHANNELS[n] for n in names},
    }


def run_walk(
    commands: Sequence[tuple[float, MotionCommand]] = (),
    *,
    duration: float,
    graph: Mapping[str, Any] | None = None,
) -> RunResult:
    """Run :func:`walk_graph` for ``duration`` s of virtual time, feeding ``commands``
    ((time, command) pairs, in order) into the ``commands`` channel."""
    doc = dict(graph) if graph is not None else walk_graph()
    feeds = ["commands"] + (["reflex"] if "reflex" in doc["channels"] else [])

    async def scenario(h: Harness) -> None:
        for t, cmd in commands:
            await h.sleep_until(t)
            await h.feed("commands", cmd)

    return run_actors(doc, duration=duration, scenario=scenario, feeds=feeds)


def command(**fields: Any) -> MotionCommand:
    """A :class:`MotionCommand` from the harness, at time 0 (the channel stamps nothing)."""
    return MotionCommand(t=0.0, source="harness", **fields)
