"""The bus scheduler under test: the robot's emulated servos and a one-scheduler graph,
with the goal source :class:`~whexar.actors.bus.wiggle.GoalWiggle` that answers every
cycle."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from whexar.actors.bus.wiggle import GoalWiggle
from whexar.bus.emulator.chain import ServoChain
from whexar.config import RobotConfig
from whexar.runtime.harness import RunResult, Scenario, run_actors


def run_bus(
    graph: Mapping[str, Any],
    scenario: Scenario | None = None,
    duration: float | None = None,
) -> RunResult:
    """Run a :func:`bus_graph` on virtual time; the harness feeds ``goals`` unless a
    :class:`GoalWiggle` does."""
    wiggling = any(a["name"] == "wiggle" for a in graph["actors"])
    return run_actors(
        graph, duration=duration, scenario=scenario, feeds=[] if wiggling else ["goals"]
    )


def servo_chain(cfg: RobotConfig | None = None, **options: Any) -> ServoChain:
    """The emulated servos of ``cfg`` (default: the thesis robot) at its bus's baud rate.

    ``options`` go to :meth:`~whexar.bus.emulator.chain.ServoChain.for_models`
    (``timing``, ``fast_sync_read``, ``return_delay_us``, ``load_model``).
    """
    cfg = RobotConfig() if cfg is None else cfg
    return ServoChain.for_models(cfg.servos(), baudrate=cfg.bus.baudrate, **options)


BUS_CHANNELS: dict[str, dict[str, str]] = {
    "goals": {"message": "JointGoals", "policy": "queue"},
    "state": {"message": "ServoStates", "policy": "latest"},
    "health": {"message": "ServoHealth", "policy": "queue"},
    "stats": {"message": "BusStats", "policy": "latest"},
}
"""The scheduler's channels: goals queue up (latest per joint wins inside it), state is latest."""


def bus_graph(
    port: str,
    params: Mapping[str, Any] | None = None,
    *,
    wiggle: Mapping[str, Any] | None = None,
    outputs: Sequence[str] = ("state", "health", "stats"),
    max_restarts: int | None = None,
) -> dict[str, Any]:
    """A wiring document: a ``BusScheduler`` on ``port`` with ``params``.

    With ``wiggle`` (a :class:`GoalWiggle`'s params) a goal source answers
    every cycle; without, the ``goals`` channel is left for a harness to feed.
    ``outputs`` picks the scheduler's wired outputs (``state`` at least).
    """
    actors: list[dict[str, Any]] = [
        {
            "name": "bus",
            "class": "whexar.actors.bus:BusScheduler",
            "params": {"port": port, **(params or {})},
            "inputs": {"goals": "goals"},
            "outputs": {name: name for name in outputs},
        }
    ]
    if wiggle is not None:
        actors.append(
            {
                "name": "wiggle",
                "class": "whexar.actors.bus:GoalWiggle",
                "params": dict(wiggle),
                "inputs": {"state": "state"},
                "outputs": {"goals": "goals"},
            }
        )
    doc: dict[str, Any] = {
        "actors": actors,
        "channels": {name: BUS_CHANNELS[name] for name in ("goals", *outputs)},
    }
    if max_restarts is not None:
        doc["runtime"] = {"restart": {"max_restarts": max_restarts}}
    return doc


__all__ = ["BUS_CHANNELS", "GoalWiggle", "bus_graph", "run_bus", "servo_chain"]
