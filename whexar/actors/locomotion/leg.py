"""The leg actor: one per leg, a thin shell around its :class:`LegController`.

Theory of operation
-------------------
The actor wakes on every :class:`ServoStates` (one per bus cycle), takes what
its other inputs hold — the coordinator's steps and newest body motion, the
force sensors — hands it all to its
:class:`~whexar.actors.locomotion.leg_controller.LegController` with the
clock's time, and publishes what the controller returns, in its order:
events on the events channel, :class:`SwingEnded` on ``swings``,
:class:`JointGoals` on ``goals``, :class:`LegState` on ``state``. The policy
— steps, swing, IK, wheel, contact, overrides — is the controller's, and is
told in its module.

Override goals are the exception to the rhythm: they are handed to the
controller as they arrive (:meth:`LegController.take_overrides`), and the goals
of the joints they take are sent at once, so that the bus writes them at its
next cycle — a reflex's answer reaches the wire one cycle after its stimulus,
not two (``whexar bench reflex``).
"""

from __future__ import annotations

from typing import ClassVar

import anyio
from pydantic import field_validator

from whexar.actors.locomotion.leg_controller import LegController
from whexar.actors.messages import (
    BodyMotion,
    JointGoals,
    LegLoads,
    LegState,
    ServoStates,
    StepCommand,
    SwingEnded,
)
from whexar.config import ConfigFile, ContactSource, RobotConfig, load_config
from whexar.robot import leg_index
from whexar.runtime.actor import Actor, ActorParams, Input, Output
from whexar.runtime.messages import Event


class LegActor(Actor):
    """Executes the coordinator's steps for one leg (:class:`LegController`)."""

    class Params(ActorParams):
        leg: str
        """The leg this actor drives: RF, LF, RM, LM, RR or LR (or 0…5)."""
        config: ConfigFile | None = None
        """Robot configuration file; absent: the built-in defaults."""
        contact: ContactSource | None = None
        """Overrides ``locomotion.contact`` (e.g. ``none`` on emulators without ground)."""

        @field_validator("leg")
        @classmethod
        def _known_leg(cls, value: str) -> str:
            leg_index(value)  # raises UsageError naming the allowed legs
            return value

    params: Params
    controller: ClassVar[type[LegController]] = LegController
    """The policy this actor runs (a subclass may add, e.g., a stopwatch)."""
    servo_state = Input(ServoStates)
    steps = Input(StepCommand, optional=True)
    motion = Input(BodyMotion, optional=True)
    loads = Input(LegLoads, optional=True)
    reflex = Input(JointGoals, optional=True)
    """Override goals (``JointGoals.reflex``): the interface reflexes act through."""
    goals = Output(JointGoals)
    state = Output(LegState, optional=True)
    swings = Output(SwingEnded, optional=True)
    """How each swing ended: the typed signal the elevator and searching reflexes take."""

    async def run(self) -> None:
        p = self.params
        cfg = load_config(p.config) if p.config else RobotConfig()
        leg = self.controller(
            cfg,
            leg_index(p.leg),
            name=self.name,
            contact=p.contact,
            report=self.state.connected,
        )
        reflex_in = self.reflex if self.reflex.connected else None
        self.ready()
        if reflex_in is None:
            await self._cycles(leg)
            return
        async with anyio.create_task_group() as tg:
            tg.start_soon(self._cycles, leg)
            # Overrides are taken as they come and their goals sent at once: the bus writes
            # them at its next cycle, not after the leg's next one (whexar bench reflex).
            now, goals_out = self.now, self.goals
            async for first in reflex_in:
                goals = leg.take_overrides(now(), [first, *reflex_in.drain()])
                if goals is not None:
                    await goals_out.send(goals)

    async def _cycles(self, leg: LegController) -> None:
        """One cycle per servo reading: the leg's goals, state, swing ends and events."""
        # Looked up once, not every cycle: a port attribute is a descriptor and a mapping
        # lookup. An optional input the wiring left unconnected is None here.
        now, emit = self.now, self.emit
        steps_in = self.steps if self.steps.connected else None
        motion_in = self.motion if self.motion.connected else None
        loads_in = self.loads if self.loads.connected else None
        goals_out = self.goals
        state_out = self.state if self.state.connected else None
        swings_out = self.swings if self.swings.connected else None
        async for states in self.servo_state:
            out = leg.cycle(
                now(),
                states,
                motion=motion_in.latest() if motion_in is not None else None,
                loads=loads_in.latest() if loads_in is not None else None,
                steps=steps_in.drain() if steps_in is not None else (),
            )
            for msg in out:
                if isinstance(msg, JointGoals):
                    await goals_out.send(msg)
                elif isinstance(msg, LegState):
                    if state_out is not None:
                        await state_out.send(msg)
                elif isinstance(msg, SwingEnded):
                    if swings_out is not None:
                        await swings_out.send(msg)
                elif isinstance(msg, Event):
                    emit(msg)
