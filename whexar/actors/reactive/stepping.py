"""The stepping reflex: a stance leg kept from where it should be steps back (4.2.2, 6.7.1).

Theory of operation
-------------------
In the thesis's test "one of the legs was prevented from reaching its goal
position", and the reflex "returns the leg to its original position" (6.7.1).
A leg's :class:`~whexar.actors.messages.LegState` says how far its foot is from
where the goals it sent put it (``foot_error_m``: the servos' tracking error at
the foot — a leg pushed, held or snagged). What a stance foot's error is
depends on the load the leg carries: 9 mm at the median walking the tripod
gait on the flat, 18 mm on 15°, more on steeper ground, and on 30° it swings
with the stride. So each leg learns its own: a running mean and variance of
its errors over ``learn_s`` of stance or standing (the readings beyond the
trigger left out). In stance, an error beyond that mean by ``error_m`` or by
``spread_k`` standard deviations, whichever is more, held for ``hold_s``,
makes the reflex ask the coordinator to step that leg again to its neutral
point (``restep_leg``): the body halts, the leg swings there, the walk goes on.
An error that falls by ``settle_m`` while held is the servos catching up after
a touchdown: the hold starts again. A leg is stepped again at most once per
``rest_s``; the reflex is active from its request until ``rest_s`` passes.

While active it holds back the searching and elevator reflexes (``inhibits``):
a leg pushed off its foothold loses its support and meets things on its way,
and the thesis had to disable "other reflexes" by hand to test this one.

Walking the tripod gait on the flat, a stance foot is 9 mm from its goal's
point at the median and 17 mm at most; on 15° 18 mm and 34 mm; a snagged coxa
keeps its foot 56 mm off (docs/reflexes.md).
"""

from __future__ import annotations

from collections.abc import Iterable

from pydantic import Field

from whexar.actors.messages import LegState
from whexar.actors.reactive.reflex import Command, Reflex, ReflexParams
from whexar.config import RobotConfig
from whexar.robot import LEG_NAMES, N_LEGS
from whexar.runtime.messages import Message

_LOADED = ("stance", "hold")
"""The phases a leg learns its usual error in: bearing the body, walking or standing (on
30° a leg stands with 25–32 mm before its first stride)."""


class SteppingParams(ReflexParams):
    """When a leg counts as kept from its goal (docs/reflexes.md, measured walks)."""

    error_m: float = Field(0.025, gt=0.0, le=0.2)
    """A stance foot this much further from its goal's point than the leg's usual is kept
    from it, m: the spread of a walk's errors (p99 − median) is 7 mm on the flat, 15 mm on
    15°."""
    learn_s: float = Field(3.0, gt=0.0, le=60.0)
    """The time constant of each leg's usual error, s of stance."""
    usual_m: float = Field(0.01, ge=0.0, le=0.1)
    """The usual error before a leg has learnt its own, m (the flat's median)."""
    hold_s: float = Field(0.2, gt=0.0, le=5.0)
    """… for this long: a servo's lag at a touchdown is not it, s."""
    rest_s: float = Field(2.0, gt=0.0, le=60.0)
    """A leg is stepped again at most once in this long, s."""
    spread_k: float = Field(4.0, ge=0.0, le=10.0)
    """… or this many of the leg's own standard deviations, where that is more than
    ``error_m``: on 30° a loaded rear leg's stance error spreads 9 mm about its 18 mm mean
    and reaches 46–54 mm every few strides (docs/reflexes.md, "stepping")."""
    settle_m: float = Field(0.005, gt=0.0, le=0.05)
    """An error that falls this much while held is the servos catching up after a
    touchdown, not a leg kept away: the hold starts again, m."""


class Stepping(Reflex):
    """Steps a stance leg that is kept from its goal back under the body (module docstring)."""

    inputs = ("legs",)
    priority = 30
    inhibits = ("reflex-searching", "reflex-elevator")
    tick_s = 0.1
    Params = SteppingParams
    params: SteppingParams

    def __init__(self, params: ReflexParams, *, name: str, cfg: RobotConfig) -> None:
        super().__init__(params, name=name, cfg=cfg)
        self.since: list[float | None] = [None] * N_LEGS
        """Per leg: since when its stance foot has been kept from its goal."""
        self.peak = [0.0] * N_LEGS
        """Per leg: the largest error since then, m."""
        self.until = [-1e9] * N_LEGS
        """Per leg: no new step before this time."""
        p = self.params
        self.usual = [p.usual_m] * N_LEGS
        """Per leg: its usual stance error, m."""
        self.var = [0.0] * N_LEGS
        """Per leg: the variance of its stance errors about the usual, m²."""
        self.last_t: list[float | None] = [None] * N_LEGS

    def limit(self, leg: int) -> float:
        """The stance error beyond which leg ``leg`` counts as kept from its goal, m."""
        p = self.params
        sd: float = self.var[leg] ** 0.5
        return self.usual[leg] + max(p.error_m, p.spread_k * sd)

    def react(self, t: float, msg: Message) -> Iterable[Command]:
        if not isinstance(msg, LegState):
            return ()
        i, p = msg.leg, self.params
        err = msg.foot_error_m
        last, self.last_t[i] = self.last_t[i], t
        if msg.phase not in _LOADED or err is None:
            self.since[i] = None
            return ()
        if err <= self.limit(i):
            self.since[i] = None
            if last is not None:  # learn from a leg that bears the body and is not kept
                k = min(1.0, max(t - last, 0.0) / p.learn_s)
                d = err - self.usual[i]
                self.usual[i] += d * k
                self.var[i] += (d * d - self.var[i]) * k
            return ()
        if msg.phase != "stance":
            self.since[i] = None  # a standing leg is not stepped: the walk's stance is
            return ()
        since = self.since[i]
        if since is None or err < self.peak[i] - p.settle_m:
            self.since[i] = since = t  # kept from now on, or falling back: the servos catch up
            self.peak[i] = err
        self.peak[i] = max(self.peak[i], err)
        if t - since < p.hold_s or t < self.until[i]:
            return ()
        self.since[i] = None
        self.until[i] = t + p.rest_s
        self.active = True
        self.reason = f"{LEG_NAMES[i]} kept {err * 1000:.0f} mm from its goal: stepped back"
        return (self.request(t, restep_leg=i, reason=self.reason),)

    def tick(self, t: float) -> Iterable[Command]:
        if self.active and all(t >= u for u in self.until):
            self.active = False
            self.reason = ""
        return ()
