"""The terrain estimator: what the ground asks of the gait (Žák 2023, 4.2.3, 5.4, 6.7.5).

Theory of operation
-------------------
The thesis's terrain controller watches five things and hands them to the gait
selector. :class:`TerrainEstimator` keeps each as timed observations and
reports them over a sliding window of one gait cycle
(``gait_selector.lost_support_window_cycles`` × the coordinator's cycle
``T``, at least ``terrain.min_window_s``; ``terrain.still_window_s`` while no
gait runs), as one :class:`TerrainEstimate` every ``terrain.tick_s``:

* **step height** — the highest ground a swing met above where it expected it:
  a foot stopped early on it (``early_contact``) or a swing blocked on its way
  up (``blocked``: the elevator's case), each by its
  :class:`SwingEnded`'s ground offset; less than ``terrain.min_offset_mm`` is
  the flat. "If a leg does not hit any obstacle on the ground while lifted only
  to specific threshold, the terrain is considered flat" (4.2.3);
* **pitch and roll** — the body's tilt (the IMU's, eq. 5.6–5.7), averaged over
  the window, apart: "Different counters will be used for pitch and roll";
* **obstacles** — the rangefinders' approaches while the body moves: a reading
  nearer than ``terrain.obstacle_near_m`` after one beyond ``obstacle_clear_m``
  (seated, the rays pitched down meet the floor 0.23 m ahead);
* **bumps** — the IMU's jolts, readings further than ``terrain.bump_g`` from
  1 g, those closer than ``bump_gap_s`` counted once ("if the robot travels on
  wheels, the higher count of bumps means ... difficult terrain");
* **lost supports** — feet that found no ground where expected (a swing ending
  ``no_contact``) or lost it in stance (contact gone for ``contact.touchdown_s``
  in a stance that had it), each only if its contact estimate believes the loss
  at least ``terrain.lost_confidence`` (5.4: "based on the number of
  activations of the searching reflex").

A plain class: each reading goes in through its method with its time,
:meth:`TerrainEstimator.estimate` gives the window's metrics at a time. Its
actor (:class:`~whexar.actors.reactive.selection.TerrainEstimatorActor`) feeds
it and publishes its estimates.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable

from whexar.actors.messages import (
    BodyTilt,
    ImuSample,
    LegState,
    LocomotionState,
    ObstacleRanges,
    SwingEnded,
    TerrainEstimate,
)
from whexar.actors.reactive.reflex import WALKING
from whexar.config import RobotConfig
from whexar.kinematics.contact import StanceLoss
from whexar.robot import N_LEGS

_KEEP_S = 30.0
"""Observations are kept this long whatever the window: a slow wave cycle is 6 s."""
SETTLE_S = 0.05
"""An estimate at ``t`` takes the readings stamped up to ``t - SETTLE_S``: a reading of the
same instant may or may not have arrived (the order of tasks within one instant is no
contract), one stamped five control cycles earlier has, whatever else runs (a recorder,
a live view): equal runs give equal estimates."""


class TerrainEstimator:
    """The terrain's metrics over a sliding window (module docstring)."""

    def __init__(self, cfg: RobotConfig) -> None:
        self.spec = cfg.terrain
        self.cycles = cfg.gait_selector.lost_support_window_cycles
        self.cycle_s = 0.0
        """The gait's cycle, s; 0 while none runs."""
        self.steps: deque[tuple[float, float]] = deque()
        """(t, height m) of ground met above the expected."""
        self.tilts: deque[tuple[float, float, float]] = deque()
        """(t, pitch rad, roll rad)."""
        self.obstacles: deque[float] = deque()
        self.bumps: deque[float] = deque()
        self.lost: deque[float] = deque()
        self.last_bump = -math.inf
        self.armed = [True, True]
        self.still = False
        """The body goes nowhere (seated, standing up, standing): the rangefinders,
        pitched down (``ir.pitch_deg``), then meet the floor near the feet, and nothing
        comes near."""
        """Per rangefinder: the last reading was clear, so the next near one counts."""
        self.losses = StanceLoss(N_LEGS, cfg.contact.touchdown_s, self.spec.lost_confidence)

    def window_s(self) -> float:
        """The window the metrics are taken over, s."""
        s = self.spec
        if self.cycle_s <= 0.0:
            return s.still_window_s
        return max(s.min_window_s, self.cycles * self.cycle_s)

    # ----------------------------------------------------------------- readings

    def locomotion(self, msg: LocomotionState) -> None:
        """The coordinator's state: the gait cycle the window follows, and whether the
        body goes anywhere."""
        self.cycle_s = msg.cycle_s if msg.activity in WALKING else 0.0
        self.still = msg.activity not in ("walking", "riding", "hybrid")

    def swing(self, msg: SwingEnded) -> None:
        """A swing's end: ground met above the expected, or none where expected."""
        if msg.outcome in ("early_contact", "blocked"):
            if msg.ground_offset_m * 1000.0 >= self.spec.min_offset_mm:
                self.steps.append((msg.t, msg.ground_offset_m))
        elif msg.outcome == "no_contact" and msg.confidence >= self.spec.lost_confidence:
            self.lost.append(msg.t)

    def leg(self, msg: LegState) -> None:
        """A leg's state: a support lost in the middle of a stance."""
        if self.losses.lost(msg.t, msg.leg, msg.phase, msg.contact, msg.contact_confidence):
            self.lost.append(msg.t)

    def tilt(self, msg: BodyTilt) -> None:
        """The body's tilt (eq. 5.6–5.7)."""
        self.tilts.append((msg.t, msg.pitch_rad, msg.roll_rad))

    def imu(self, msg: ImuSample) -> None:
        """An IMU reading: a jolt, if it is far from 1 g."""
        ax, ay, az = msg.accel_g
        size = math.sqrt(ax * ax + ay * ay + az * az)
        if not (abs(size - 1.0) > self.spec.bump_g):  # a nan reading is no bump
            return
        if msg.t - self.last_bump >= self.spec.bump_gap_s:
            self.bumps.append(msg.t)
        self.last_bump = msg.t

    def ranges(self, msg: ObstacleRanges) -> None:
        """The rangefinders: an obstacle coming near."""
        s = self.spec
        for k, d in enumerate(msg.distances_m):
            if d is None:
                continue  # no reading: nothing known, nothing counted
            if d < s.obstacle_near_m:
                if self.armed[k] and not self.still:
                    self.obstacles.append(msg.t)
                    self.armed[k] = False
            elif d > s.obstacle_clear_m:
                self.armed[k] = True

    # ----------------------------------------------------------------- the estimate

    def estimate(self, t: float, source: str = "terrain") -> TerrainEstimate:
        """The metrics at ``t``: over the window ending :data:`SETTLE_S` before it."""
        self._forget(t - _KEEP_S)
        window = self.window_s()
        end = t - SETTLE_S
        start = end - window
        steps = [h for u, h in self.steps if start < u <= end]
        tilts = [(p, r) for u, p, r in self.tilts if start < u <= end]
        n = len(tilts)
        return TerrainEstimate(
            t=t,
            source=source,
            window_s=window,
            step_height_m=max(steps, default=0.0),
            pitch_rad=sum(p for p, _ in tilts) / n if n else 0.0,
            roll_rad=sum(r for _, r in tilts) / n if n else 0.0,
            obstacles=_within(self.obstacles, start, end),
            bumps=_within(self.bumps, start, end),
            lost_supports=_within(self.lost, start, end),
            tilt_known=n > 0,
        )

    def _forget(self, before: float) -> None:
        for q in (self.steps, self.tilts):
            while q and q[0][0] < before:
                q.popleft()
        for times in (self.obstacles, self.bumps, self.lost):
            while times and times[0] < before:
                times.popleft()


def _within(times: Iterable[float], start: float, end: float) -> int:
    return sum(1 for u in times if start < u <= end)
