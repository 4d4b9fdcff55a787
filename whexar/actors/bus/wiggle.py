"""A goal source for the bus on its own: every joint swayed, every cycle.

:class:`GoalWiggle` listens to :class:`~whexar.actors.messages.ServoStates`
and answers each cycle with goals for every joint: a slow sine around a
centre angle (positions) and a constant speed (wheels). Every goal changes
every cycle, so the scheduler writes all 42 goals each time — the load of
the bus benchmark's plans ("all goals"), the demo graph
``config/graphs/bus.toml`` and a live check that goals reach the servos.
"""

from __future__ import annotations

import math

from pydantic import Field

from whexar.actors.messages import JointGoal, JointGoals, ServoStates
from whexar.robot import JOINT_NAMES, N_LEGS
from whexar.runtime.actor import Actor, ActorParams, Input, Output

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
