"""Foot trajectories in a leg-local step frame: swing, stance and early touchdown.

The step frame is 2-D: ``s`` is the position along the direction of travel in metres,
centred on the neutral foot point, and ``h`` the height above the nominal ground in metres.
Stance moves the foot from the anterior extreme position (AEP, s = +L/2) back to the
posterior extreme position (PEP, s = −L/2); swing lifts it from the PEP forwards to the AEP
(Žák 2023, 3.2.1, Fig. 3.2).

Phase conventions. A swing or stance is parametrised by u ∈ [0, 1]. Within the whole gait
cycle, a leg's phase φ ∈ [0, 1] starts with the swing: swing for φ ∈ [0, 1 − β), stance for
φ ∈ [1 − β, 1], β being the duty factor, so φ = 0 (≡ 1) is lift-off at the PEP and φ = 1 − β
touchdown at the AEP. This matches :mod:`whexar.kinematics.gait`, whose phase offsets are
the phases at which each leg starts its swing.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Final, Literal, get_args

import numpy as np

from whexar._typing import ArrayLike, BoolArray, FloatArray
from whexar.errors import UsageError
from whexar.kinematics.cpg import OSCILLATORS, CpgOrbit, cpg_orbit
from whexar.kinematics.gait import PHASE_TOLERANCE
from whexar.runtime.checks import non_negative, positive, real

SwingShape = Literal["parabola", "half_sine"]
"""Analytic swing shapes (Diosdado 2014, 3.3–3.4)."""

SWING_SHAPES: Final[tuple[str, ...]] = get_args(SwingShape)
TRAJECTORIES: Final[tuple[str, ...]] = (*SWING_SHAPES, *OSCILLATORS)
"""Swing shapes a step may name: analytic (Diosdado 2014, 3.3–3.4) or a CPG orbit
(Grzelczyk et al., 8.4)."""

SwingOutcome = Literal["completed", "early_contact", "blocked", "no_contact"]
"""How a swing ended.

* ``"completed"`` — touchdown at the nominal end of the swing (u = 1);
* ``"early_contact"`` — contact while descending, before u = 1: the leg stops there and the
  body moves on (Diosdado 2014, 3.5, adaptive trajectory);
* ``"blocked"`` — contact while still ascending: an obstacle in the way, the case of the
  elevator reflex (Žák 2023, 4.2.2);
* ``"no_contact"`` — the swing ended with no contact because the ground is lower than
  expected: a hole, the case of the searching reflex (Žák 2023, 4.2.2).
"""

SwingStatus = Literal["swinging", "completed", "early_contact", "blocked", "no_contact"]
"""A :class:`SwingTracker`'s state: still ``"swinging"`` or one of :data:`SwingOutcome`."""

DEFAULT_CONTACT_TOLERANCE: Final = 1e-9
"""Foot height above the ground (m) that still counts as contact; absorbs rounding."""


def _unit_interval(name: str, value: ArrayLike) -> FloatArray:
    """Values in [0, 1]; out-of-range values are refused, never clipped."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise UsageError(f"{name} = {value!r}: expected real numbers in [0, 1]") from exc
    bad = ~np.isfinite(arr) | (arr < 0.0) | (arr > 1.0)
    if np.any(bad):
        raise UsageError(f"{name} contains {arr[bad].flat[0]!r}: allowed: finite values in [0, 1]")
    return arr


def _duty(value: object) -> float:
    number = real("duty_factor", value)
    if not 0.0 < number < 1.0:
        raise UsageError(f"duty_factor = {value!r}: must lie in (0, 1)")
    return number


def parabolic_swing(
    u: ArrayLike, step_length: float, step_height: float
) -> tuple[FloatArray, FloatArray]:
    """Parabolic swing (Diosdado 2014, 3.3–3.4, eq. 4–10): (s, h) at swing phases u.

    s runs linearly from −L/2 to +L/2; h = H − (a·s)²/4 with a = 2√(4H)/L, i.e.
    h = H·(1 − (2s/L)²), evaluated as 4H·u(1 − u), which is the same parabola and never
    rounds below zero.
    """
    uu = _unit_interval("u", u)
    length, height = (
        positive("step_length", step_length, "m"),
        non_negative("step_height", step_height, "m"),
    )
    s = length * (uu - 0.5)
    h = 4.0 * height * uu * (1.0 - uu)
    return s, h


def half_sine_swing(
    u: ArrayLike, step_length: float, step_height: float
) -> tuple[FloatArray, FloatArray]:
    """Half-sine swing, h = H·sin(πu), s linear from −L/2 to +L/2 (Diosdado 2014, 3.3–3.4).

    This is the sinusoidal trajectory the parabola replaced (Fig. 3.13).
    """
    uu = _unit_interval("u", u)
    length, height = (
        positive("step_length", step_length, "m"),
        non_negative("step_height", step_height, "m"),
    )
    s = length * (uu - 0.5)
    h = height * np.maximum(np.sin(np.pi * uu), 0.0)
    return s, h


def stance(u: ArrayLike, step_length: float) -> tuple[FloatArray, FloatArray]:
    """Stance: s from +L/2 to −L/2 linearly in u, h = 0 (Diosdado 2014, 3.4, Fig. 3.13)."""
    uu = _unit_interval("u", u)
    length = positive("step_length", step_length, "m")
    s = length * (0.5 - uu)
    return s, np.zeros_like(s)


def swing(
    u: ArrayLike, step_length: float, step_height: float, shape: SwingShape = "parabola"
) -> tuple[FloatArray, FloatArray]:
    """Swing of the named analytic ``shape``: ``"parabola"`` or ``"half_sine"``."""
    if shape == "parabola":
        return parabolic_swing(u, step_length, step_height)
    if shape == "half_sine":
        return half_sine_swing(u, step_length, step_height)
    raise UsageError(f"unknown swing shape {shape!r}; allowed: {', '.join(SWING_SHAPES)}")


@dataclass(frozen=True)
class FootTrajectory:
    """The foot point over a whole gait cycle: swing in [0, 1 − β), stance in [1 − β, 1].

    ``swing`` is ``"parabola"`` (Diosdado 2014, 3.4), ``"half_sine"`` (3.3) or a
    :class:`~whexar.kinematics.cpg.CpgOrbit`. With the analytic shapes the stance is flat
    (h = 0) and linear in s. With a CPG orbit the foot follows the orbit over the whole cycle,
    as in Grzelczyk et al., 8.4.3 and 8.5: the orbit's part from ``lift_off`` to
    ``touchdown`` fills the swing and the rest fills the stance, each re-timed to the gait's
    fractions, and s = X·L, h = Z·H. For the stick-slip orbit the stance is its stick phase,
    flat and at constant speed (8.5.1). For the Hopf, van der Pol and Rayleigh orbits the
    swing is the forward half (posterior to anterior extreme) and the foot height varies
    during stance too (the body-height fluctuation of 8.5.3).
    """

    step_length: float
    step_height: float
    duty_factor: float
    swing: SwingShape | CpgOrbit = "parabola"

    def __post_init__(self) -> None:
        positive("step_length", self.step_length, "m")
        non_negative("step_height", self.step_height, "m")
        _duty(self.duty_factor)
        if not isinstance(self.swing, CpgOrbit) and self.swing not in SWING_SHAPES:
            raise UsageError(
                f"unknown swing shape {self.swing!r}; allowed: "
                f"{', '.join(SWING_SHAPES)} or a CpgOrbit"
            )

    @property
    def swing_fraction(self) -> float:
        """Share of the cycle in swing, 1 − β."""
        return 1.0 - self.duty_factor

    def in_swing(self, phase: ArrayLike) -> BoolArray:
        """True where the leg phase lies in the swing part [0, 1 − β) (1 counts as 0).

        Boundaries use the tolerance of :meth:`whexar.kinematics.gait.Gait.in_swing`, so both
        agree on every phase the gait produces.
        """
        p = _unit_interval("phase", phase)
        return np.asarray(
            (p < self.swing_fraction - PHASE_TOLERANCE) | (p > 1.0 - PHASE_TOLERANCE),
            dtype=np.bool_,
        )

    def at(self, phase: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Foot point (s, h) in metres at leg phases ∈ [0, 1] (1 is the same point as 0)."""
        in_swing = self.in_swing(phase)
        p = _unit_interval("phase", phase)
        p = np.where(p > 1.0 - PHASE_TOLERANCE, 0.0, p)
        split = self.swing_fraction
        # Clipping only absorbs the boundary tolerance (≤ 1e-9 of a cycle).
        u_swing = np.where(in_swing, np.minimum(p / split, 1.0), 0.0)
        u_stance = np.where(in_swing, 0.0, np.clip((p - split) / self.duty_factor, 0.0, 1.0))
        if isinstance(self.swing, CpgOrbit):
            orbit = self.swing
            f = orbit.swing_fraction
            orbit_phase = np.where(
                in_swing, orbit.lift_off + f * u_swing, orbit.touchdown + (1.0 - f) * u_stance
            )
            return self.swing.scaled(self.step_length, self.step_height, orbit_phase)
        s_sw, h_sw = swing(u_swing, self.step_length, self.step_height, self.swing)
        s_st, h_st = stance(u_stance, self.step_length)
        return np.where(in_swing, s_sw, s_st), np.where(in_swing, h_sw, h_st)


def sample_swing(
    n: int, step_length: float, step_height: float, shape: SwingShape = "parabola"
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(u, s, h) at ``n`` ≥ 2 swing phases evenly spaced over [0, 1], ends included."""
    if isinstance(n, bool) or not isinstance(n, int) or n < 2:
        raise UsageError(f"n = {n!r}: must be an integer ≥ 2")
    u = np.linspace(0.0, 1.0, n)
    s, h = swing(u, step_length, step_height, shape)
    return u, s, h


@dataclass(frozen=True, eq=False)
class Touchdown:
    """Result of :func:`adapt_swing`: the swing as executed and how it ended.

    ``u``, ``s``, ``h`` are the nominal samples up to and including the contact sample (all
    of them when there is no contact). ``index`` is that sample's index in the nominal swing,
    ``contact_u`` its phase and ``contact_ground`` the terrain height there (m), where the
    foot comes to rest; all three are None for ``"no_contact"``.
    """

    outcome: SwingOutcome
    u: FloatArray
    s: FloatArray
    h: FloatArray
    index: int | None
    contact_u: float | None
    contact_ground: float | None

    @property
    def ended_early(self) -> bool:
        """True when contact stopped the swing before its nominal end."""
        return self.outcome in ("early_contact", "blocked")


def _ground_heights(
    ground: Callable[[FloatArray], ArrayLike] | ArrayLike, s: FloatArray
) -> FloatArray:
    values = ground(s) if callable(ground) else ground
    try:
        g = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise UsageError(f"ground = {values!r}: expected heights in m") from exc
    if g.ndim == 0 and callable(ground):
        g = np.full_like(s, float(g))
    if g.shape != s.shape:
        raise UsageError(
            f"ground has shape {g.shape}: expected {s.shape}, one height per swing sample"
        )
    if not np.all(np.isfinite(g)):
        raise UsageError(f"ground contains {g[~np.isfinite(g)][0]!r} m: heights must be finite")
    return g


def adapt_swing(
    u: ArrayLike,
    s: ArrayLike,
    h: ArrayLike,
    ground: Callable[[FloatArray], ArrayLike] | ArrayLike,
    *,
    tolerance: float = DEFAULT_CONTACT_TOLERANCE,
) -> Touchdown:
    """Cut a sampled nominal swing at its first ground contact (Diosdado 2014, 3.5).

    ``u``, ``s``, ``h`` are 1-D samples of the nominal swing (u non-decreasing in [0, 1],
    h ≥ 0 above the nominal ground h = 0); ``ground`` gives the terrain height at each s,
    either as a callable ``ground(s) -> heights`` (called once with the array of s) or as an
    array of the same length. The foot is in contact where h ≤ ground + ``tolerance``.

    The first sample is the lift-off and never counts as contact. The first contact after it
    decides the outcome: at the last sample it is ``"completed"``; before the apex (the first
    sample of greatest nominal height) the foot hits an obstacle on the way up,
    ``"blocked"``; from the apex on it is ``"early_contact"`` — the leg stops there and the
    body moves on (3.5). No contact at all means the ground lies below the nominal
    touchdown: ``"no_contact"`` (a hole).
    """
    uu = _unit_interval("u", u)
    ss = np.asarray(s, dtype=np.float64)
    hh = np.asarray(h, dtype=np.float64)
    if uu.ndim != 1 or uu.size < 2:
        raise UsageError(f"u has shape {uu.shape}: expected a 1-D array of at least 2 phases")
    if ss.shape != uu.shape or hh.shape != uu.shape:
        raise UsageError(f"s {ss.shape} and h {hh.shape} must have the shape of u {uu.shape}")
    for name, arr in (("s", ss), ("h", hh)):
        if not np.all(np.isfinite(arr)):
            raise UsageError(f"{name} contains {arr[~np.isfinite(arr)][0]!r}: must be finite")
    if np.any(np.diff(uu) < 0.0):
        raise UsageError("u must be non-decreasing: samples of one swing in order")
    if np.any(hh < 0.0):
        raise UsageError(f"h contains {hh[hh < 0.0][0]!r} m: nominal heights must be ≥ 0")
    tol = real("tolerance", tolerance)
    if tol < 0.0:
        raise UsageError(f"tolerance = {tolerance!r} m: must be ≥ 0")
    g = _ground_heights(ground, ss)

    contact = np.nonzero(hh[1:] <= g[1:] + tol)[0]
    if contact.size == 0:
        return Touchdown("no_contact", uu, ss, hh, None, None, None)
    i = int(contact[0]) + 1
    apex = int(np.argmax(hh))
    outcome: SwingOutcome
    if i == uu.size - 1:
        outcome = "completed"
    elif i < apex:
        outcome = "blocked"
    else:
        outcome = "early_contact"
    end = i + 1
    return Touchdown(outcome, uu[:end], ss[:end], hh[:end], i, float(uu[i]), float(g[i]))


class SwingTracker:
    """Follows one swing from foot-contact readings; pure: no clock, phase is an argument.

    Feed :meth:`step` the swing phase u (non-decreasing, in [0, 1]) and whether the foot
    sensor reports contact. Classification as in :func:`adapt_swing`: contact at u = 0 is
    the lift-off and ignored; contact before ``apex_u`` is ``"blocked"``; contact from
    ``apex_u`` on but before ``1 − completion_margin`` is ``"early_contact"``; contact after
    that is ``"completed"``; reaching u = 1 without contact is ``"no_contact"``. The first
    outcome latches until :meth:`reset`.
    """

    def __init__(self, apex_u: float = 0.5, completion_margin: float = 0.0) -> None:
        """``apex_u`` is the phase of the highest swing point: 0.5 for both analytic shapes."""
        apex = real("apex_u", apex_u)
        margin = real("completion_margin", completion_margin)
        if not 0.0 <= apex <= 1.0:
            raise UsageError(f"apex_u = {apex_u!r}: allowed: [0, 1]")
        if not 0.0 <= margin < 1.0:
            raise UsageError(f"completion_margin = {completion_margin!r}: allowed: [0, 1)")
        self.apex_u = apex
        self.completion_margin = margin
        self._u = 0.0
        self._status: SwingStatus = "swinging"
        self._contact_u: float | None = None

    @property
    def status(self) -> SwingStatus:
        """``"swinging"`` until the swing has ended, then its outcome."""
        return self._status

    @property
    def contact_u(self) -> float | None:
        """Phase of the contact that ended the swing, None otherwise."""
        return self._contact_u

    def reset(self) -> None:
        """Start a new swing."""
        self._u = 0.0
        self._status = "swinging"
        self._contact_u = None

    def step(self, u: float, contact: bool) -> SwingStatus:
        """Advance to swing phase ``u`` with the current contact reading; return the status."""
        phase = float(_unit_interval("u", real("u", u)))
        if self._status != "swinging":
            return self._status
        if phase < self._u:
            raise UsageError(f"u = {u!r} goes back from {self._u!r}: phases must not decrease")
        self._u = phase
        if contact and phase > 0.0:
            self._contact_u = phase
            if phase >= 1.0 - self.completion_margin:
                self._status = "completed"
            elif phase < self.apex_u:
                self._status = "blocked"
            else:
                self._status = "early_contact"
        elif phase >= 1.0:
            self._status = "no_contact"
        return self._status


# --------------------------------------------------------------------------- scalar fast paths
# A leg controller asks these every control cycle for one foot, where numpy's per-call cost
# would be most of the time: plain Python, built from the vectorised forms above.

SWING_SAMPLES: Final = 64
"""Samples of a swing table; linear interpolation between them is within 0.1 mm."""


def min_jerk(u: float) -> float:
    """Minimum-jerk blend 10u³ − 15u⁴ + 6u⁵ for u in [0, 1] (clamped): zero speed and
    acceleration at both ends (Flash and Hogan 1985)."""
    u = 0.0 if u < 0.0 else 1.0 if u > 1.0 else u
    return u * u * u * (10.0 + u * (-15.0 + 6.0 * u))


@dataclass(frozen=True, slots=True)
class SwingTable:
    """A swing's normalised shape: forward progress f(u) ∈ [0, 1] and height h(u) ∈ [0, 1]
    at the swing phase u, sampled (:func:`swing_table`)."""

    name: str
    u: tuple[float, ...]
    forward: tuple[float, ...]
    height: tuple[float, ...]
    apex_u: float

    def at(self, u: float) -> tuple[float, float]:
        """(f, h) at swing phase ``u`` by linear interpolation in the table."""
        n = len(self.u) - 1
        x = (0.0 if u < 0.0 else 1.0 if u > 1.0 else u) * n
        k = min(int(x), n - 1)
        w = x - k
        f, h = self.forward, self.height
        return f[k] + w * (f[k + 1] - f[k]), h[k] + w * (h[k + 1] - h[k])


_TABLES: dict[tuple[str, float], SwingTable] = {}


def swing_table(name: str, duty_factor: float) -> SwingTable:
    """The table of swing shape ``name`` — analytic (:data:`SWING_SHAPES`) or a CPG orbit
    (:data:`~whexar.kinematics.cpg.OSCILLATORS`) — for a gait of duty factor β (cached).

    Built from :class:`FootTrajectory` with unit step length and height over the swing part
    of the leg phase, [0, 1 − β), so the analytic shapes and the CPG orbits (re-timed to the
    gait) come from one place.
    """
    key = (name, round(duty_factor, 9))
    found = _TABLES.get(key)
    if found is not None:
        return found
    shape: SwingShape | CpgOrbit = cpg_orbit(name) if name in OSCILLATORS else name  # type: ignore[assignment]
    trajectory = FootTrajectory(1.0, 1.0, duty_factor, shape)
    u = np.linspace(0.0, 1.0, SWING_SAMPLES + 1)
    # The last sample is the touchdown itself: the leg phase 1 − β, where the stance begins.
    phase = np.minimum(u * trajectory.swing_fraction, trajectory.swing_fraction - 1e-7)
    s, h = trajectory.at(phase)
    forward = (s - s[0]) / (s[-1] - s[0]) if s[-1] != s[0] else u
    # Height above the straight line from lift-off to touchdown (a CPG orbit is not at 0
    # there), normalised so the apex is the commanded step height.
    lifted = np.maximum(h - (h[0] * (1 - u) + h[-1] * u), 0.0)
    height = lifted / (float(np.max(lifted)) or 1.0)
    height[0] = height[-1] = 0.0
    table = SwingTable(
        name,
        tuple(u.tolist()),
        tuple(forward.tolist()),
        tuple(height.tolist()),
        float(u[int(np.argmax(height))]),
    )
    _TABLES[key] = table
    return table


__all__ = [
    "DEFAULT_CONTACT_TOLERANCE",
    "SWING_SAMPLES",
    "SWING_SHAPES",
    "TRAJECTORIES",
    "FootTrajectory",
    "SwingOutcome",
    "SwingShape",
    "SwingStatus",
    "SwingTable",
    "SwingTracker",
    "Touchdown",
    "adapt_swing",
    "half_sine_swing",
    "min_jerk",
    "parabolic_swing",
    "sample_swing",
    "stance",
    "swing",
    "swing_table",
]
