"""The bus scheduler under test: the robot's emulated servos, a goal source that answers
every cycle, and its graph.

:class:`GoalWiggle` listens to :class:`~whexar.actors.messages.ServoStates`
and answers each cycle with goals for every joint: a slow sine around a
centre angle (positions) and a constant speed (wheels). Every goal changes
every cycle, so the scheduler writes all 42 goals each time — the load of
the benchmark plans ("all goals") and a live check that goals reach the
servos.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from pydantic import Field

from whexar.actors.messages import JointGoal, JointGoals, ServoStates
from whexar.bus.emulator.chain import ServoChain
from whexar.config import RobotConfig
from whexar.robot import JOINT_NAMES, N_LEGS
from whexar.runtime.actor import Actor, ActorParams, Input, Output
from whexar.runtime.harness import RunResult, Scenario, run_actors

_WHEEL = JOINT_NAMES.index("wheel")


class GoalWiggle(Actor):
    """Answers every :class:`ServoStates` with a goal for each of the 42 joints."""

    class Params(ActorParams):
        amplitude_rad: float = Field(0.2, ge=0)
        frequency_hz: float = Field(0.5, gt=0)
        center_rad: float = 0.0
        wheel_rad_s: float = 1.0
        stop_after_cycles: int | None = Field(None, gt=0)
        """Ask the runtime to stop after answering this many cycles."""

    params: Params
    state = Input(ServoStates)
    goals = Output(JointGoals)

    async def run(self) -> None:
        p = self.params
        self.ready()
        answered = 0
        w = 2 * math.pi * p.frequency_hz
        async for states in self.state:
            t = states.t
            # A dither larger than the sine's step per cycle makes every goal
            # differ from the last, so each cycle writes all of them.
            dither = 0.02 * (answered % 2)
            angle = p.center_rad + p.amplitude_rad * math.sin(w * t) + dither
            wheel = p.wheel_rad_s + 2 * dither
            goals = tuple(
                JointGoal(t=t, source=self.name, leg=leg, joint=j, velocity_rad_s=wheel)
                if j == _WHEEL
                else JointGoal(t=t, source=self.name, leg=leg, joint=j, position_rad=angle)
                for leg in range(N_LEGS)
                for j in range(len(JOINT_NAMES))
            )
            await self.goals.send(JointGoals(t=states.t, source=self.name, goals=goals))
            answered += 1
            if p.stop_after_cycles is not None and answered >= p.stop_after_cycles:
                self.request_stop(f"answered {answered} cycles")
                return


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
                "class": "whexar.testing.bus:GoalWiggle",
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
