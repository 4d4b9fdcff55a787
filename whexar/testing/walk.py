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
from whexar.runtime.messages import Message
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
    "tilt": {"message": "BodyTilt", "policy": "latest"},
    "loads": {"message": "LegLoads", "policy": "latest"},
    "ranges": {"message": "ObstacleRanges", "policy": "latest"},
}


def walk_graph(
    port: str = "emulator",
    *,
    config: str | None = None,
    bus_params: Mapping[str, Any] | None = None,
    leg_params: Mapping[str, Any] | None = None,
    reflex: bool = False,
    tilt: bool = False,
    sensors: str | None = None,
    imu: str | None = None,
    stop_timeout_s: float = 3.0,
) -> dict[str, Any]:
    """A wiring document: bus on ``port``, six legs, the coordinator; ``commands`` fed.

    ``reflex`` wires a ``reflex`` channel into every leg and ``tilt`` a ``tilt`` channel
    (:class:`BodyTilt`) into the coordinator, both for a scenario to feed. ``sensors``
    (a board port) adds the sensor reader, whose force sensors reach the legs (which then
    sense contact as ``locomotion.contact`` says; without a board they sense none), and
    ``imu`` (a fake I²C device) the IMU reader, whose tilt reaches the coordinator.
    """
    cfg = {"config": config} if config else {}
    tilt = tilt or imu is not None
    actors: list[dict[str, Any]] = [
        {
            "name": "bus",
            "class": "whexar.actors.bus:BusScheduler",
            "params": {"port": port, **cfg, **(bus_params or {})},
            "inputs": {"goals": "goals"},
            "outputs": {"state": "servo-state"},
        }
    ]
    if sensors is not None:
        actors.append(
            {
                "name": "sensors",
                "class": "whexar.actors.sensors:SensorReader",
                "params": {"port": sensors, **cfg},
                "outputs": {"loads": "loads", "ranges": "ranges"},
            }
        )
    if imu is not None:
        actors.append(
            {
                "name": "imu",
                "class": "whexar.actors.imu:ImuReader",
                "params": {"device": imu, **cfg},
                "outputs": {"tilt": "tilt"},
            }
        )
    contact = {} if sensors is not None else {"contact": "none"}
    for leg in LEG_NAMES:
        inputs = {"servo_state": "servo-state", "steps": "steps", "motion": "motion"}
        if sensors is not None:
            inputs["loads"] = "loads"
        if reflex:
            inputs["reflex"] = "reflex"
        actors.append(
            {
                "name": f"leg-{leg}",
                "class": "whexar.actors.leg:LegActor",
                "params": {"leg": leg, **contact, **cfg, **(leg_params or {})},
                "inputs": inputs,
                "outputs": {"goals": "goals", "state": "legs"},
            }
        )
    actors.append(
        {
            "name": "coordinator",
            "class": "whexar.actors.coordinator:Coordinator",
            "params": dict(cfg),
            "inputs": {
                "servo_state": "servo-state",
                "commands": "commands",
                "legs": "legs",
                **({"tilt": "tilt"} if tilt else {}),
            },
            "outputs": {"steps": "steps", "motion": "motion", "state": "locomotion"},
        }
    )
    wanted = {"reflex": reflex, "tilt": tilt, "loads": sensors, "ranges": sensors}
    names = [n for n in WALK_CHANNELS if wanted.get(n, True)]
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
