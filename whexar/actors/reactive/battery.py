"""The battery reflex: warn when the Li-Po runs low, then sit down and shut down (5.3.1).

Theory of operation
-------------------
The thesis's 3S Li-Po is empty at 9.6–9.9 V, and the servos need 10 V; "the
control system will therefore monitor the current battery voltage and
interrupt the operation of the robot in time" (5.3.1). The servos report their
Present Input Voltage (0.1 V a unit) at the read plan's slow rate; the line
they share is one voltage, so the reflex takes the **median** of each servo's
latest reading younger than ``stale_s`` — one servo's bad reading moves
nothing. The voltage sags under each step's load; a level counts only once
it has held for ``hold_s`` (longer than a gait cycle, 1.6 s), so a sag does not
fire it.

States, along one table (:data:`TRANSITIONS`)::

    nominal ──(median < warn_v for hold_s)──▶ low        BatteryLow "warning"
    low ──(median ≥ warn_v + recover_v for hold_s)──▶ nominal   BatteryRestored
    nominal | low ──(median < sit_v for hold_s)──▶ empty  BatteryLow "empty":
                                                          sit down and stay seated
    empty ──(the coordinator says seated)──▶ shut down    the run stops (torque off)

An empty battery never counts as restored: a Li-Po's voltage rises when its load
falls, and the robot sitting down would read as a recharge.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Iterable
from enum import StrEnum
from typing import Final, Self

from pydantic import Field, model_validator

from whexar.actors.messages import BatteryLow, BatteryRestored, LocomotionState, ServoHealth
from whexar.actors.reactive.reflex import Command, Reflex, ReflexParams, Shutdown
from whexar.config import RobotConfig
from whexar.runtime.messages import Message


class BatteryParams(ReflexParams):
    """The battery reflex's levels (5.3.1; the Li-Po's curve: AMPOW, "LiPo voltage
    chart", the resting voltage of a cell against its charge)."""

    warn_v: float = Field(10.8, ge=9.0, le=13.0)
    """Below it: the warning. 3.6 V a cell, the knee of the discharge curve: 5 % left."""
    sit_v: float = Field(10.2, ge=9.0, le=13.0)
    """Below it: sit down. 0.2 V above the servos' 10 V minimum (5.3.1; e-manual:
    10–14.8 V), for the sag of the sit-down itself."""
    recover_v: float = Field(0.2, ge=0.0, le=2.0)
    """A low battery counts as restored only this far above ``warn_v`` (hysteresis)."""
    hold_s: float = Field(2.0, gt=0.0, le=60.0)
    """How long a level must hold before it counts: longer than a gait cycle's sags."""
    stale_s: float = Field(5.0, gt=0.0, le=60.0)
    """A servo's reading older than this is not counted (the default plan reads each
    servo's voltage every 1.2 s)."""
    shutdown: bool = True
    """Once seated on an empty battery, stop the run (the servos' torque goes off)."""

    @model_validator(mode="after")
    def _ordered(self) -> Self:
        if not self.sit_v < self.warn_v:
            raise ValueError(f"sit_v ({self.sit_v} V) must be below warn_v ({self.warn_v} V)")
        return self


class Stage(StrEnum):
    NOMINAL = "nominal"
    LOW = "low"
    EMPTY = "empty"
    SHUT_DOWN = "shut down"


TRANSITIONS: Final[dict[Stage, frozenset[Stage]]] = {
    Stage.NOMINAL: frozenset({Stage.LOW, Stage.EMPTY}),
    Stage.LOW: frozenset({Stage.NOMINAL, Stage.EMPTY}),
    Stage.EMPTY: frozenset({Stage.SHUT_DOWN}),
    Stage.SHUT_DOWN: frozenset(),
}


class Battery(Reflex):
    """Warns on a low battery, sits the robot down on an empty one (module docstring)."""

    inputs = ("health", "locomotion")
    priority = 100
    """Above every other reflex: nothing outranks an empty battery."""
    Params = BatteryParams
    params: BatteryParams

    def __init__(self, params: ReflexParams, *, name: str, cfg: RobotConfig) -> None:
        super().__init__(params, name=name, cfg=cfg)
        self.stage = Stage.NOMINAL
        self.readings: dict[int, tuple[float, float]] = {}
        """servo ID → (time, volts) of its latest reading."""
        self.since: dict[str, float] = {}
        """condition → when it began to hold without a break."""

    def voltage(self, t: float) -> float | None:
        """The line's voltage: the median of the servos' fresh readings (None: none)."""
        fresh = [v for at, v in self.readings.values() if t - at <= self.params.stale_s]
        return statistics.median(fresh) if fresh else None

    def _held(self, name: str, now_true: bool, t: float) -> bool:
        """``now_true`` has held for ``hold_s`` without a break."""
        if not now_true:
            self.since.pop(name, None)
            return False
        start = self.since.setdefault(name, t)
        return t - start >= self.params.hold_s

    def _go(self, stage: Stage) -> None:
        if stage not in TRANSITIONS[self.stage]:
            raise ValueError(f"battery: no transition {self.stage} → {stage}")
        self.stage = stage

    def react(self, t: float, msg: Message) -> Iterable[Command]:
        if isinstance(msg, LocomotionState):
            return self._seated(t, msg)
        if not isinstance(msg, ServoHealth) or msg.voltage_v is None:
            return ()
        if not math.isfinite(msg.voltage_v):
            return ()
        self.readings[msg.servo_id] = (t, msg.voltage_v)
        v = self.voltage(t)
        if v is None or self.stage in (Stage.EMPTY, Stage.SHUT_DOWN):
            return ()
        p = self.params
        empty = self._held("empty", v < p.sit_v, t)
        low = self._held("low", v < p.warn_v, t)
        restored = self._held("restored", v >= p.warn_v + p.recover_v, t)
        why = f"battery at {v:.1f} V"
        if empty:
            self._go(Stage.EMPTY)
            self.active, self.reason = True, f"{why}, below {p.sit_v:g} V: sitting down"
            return (
                self._event(t, "empty", v, p.sit_v),
                self.request(t, sit_down=True, reason=why),
            )
        if low and self.stage == Stage.NOMINAL:
            self._go(Stage.LOW)
            return (self._event(t, "warning", v, p.warn_v),)
        if restored and self.stage == Stage.LOW:
            self._go(Stage.NOMINAL)
            return (BatteryRestored(t=t, source=self.name, voltage_v=v),)
        return ()

    def _seated(self, t: float, state: LocomotionState) -> Iterable[Command]:
        if self.stage != Stage.EMPTY or state.activity != "seated" or not self.params.shutdown:
            return ()
        self._go(Stage.SHUT_DOWN)
        self.reason = "the battery is empty: the robot sat down and shuts down"
        return (Shutdown(self.reason),)

    def _event(self, t: float, stage: str, v: float, level: float) -> BatteryLow:
        return BatteryLow(t=t, source=self.name, stage=stage, voltage_v=v, threshold_v=level)
