"""The gait selector: the fastest gait the terrain allows (Žák 2023, 4.2.4, 5.4, Table 5.9).

Theory of operation
-------------------
The thesis ranks the ways of moving from flat to difficult ground — wheels,
tripod, tetrapod, ripple, wave — and gives each limits of the terrain
estimator's metrics (Table 5.9, ``[gait_selector]``; the wheels' tilt raised to
20° in 6.7.5): "If the threshold value for at least one parameter is exceeded,
it will change to a more stable gait." :class:`GaitSelector` applies the table
and adds what the thesis lacks:

* **at once up, slowly down.** On each :class:`TerrainEstimate` the target is
  the least stable mode whose every limit holds (the most stable, wave, if none
  does). A more stable target is taken at once, whatever it skips: safety is
  never delayed. A less stable one is approached one rank at a time, and only
  once the terrain has stayed inside that rank's limits *less the hysteresis*
  (``tilt_hysteresis_deg``, ``step_hysteresis_mm``, ``count_hysteresis``) for
  ``calm_s``, and the present gait has been kept ``min_dwell_s``: a slope near
  a threshold or one bump too many does not make the gait flap;
* **pitch and roll apart** (4.2.3): a mode's ``max_roll_deg`` limits roll,
  ``max_tilt_deg`` pitch (and roll where no roll limit is given);
* **who wins is explicit**: the selector only chooses. Its
  :class:`GaitChoice` says the walking gait (``wheels`` says whether riding
  would do); the coordinator takes it while the operator's gait is ``auto``,
  and changes gait as it always does, safely: no new lift-offs, the swings
  land, the body stops, then the new gait starts.

Each change is also a :class:`GaitSelected` event naming the metric and the
threshold that decided it. No estimate with no tilt reading counts as level:
without an IMU the tilt limits do not apply. A plain class; its actor
(:class:`~whexar.actors.reactive.selection.GaitSelectorActor`) feeds it the
estimates and publishes its choices.
"""

from __future__ import annotations

import math

from whexar.actors.messages import GaitChoice, GaitSelected, TerrainEstimate
from whexar.config import GaitSelectorSpec, GaitThresholds
from whexar.kinematics.gait import GAIT_RANKING
from whexar.runtime.messages import Message


def exceeded(
    est: TerrainEstimate, limits: GaitThresholds, margin: GaitSelectorSpec | None = None
) -> str | None:
    """The first of ``limits`` the estimate ``est`` exceeds, in words, or ``None``;
    ``margin``: the limits drawn in by its hysteresis (for a return)."""
    tilt = margin.tilt_hysteresis_deg if margin else 0.0
    step = margin.step_hysteresis_mm if margin else 0.0
    count = margin.count_hysteresis if margin else 0
    step_mm = est.step_height_m * 1000.0
    if step_mm > max(limits.max_step_height_mm - step, 0.0):
        return f"a step of {step_mm:.0f} mm over {limits.max_step_height_mm:g} mm"
    if est.tilt_known:
        pitch, roll = math.degrees(est.pitch_rad), math.degrees(est.roll_rad)
        if abs(pitch) > limits.max_tilt_deg - tilt:
            return f"a pitch of {pitch:+.1f}° beyond ±{limits.max_tilt_deg:g}°"
        if abs(roll) > limits.roll_limit_deg - tilt:
            return f"a roll of {roll:+.1f}° beyond ±{limits.roll_limit_deg:g}°"
    counted = (
        ("obstacles", est.obstacles, limits.max_obstacles),
        ("bumps", est.bumps, limits.max_bumps),
        ("lost supports", est.lost_supports, limits.max_lost_supports),
    )
    for what, n, limit in counted:
        if limit is not None and n > max(limit - count, 0):
            return f"{n} {what} in {est.window_s:.1f} s, over {limit}"
    return None


class GaitSelector:
    """Chooses the mode from the terrain's metrics (module docstring); ``name`` is the
    ``source`` of what it says."""

    def __init__(self, spec: GaitSelectorSpec, *, name: str = "gait-selector") -> None:
        self.spec = spec
        self.name = name
        self.ranked = spec.ranked()
        self.rank: int | None = None
        """The present mode's index in :data:`GAIT_RANKING`; ``None`` before an estimate."""
        self.since = -math.inf
        """When the present mode was chosen."""
        self.calm_since: float | None = None
        """Since when the terrain has allowed the next less stable mode."""

    @property
    def mode(self) -> str | None:
        """The present mode (wheels, tripod … wave), ``None`` before an estimate."""
        return None if self.rank is None else GAIT_RANKING[self.rank]

    def take(self, est: TerrainEstimate) -> list[Message]:
        """One estimate: a :class:`GaitChoice` and a :class:`GaitSelected` when the mode
        changes (and the first choice), else nothing."""
        t = est.t
        target, why = len(self.ranked) - 1, "every mode's limits exceeded"
        for k, (_, limits) in enumerate(self.ranked):
            if exceeded(est, limits) is None:
                target = k
                break
        if self.rank is None:
            return self._choose(t, target, "the first estimate")
        rank = self.rank
        if target > rank:
            why = exceeded(est, self.ranked[rank][1]) or why
            return self._choose(t, target, why)
        if target == rank:
            self.calm_since = None
            return []
        lower = self.ranked[rank - 1][1]
        if exceeded(est, lower, self.spec) is not None:
            self.calm_since = None
            return []
        if self.calm_since is None:
            self.calm_since = t
        calm = t - self.calm_since
        if calm < self.spec.calm_s or t - self.since < self.spec.min_dwell_s:
            return []
        return self._choose(t, rank - 1, f"calm for {calm:.1f} s")

    def _choose(self, t: float, rank: int, why: str) -> list[Message]:
        before = self.mode or "none"
        self.rank = rank
        self.since = t
        self.calm_since = None
        mode = GAIT_RANKING[rank]
        gait = GAIT_RANKING[max(rank, 1)]  # riding would do: the least stable walking gait
        return [
            GaitChoice(t=t, source=self.name, gait=gait, wheels=rank == 0, reason=why),
            GaitSelected(t=t, source=self.name, before=before, after=mode, reason=why),
        ]
