"""Gaits as phase tables: which leg swings when (Žák 2023, 3.2.1, Fig. 3.3, and 5.4).

A gait cycle has phase p ∈ [0, 1). Each leg starts its swing at its phase offset and swings
for the fraction 1 − β of the cycle (β: duty factor), then stands. A leg's own phase is
ψ = (p − offset) mod 1, with swing for ψ ∈ [0, 1 − β) and stance for ψ ∈ [1 − β, 1), the
convention of :class:`whexar.kinematics.trajectory.FootTrajectory`.

Offsets are thirds and sixths, which floats cannot hold exactly; comparisons are made with a
tolerance of 1e-9 cycles so that the swing intervals of a gait tile the cycle as intended
(a leg ending its swing and the next one starting at the "same" phase never overlap).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Final

import numpy as np

from whexar._typing import ArrayLike, BoolArray, FloatArray
from whexar.errors import UsageError
from whexar.robot import LEG_NAMES, N_LEGS, leg_index

PHASE_TOLERANCE: Final = 1e-9
"""Cycles within which two phases count as equal."""

GAIT_RANKING: Final = ("wheels", "tripod", "tetrapod", "ripple", "wave")
"""Locomotion modes from flat to difficult terrain, least to most stable (Žák 2023, 5.4,
Gait Selector, Table 5.9). Riding on wheels (rank 0) has no phase table."""
AUTO_GAIT: Final = "auto"
"""The gait a command names to let the gait selector choose among the walking gaits
(:mod:`whexar.actors.reactive.selector`)."""


@dataclass(frozen=True)
class Gait:
    """A periodic gait: duty factor β, per-leg swing-start phases, leg groups, stability rank.

    ``offsets`` are in leg order RF, LF, RM, LM, RR, LR (:data:`whexar.robot.LEG_NAMES`);
    ``groups`` are the sets of legs that swing together (equal offsets); ``stability_rank``
    is the position in :data:`GAIT_RANKING`.
    """

    name: str
    duty_factor: float
    offsets: tuple[float, float, float, float, float, float]
    groups: tuple[tuple[str, ...], ...]
    stability_rank: int

    def __post_init__(self) -> None:
        beta = self.duty_factor
        if not (isinstance(beta, float | int) and math.isfinite(beta) and 0.0 < beta < 1.0):
            raise UsageError(f"duty_factor = {beta!r}: must lie in (0, 1)")
        if len(self.offsets) != N_LEGS:
            raise UsageError(f"offsets has {len(self.offsets)} values: expected one per leg, 6")
        for leg, value in zip(LEG_NAMES, self.offsets, strict=True):
            if not (math.isfinite(value) and 0.0 <= value < 1.0):
                raise UsageError(f"offset of {leg} = {value!r}: allowed: [0, 1)")
        named = [leg_index(leg) for group in self.groups for leg in group]
        if sorted(named) != list(range(N_LEGS)):
            raise UsageError(
                f"groups {self.groups!r} must name each of {', '.join(LEG_NAMES)} exactly once"
            )
        for group in self.groups:
            starts = {self.offsets[leg_index(leg)] for leg in group}
            if len(starts) != 1:
                raise UsageError(f"group {group!r} has offsets {sorted(starts)}: must be equal")

    @property
    def swing_fraction(self) -> float:
        """Share of the cycle each leg spends in swing, 1 − β."""
        return 1.0 - self.duty_factor

    def offset(self, leg: int | str) -> float:
        """Phase at which ``leg`` (index or name) starts its swing."""
        return self.offsets[leg_index(leg)]

    def leg_phase(self, phase: ArrayLike) -> FloatArray:
        """Each leg's phase within its own cycle, shape (..., 6), values in [0, 1).

        ``phase`` is the gait-cycle phase (any finite real; it wraps, so p = t/T works).
        A leg phase of 0 is the start of its swing.
        """
        p = _phases(phase)
        psi = np.mod(p[..., np.newaxis] - np.asarray(self.offsets), 1.0)
        # A phase a rounding error short of 1 is the next cycle's start.
        return np.where(psi > 1.0 - PHASE_TOLERANCE, 0.0, psi)

    def in_swing(self, phase: ArrayLike) -> BoolArray:
        """True for the legs in swing, shape (..., 6): leg phase in [0, 1 − β)."""
        return np.asarray(
            self.leg_phase(phase) < self.swing_fraction - PHASE_TOLERANCE, dtype=np.bool_
        )

    def support_set(self, phase: ArrayLike) -> BoolArray:
        """True for the legs on the ground (in stance), shape (..., 6)."""
        return ~self.in_swing(phase)

    def swing_legs(self, phase: float) -> tuple[str, ...]:
        """Names of the legs in swing at one cycle phase."""
        mask = self.in_swing(phase)
        return tuple(name for name, on in zip(LEG_NAMES, mask.tolist(), strict=True) if on)

    def support_legs(self, phase: float) -> tuple[str, ...]:
        """Names of the legs on the ground at one cycle phase."""
        mask = self.support_set(phase)
        return tuple(name for name, on in zip(LEG_NAMES, mask.tolist(), strict=True) if on)

    def event_phases(self) -> FloatArray:
        """Sorted distinct phases in [0, 1) where some leg lifts off or touches down."""
        starts = np.asarray(self.offsets)
        ends = np.mod(starts + self.swing_fraction, 1.0)
        events = np.sort(np.concatenate([starts, ends]))
        keep = np.concatenate([[True], np.diff(events) > PHASE_TOLERANCE])
        events = events[keep]
        if events.size > 1 and events[-1] > 1.0 - PHASE_TOLERANCE:
            events = events[:-1]
        return np.asarray(events, dtype=np.float64)

    def _states(self) -> BoolArray:
        # Swing sets are constant between events: probe each event and each midpoint.
        events = self.event_phases()
        following = np.append(events[1:], events[0] + 1.0)
        probes = np.concatenate([events, 0.5 * (events + following)])
        return self.in_swing(probes)

    def min_support_legs(self) -> int:
        """Fewest legs on the ground at any phase of the cycle."""
        return int(N_LEGS - self._states().sum(axis=-1).max())

    def max_swing_legs(self) -> int:
        """Most legs in swing at once over the cycle."""
        return int(self._states().sum(axis=-1).max())


def _phases(phase: ArrayLike) -> FloatArray:
    try:
        p = np.asarray(phase, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise UsageError(f"phase = {phase!r}: expected real numbers (cycles)") from exc
    if not np.all(np.isfinite(p)):
        raise UsageError(f"phase contains {p[~np.isfinite(p)].flat[0]!r}: must be finite")
    return p


def _table(by_leg: Mapping[str, float]) -> tuple[float, float, float, float, float, float]:
    rf, lf, rm, lm, rr, lr = (by_leg[leg] for leg in LEG_NAMES)
    return rf, lf, rm, lm, rr, lr


def _singletons() -> tuple[tuple[str, ...], ...]:
    return tuple((leg,) for leg in LEG_NAMES)


TRIPOD: Final = Gait(
    # Žák 2023, 3.2.1: front and rear legs of one side with the middle leg of the other swing
    # together, the two groups alternate; at least three legs on the ground.
    name="tripod",
    duty_factor=1.0 / 2.0,
    offsets=_table({"RF": 0.0, "LM": 0.0, "RR": 0.0, "LF": 0.5, "RM": 0.5, "LR": 0.5}),
    groups=(("RF", "LM", "RR"), ("LF", "RM", "LR")),
    stability_rank=GAIT_RANKING.index("tripod"),
)

TETRAPOD: Final = Gait(
    # Žák 2023, 3.2.1 and 5.4: two legs swing at a time, at least four stand; three pairs
    # in a back-to-front wave on each side.
    name="tetrapod",
    duty_factor=2.0 / 3.0,
    offsets=_table({"RR": 0.0, "LM": 0.0, "RM": 1 / 3, "LF": 1 / 3, "RF": 2 / 3, "LR": 2 / 3}),
    groups=(("RR", "LM"), ("RM", "LF"), ("RF", "LR")),
    stability_rank=GAIT_RANKING.index("tetrapod"),
)

RIPPLE: Final = Gait(
    # Žák 2023, 5.4: "The second leg starts its swing phase when the first leg is in the
    # middle of its swing phase": starts 1/6 apart with a swing of 1/3, at most two legs in
    # swing; back-to-front on each side, the sides half a cycle apart.
    name="ripple",
    duty_factor=2.0 / 3.0,
    offsets=_table({"RR": 0.0, "RM": 1 / 3, "RF": 2 / 3, "LR": 1 / 2, "LM": 5 / 6, "LF": 1 / 6}),
    groups=_singletons(),
    stability_rank=GAIT_RANKING.index("ripple"),
)

WAVE: Final = Gait(
    # Žák 2023, 3.2.1 and 5.4: one leg swings at a time, back to front on the right side,
    # then on the left.
    name="wave",
    duty_factor=5.0 / 6.0,
    offsets=_table({"RR": 0.0, "RM": 1 / 6, "RF": 2 / 6, "LR": 3 / 6, "LM": 4 / 6, "LF": 5 / 6}),
    groups=_singletons(),
    stability_rank=GAIT_RANKING.index("wave"),
)

GAITS: Final[Mapping[str, Gait]] = MappingProxyType(
    {g.name: g for g in (TRIPOD, TETRAPOD, RIPPLE, WAVE)}
)
"""The four walking gaits of Žák 2023, 3.2.1 (Fig. 3.3), by name."""


def gait(name: str) -> Gait:
    """The gait called ``name`` (case-insensitive): tripod, tetrapod, ripple or wave."""
    key = name.strip().lower() if isinstance(name, str) else name
    if isinstance(key, str) and key in GAITS:
        return GAITS[key]
    allowed = ", ".join(GAITS)
    if key == "wheels":
        raise UsageError(f"'wheels' is riding, not a gait with a phase table; allowed: {allowed}")
    raise UsageError(f"unknown gait {name!r}; allowed: {allowed}")


def stability_rank(name: str) -> int:
    """Position of a locomotion mode in :data:`GAIT_RANKING` (0 = wheels, 4 = wave)."""
    key = name.strip().lower() if isinstance(name, str) else name
    if isinstance(key, str) and key in GAIT_RANKING:
        return GAIT_RANKING.index(key)
    raise UsageError(f"unknown locomotion mode {name!r}; allowed: {', '.join(GAIT_RANKING)}")


__all__ = [
    "AUTO_GAIT",
    "GAITS",
    "GAIT_RANKING",
    "PHASE_TOLERANCE",
    "RIPPLE",
    "TETRAPOD",
    "TRIPOD",
    "WAVE",
    "Gait",
    "gait",
    "stability_rank",
]
