"""The coordinator: a thin shell around the :class:`LocomotionPlanner` (Žák 2023, 4.2.5).

Theory of operation
-------------------
The actor wakes on every :class:`ServoStates`, like the legs, takes what
arrived on its other inputs — motion commands, the legs' states, the newest
body tilt, the reflexes' requests, the gait selector's choice — hands it to its
:class:`~whexar.actors.locomotion.planner.LocomotionPlanner`, and publishes
what the planner returns, in its order: events on the events channel,
:class:`StepCommand` s on ``steps``, :class:`BodyMotion` on ``motion``,
:class:`LocomotionState` on ``state``. The policy — gaits, riding, stances,
the flip, the scripts and their activities — is the planner's.

On stop and on a safe stop the robot sits down before the bus turns the
torque off, while servo states still arrive: a safe stop asks the planner
to begin the sit-down and waits while the loop cycles it; a stop (the loop
cancelled) drives the sit-down from here, one servo state at a time.
"""

from __future__ import annotations

from typing import ClassVar

import anyio

from whexar.actors.locomotion.core import SETTLE_S
from whexar.actors.locomotion.planner import SIT_MARGIN_S, LocomotionPlanner
from whexar.actors.messages import (
    BodyMotion,
    BodyTilt,
    GaitChoice,
    LegState,
    LocomotionState,
    MotionCommand,
    ReflexRequest,
    ServoStates,
    StepCommand,
)
from whexar.config import ConfigFile, RobotConfig, load_config
from whexar.runtime.actor import Actor, ActorParams, Input, Output
from whexar.runtime.messages import Event, Message


class Coordinator(Actor):
    """Synchronises the six legs (:class:`LocomotionPlanner`)."""

    class Params(ActorParams):
        config: ConfigFile | None = None
        """Robot configuration file; absent: the built-in defaults."""

    params: Params
    policy: ClassVar[type[LocomotionPlanner]] = LocomotionPlanner
    """The policy this actor runs (a subclass may add, e.g., a stopwatch)."""
    servo_state = Input(ServoStates)
    commands = Input(MotionCommand, optional=True)
    legs = Input(LegState, optional=True)
    tilt = Input(BodyTilt, optional=True)
    requests = Input(ReflexRequest, optional=True)
    """What the reflexes ask: a higher step, a halt, a heading correction, to sit down."""
    gait_choice = Input(GaitChoice, optional=True)
    """The gait selector's choice, taken while the operator's gait is ``auto``."""
    steps = Output(StepCommand)
    motion = Output(BodyMotion)
    state = Output(LocomotionState, optional=True)

    planner: LocomotionPlanner

    async def _say(self, out: list[Message]) -> None:
        for msg in out:
            if isinstance(msg, StepCommand):
                await self.steps.send(msg)
            elif isinstance(msg, BodyMotion):
                await self.motion.send(msg)
            elif isinstance(msg, LocomotionState):
                if self._state_out is not None:
                    await self._state_out.send(msg)
            elif isinstance(msg, Event):
                self.emit(msg)

    async def run(self) -> None:
        p = self.params
        cfg = load_config(p.config) if p.config else RobotConfig()
        self._state_out = self.state if self.state.connected else None
        self.planner = planner = self.policy(
            cfg, name=self.name, report=self._state_out is not None
        )
        # An optional input the wiring left unconnected is None here.
        commands_in = self.commands if self.commands.connected else None
        legs_in = self.legs if self.legs.connected else None
        tilt_in = self.tilt if self.tilt.connected else None
        requests_in = self.requests if self.requests.connected else None
        choice_in = self.gait_choice if self.gait_choice.connected else None
        self.ready()
        try:
            async for states in self.servo_state:
                await self._say(
                    planner.cycle(
                        states,
                        commands=commands_in.drain() if commands_in is not None else (),
                        legs=legs_in.drain() if legs_in is not None else (),
                        tilt=tilt_in.latest() if tilt_in is not None else None,
                        tilt_wired=tilt_in is not None,
                        requests=requests_in.drain() if requests_in is not None else (),
                        gait_choice=choice_in.latest() if choice_in is not None else None,
                    )
                )
        finally:
            with self.shielded():
                await self._sit_before_stop()

    async def safe_stop(self, reason: str) -> None:
        """Sit down while the bus can still carry it out; the bus then parks the servos.

        :meth:`run` is still cycling here: it drives the sit-down, this waits for it.
        """
        planner = getattr(self, "planner", None)
        if planner is None or not planner.begin_sit(self.clock.now()):
            return
        with anyio.move_on_after(planner.loco.sit_down_s + SIT_MARGIN_S):
            while planner.script is not None:
                await self.clock.sleep(SETTLE_S)

    async def _sit_before_stop(self) -> None:
        """On cancellation :meth:`run` no longer cycles: drive the sit-down from here."""
        planner = self.planner
        if not planner.begin_sit(self.clock.now()):
            return
        deadline = self.clock.now() + planner.loco.sit_down_s + SIT_MARGIN_S
        legs_in = self.legs if self.legs.connected else None
        while planner.script is not None and self.clock.now() < deadline:
            states = await self.servo_state.receive()
            legs = legs_in.drain() if legs_in is not None else ()
            await self._say(planner.stop_cycle(states, legs))
