"""The terrain estimator's and the gait selector's actors: thin shells around
:class:`~whexar.actors.reactive.terrain.TerrainEstimator` and
:class:`~whexar.actors.reactive.selector.GaitSelector` (4.2.3, 4.2.4).

Theory of operation
-------------------
:class:`TerrainEstimatorActor` hands each message of its inputs to its core as it
arrives and publishes the core's estimate every ``terrain.tick_s``;
:class:`GaitSelectorActor` hands each estimate to its core and publishes its
choices (on ``choice``, the coordinator's ``gait_choice`` input) and its events.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import anyio

from whexar.actors.messages import (
    BodyTilt,
    GaitChoice,
    GaitSelected,
    ImuSample,
    LegState,
    LocomotionState,
    ObstacleRanges,
    SwingEnded,
    TerrainEstimate,
)
from whexar.actors.reactive.selector import GaitSelector
from whexar.actors.reactive.terrain import TerrainEstimator
from whexar.config import ConfigFile, RobotConfig, load_config
from whexar.runtime.actor import Actor, ActorParams, Input, Output
from whexar.runtime.channels import Inbox


class TerrainEstimatorActor(Actor):
    """Feeds a :class:`TerrainEstimator` and publishes its estimate every ``terrain.tick_s``
    (module docstring). Every input is optional: a metric whose readings are not wired
    stays 0.

    With the coordinator's state wired, an estimate is due at the first state at least
    ``tick_s`` after the last estimate, and published right after it: its place among the
    messages of one instant is then set by what caused it, not by which of two tickers
    with the same period the loop woke first (a recorder or a live view would change
    that order). Without it, a ticker."""

    class Params(ActorParams):
        config: ConfigFile | None = None
        """Robot configuration file; absent: the built-in defaults."""

    params: Params
    swings = Input(SwingEnded, optional=True)
    legs = Input(LegState, optional=True)
    tilt = Input(BodyTilt, optional=True)
    imu = Input(ImuSample, optional=True)
    ranges = Input(ObstacleRanges, optional=True)
    locomotion = Input(LocomotionState, optional=True)
    estimate = Output(TerrainEstimate)

    async def run(self) -> None:
        cfg = load_config(self.params.config) if self.params.config else RobotConfig()
        core = TerrainEstimator(cfg)
        tick_s = cfg.terrain.tick_s
        feeds: list[tuple[Inbox[Any], Callable[[Any], None]]] = [
            (self.swings, core.swing),
            (self.legs, core.leg),
            (self.tilt, core.tilt),
            (self.imu, core.imu),
            (self.ranges, core.ranges),
        ]
        self.ready()
        async with anyio.create_task_group() as tg:
            for inbox, take in feeds:
                if inbox.connected:
                    tg.start_soon(_feed, inbox, take)
            if not self.locomotion.connected:
                async for _ in self.ticker(tick_s):
                    await self.estimate.send(core.estimate(self.now(), self.name))
            due = -math.inf
            async for state in self.locomotion:
                core.locomotion(state)
                now = self.now()
                if now >= due:
                    due = now + tick_s
                    await self.estimate.send(core.estimate(now, self.name))


async def _feed(inbox: Inbox[Any], take: Callable[[Any], None]) -> None:
    async for msg in inbox:
        take(msg)


class GaitSelectorActor(Actor):
    """Runs a :class:`GaitSelector` on the terrain estimator's estimates (module docstring)."""

    class Params(ActorParams):
        config: ConfigFile | None = None
        """Robot configuration file; absent: the built-in defaults."""

    params: Params
    terrain = Input(TerrainEstimate)
    choice = Output(GaitChoice)

    async def run(self) -> None:
        cfg = load_config(self.params.config) if self.params.config else RobotConfig()
        core = GaitSelector(cfg.gait_selector, name=self.name)
        self.ready()
        async for est in self.terrain:
            for msg in core.take(est):
                if isinstance(msg, GaitChoice):
                    await self.choice.send(msg)
                else:
                    assert isinstance(msg, GaitSelected)
                    self.emit(msg)
