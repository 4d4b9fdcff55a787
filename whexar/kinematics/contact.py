"""One contact estimate per leg: the force sensor, the femur current and the step's phase.

Theory of operation
-------------------
A foot's contact can be read two ways on WHexaR — the force sensor under the
tarsus (FSR, 5.3.3) and the femur servo's current (6.7.3, eq. 5.19) — and is
expected a third way, from the leg's own step: a foot in stance should carry
load, one in mid-swing should not. None is reliable alone: the FSR arrives in
frames of the sensor board (20 Hz) and lags the foot by about a tenth of a
second; the femur current is quick but weak (the thesis found it "fluctuates",
6.7.3); the phase is only what the leg *meant* to do, and a foot in a hole or
on a rock does otherwise. :class:`ContactEstimator` fuses them.

*The estimate.* ``contact`` is the force sensor's reading while its frames are
fresh and it behaves; else, while the femur current's readings are fresh and
it behaves, the fused estimate below (the current alone reads load when a
front leg lifts: it bends the phase's expectation only when it is decisive),
or the current's own reading where the configuration prefers it; else none
(the leg then senses no contact and its swings run their course).
``confidence`` is the probability that ``contact`` is right given every source
at once (Bayes over independent sensors): the phase gives the prior, each
usable sensor multiplies the odds by its likelihood ratio, a sensor that reads
contact by ``hit`` / ``false_alarm``, one that reads none by (1 − ``hit``) /
(1 − ``false_alarm``). A force sensor that says "no load" while the current
and the stance both say "load" is reported as it reads, with a low confidence:
a consumer (the searching reflex) can wait for it to firm up.

*The current's threshold.* One threshold on |femur current| (the thesis's,
6.7.3) does not suit every leg: walking the tripod gait in the simulated
world, the front femurs draw about −0.5 A in stance and up to +0.7 A lifting
the leg in swing, the middle ones −1.24 A in stance. "The threshold was set
according to the initial load on that leg" (6.7.3): here each leg learns its
own, while its force sensor is trusted — the mean signed current of its
stances (and stands) with the FSR in contact and of its swings with the FSR
free, each a running mean over ``learn_cycles`` — and reads load on the
stance's side of their midpoint, once they lie ``separation_a`` apart. Until
then, and for a leg whose currents do not separate, |current| > ``current_a``.
So when a force sensor fails, the current that replaces it was calibrated by
it.

*Health.* At each change of phase the estimator looks back over the stance or
swing just ended. A force sensor that read no load through ``fault_steps``
stances in which the femur current read load for at least ``loaded_share`` of
the stance (a broken wire, a dead sensor) — a stance where neither reads load
is a foot in a hole or a leg the others unload, not a sensor fault — or that
read load through ``fault_steps`` swings in a row (stuck), is set aside; it is
taken back once it reads load in a stance and releases in the next swing. The
current is set aside while its readings are stale (a bus timeout, a servo
lost) or after a stance in which it jumped by more than ``noisy_step_a`` per
cycle on average (a walking leg's current moves by 0.03–0.24 A a cycle). Each
change of a sensor's standing is a :class:`HealthChange` the leg turns into an
event. Plain class, no clock: the time is an argument.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Final, Literal

Sensor = Literal["fsr", "current"]
Source = Literal["fsr", "current", "none"]
Preference = Literal["auto", "fsr", "current", "none"]

_GROUND: Final = frozenset({"stance", "hold", "ride"})
"""Phases whose foot should carry load (the health checks judge walking stances only)."""
_AIR: Final = frozenset({"swing"})
"""Phases whose foot should not (a lifted move or a flip is not judged)."""
_MIN_LEARNT: Final = 50
"""Readings of stance and of swing before a learnt threshold is used (half a second)."""
_MIN_MOVES: Final = 10
"""A stance shorter than this many current readings says nothing of the current's noise."""


MIN_SIN: Final = 0.05
"""eq. 5.19 divides by sin α: below this (a joint within 3° of straight) it says nothing."""
PLANE_MIN_FEET: Final = 3
"""Feet that make a ground plane: three, not in a line."""
PLANE_SPREAD_M: Final = 0.05
"""Feet closer than this to one line (their RMS distance from it) make a line, not a plane:
a plane fitted through them would tilt at will across it. Three feet of one side stand
2–3 cm off a line; a tripod's or any two sides' feet 0.2–0.3 m."""


def depth_below_plane(
    feet: Sequence[tuple[float, float, float]], foot: tuple[float, float, float]
) -> float | None:
    """How far ``foot`` stands below the plane through ``feet`` (z = a + b·x + c·y, least
    squares), m, all in one frame; ``None`` with fewer than :data:`PLANE_MIN_FEET` feet or
    feet in a line. The ground the other feet stand on, wherever the body is tilted."""
    n = len(feet)
    if n < PLANE_MIN_FEET:
        return None
    mx = sum(f[0] for f in feet) / n
    my = sum(f[1] for f in feet) / n
    mz = sum(f[2] for f in feet) / n
    sxx = sum((f[0] - mx) ** 2 for f in feet)
    syy = sum((f[1] - my) ** 2 for f in feet)
    sxy = sum((f[0] - mx) * (f[1] - my) for f in feet)
    sxz = sum((f[0] - mx) * (f[2] - mz) for f in feet)
    syz = sum((f[1] - my) * (f[2] - mz) for f in feet)
    det = sxx * syy - sxy * sxy
    # The smaller eigenvalue of the centred second moments: the spread across the best line.
    across = (sxx + syy) / 2 - math.hypot((sxx - syy) / 2, sxy)
    if across / n < PLANE_SPREAD_M**2:
        return None
    b = (sxz * syy - syz * sxy) / det
    c = (syz * sxx - sxz * sxy) / det
    return mz + b * (foot[0] - mx) + c * (foot[1] - my) - foot[2]


def segment_load(amps: float | None, length: float, next_angle: float | None) -> float | None:
    """Žák 2023, eq. 5.19: the load indicator F = I / (L · sin α) of a leg segment of
    ``length`` m whose servo draws ``amps``, α the next joint's angle (A/m); ``None``
    where a reading is missing or the next joint is nearly straight."""
    if amps is None or next_angle is None:
        return None
    sin = math.sin(next_angle)
    return None if abs(sin) < MIN_SIN else amps / (length * sin)


class StanceLoss:
    """A support lost in stance, per leg: a foot that had contact in its present stance
    and has had none for ``hold_s``, its estimate believing the loss at least
    ``confidence`` — said once per stance (the searching reflex's case, and the terrain
    estimator's "disappeared support", 4.2.3)."""

    __slots__ = ("confidence", "free_since", "hold_s", "supported")

    def __init__(self, legs: int, hold_s: float, confidence: float) -> None:
        self.hold_s = hold_s
        self.confidence = confidence
        self.supported = [False] * legs
        self.free_since: list[float | None] = [None] * legs

    def lost(self, t: float, leg: int, phase: str, contact: bool, confidence: float) -> bool:
        """One leg's state at ``t``: whether its support is lost now. A stance foot that
        reaches down for the ground it lost (phase ``search`` after a supported stance:
        the leg held the loss ``hold_s`` itself) has lost it now."""
        if phase == "search" and self.supported[leg] and confidence >= self.confidence:
            self.supported[leg] = False
            self.free_since[leg] = None
            return True
        if phase != "stance" or contact:
            self.supported[leg] = contact and phase == "stance"
            self.free_since[leg] = None
            return False
        if not self.supported[leg] or confidence < self.confidence:
            return False
        since = self.free_since[leg]
        if since is None:
            self.free_since[leg] = t
            return False
        if t - since < self.hold_s:
            return False
        self.supported[leg] = False  # once per stance
        self.free_since[leg] = None
        return True


@dataclass(frozen=True, slots=True)
class SensorModel:
    """How one contact sensor behaves: the probability it reads contact when the foot
    carries load (``hit``) and when it does not (``false_alarm``)."""

    hit: float
    false_alarm: float

    def __post_init__(self) -> None:
        if not (0.0 < self.false_alarm < self.hit < 1.0):
            raise ValueError(
                f"hit = {self.hit!r}, false_alarm = {self.false_alarm!r}: expected "
                "0 < false_alarm < hit < 1 (a sensor that tells contact from none)"
            )

    def ratio(self, reads: bool) -> float:
        """The likelihood ratio of one reading, P(reading | load) / P(reading | none)."""
        if reads:
            return self.hit / self.false_alarm
        return (1.0 - self.hit) / (1.0 - self.false_alarm)


@dataclass(frozen=True, slots=True)
class ContactModel:
    """Everything the estimator needs to know (the configuration's ``[contact]``)."""

    fsr: SensorModel
    current: SensorModel
    current_a: float
    """|femur current| above this reads as load (6.7.3)."""
    stance_prior: float
    """P(load) of a foot the leg holds on the ground."""
    swing_prior: float
    """P(load) of a foot in swing."""
    fsr_fresh_s: float
    """FSR frames older than this are stale."""
    current_fresh_s: float
    """A femur current read longer ago than this is stale."""
    fault_steps: int
    """A force sensor that contradicts this many stances (or swings) in a row is set aside."""
    noisy_step_a: float
    """A current that moves by more than this per cycle, on average over a stance, is noisy."""
    loaded_share: float
    """The share of a stance the current must read load for, to speak against the FSR."""
    learn_cycles: float
    """The time constant, in cycles, of the running means the current's threshold is
    learnt from (the FSR labelling stance and swing)."""
    separation_a: float
    """The stance and swing means must lie this far apart for the learnt threshold."""


@dataclass(frozen=True, slots=True)
class ContactEstimate:
    """One leg's contact in one cycle: the reading, how likely it is right, whose it is."""

    contact: bool
    confidence: float
    source: Source


@dataclass(frozen=True, slots=True)
class HealthChange:
    """A sensor was set aside (``usable`` False) or taken back, and why."""

    sensor: Sensor
    usable: bool
    reason: str


@dataclass(slots=True)
class _Segment:
    """What the sensors read during the present phase (a stance or a swing)."""

    kind: str = ""
    fsr_on: bool = False
    fsr_off: bool = False
    fsr_seen: bool = False
    readings: int = 0
    """Fresh femur currents read."""
    loaded: int = 0
    """… of which read load."""
    current_last: float | None = None
    moved_a: float = 0.0
    """Sum of the current's changes from cycle to cycle, A."""
    moves: int = 0


@dataclass(slots=True)
class _Standing:
    """One sensor's standing: usable, and the run of steps that speak against it."""

    usable: bool = True
    silent_stances: int = 0
    stuck_swings: int = 0
    good_stance: bool = False
    stale: bool = False
    noisy: bool = False


@dataclass(slots=True)
class ContactEstimator:
    """One leg's contact estimate (module docstring). ``preference``: ``auto`` (the best
    usable source), ``fsr`` or ``current`` (that one only), ``none`` (no sensing)."""

    model: ContactModel
    preference: Preference = "auto"
    fsr: _Standing = field(default_factory=_Standing)
    current: _Standing = field(default_factory=_Standing)
    segment: _Segment = field(default_factory=_Segment)
    changes: list[HealthChange] = field(default_factory=list)
    """What changed since :meth:`take_changes` was last called."""
    stance_a: float = 0.0
    """Running mean of the femur current in stance with the FSR in contact, A."""
    swing_a: float = 0.0
    """… and in swing with the FSR free."""
    learnt: tuple[int, int] = (0, 0)
    """How many readings of each went into the means (stance, swing)."""

    def reads_load(self, amps: float) -> bool:
        """Whether the femur current ``amps`` reads as load (module docstring)."""
        m = self.model
        n_stance, n_swing = self.learnt
        gap = self.stance_a - self.swing_a
        if min(n_stance, n_swing) >= _MIN_LEARNT and abs(gap) >= m.separation_a:
            return (amps - 0.5 * (self.stance_a + self.swing_a)) * gap > 0.0
        return abs(amps) > m.current_a

    def _learn(self, phase: str, fsr: bool, amps: float) -> None:
        """One reading labelled by a trusted FSR: into the stance's or the swing's mean."""
        k = 1.0 / self.model.learn_cycles
        n_stance, n_swing = self.learnt
        if phase in _GROUND and fsr:
            w = max(k, 1.0 / (n_stance + 1))  # a plain mean until the window is full
            self.stance_a += (amps - self.stance_a) * w
            self.learnt = (n_stance + 1, n_swing)
        elif phase == "swing" and not fsr:
            w = max(k, 1.0 / (n_swing + 1))
            self.swing_a += (amps - self.swing_a) * w
            self.learnt = (n_stance, n_swing + 1)

    def estimate(
        self,
        t: float,
        phase: str,
        *,
        fsr: bool | None,
        fsr_t: float,
        current_a: float | None,
        current_t: float,
    ) -> ContactEstimate:
        """This cycle's estimate at ``t``: ``phase`` is the leg's step (stance, swing, move,
        hold…), ``fsr`` the newest force-sensor flag (``None``: never read) received at
        ``fsr_t``, ``current_a`` the femur's newest current read at ``current_t``."""
        m = self.model
        fsr_fresh = fsr is not None and t - fsr_t <= m.fsr_fresh_s
        current_fresh = current_a is not None and t - current_t <= m.current_fresh_s
        loaded = current_a is not None and self.reads_load(current_a)
        if fsr_fresh and current_fresh and self.fsr.usable:
            assert fsr is not None
            assert current_a is not None
            self._learn(phase, fsr, current_a)
        self._follow(
            phase, fsr if fsr_fresh else None, current_a if current_fresh else None, loaded
        )
        self._stale(self.current, not current_fresh and current_a is not None, "current")
        fsr_ok = fsr_fresh and self.fsr.usable and self.preference in ("auto", "fsr")
        cur_ok = current_fresh and self.current.usable and self.preference in ("auto", "current")
        if not (fsr_ok or cur_ok):
            return ContactEstimate(False, 0.0, "none")
        prior = m.stance_prior if phase in _GROUND else m.swing_prior if phase in _AIR else 0.5
        odds = prior / (1.0 - prior)
        if fsr_ok:
            odds *= m.fsr.ratio(bool(fsr))
        if cur_ok:
            odds *= m.current.ratio(loaded)
        p_load = odds / (1.0 + odds) if math.isfinite(odds) else 1.0
        # The FSR is read as it reads, and so is the current a configuration chose; as a
        # fallback it is too weak to be (it reads load lifting a leg, 6.7.3): it bends the
        # phase's expectation only when it is decisive.
        chosen = self.preference == "current"
        contact = bool(fsr) if fsr_ok else loaded if chosen else p_load > 0.5
        return ContactEstimate(
            contact, p_load if contact else 1.0 - p_load, "fsr" if fsr_ok else "current"
        )

    def take_changes(self) -> list[HealthChange]:
        """The sensors' changes of standing since the last call, oldest first."""
        out, self.changes = self.changes, []
        return out

    # ----------------------------------------------------------------- health

    def _follow(self, phase: str, fsr: bool | None, amps: float | None, loaded: bool) -> None:
        kind = phase if phase in ("stance", "swing") else ""
        seg = self.segment
        if kind != seg.kind:
            self._judge(seg)
            seg = self.segment = _Segment(kind)
        if fsr is not None:
            seg.fsr_seen = True
            seg.fsr_on |= fsr
            seg.fsr_off |= not fsr
        if amps is not None:
            seg.readings += 1
            seg.loaded += loaded
            if seg.current_last is not None:
                seg.moved_a += abs(amps - seg.current_last)
                seg.moves += 1
            seg.current_last = amps

    def _judge(self, seg: _Segment) -> None:
        """The phase ``seg`` ended: what it says of the force sensor and the current."""
        f, n = self.fsr, self.model.fault_steps
        if seg.kind == "stance" and seg.moves >= _MIN_MOVES:
            step = seg.moved_a / seg.moves
            noisy = step > self.model.noisy_step_a
            if noisy != self.current.noisy:
                self.current.noisy = noisy
                why = f"it moved by {step:.2f} A a cycle through a stance"
                self._refresh(self.current, "current", why)
        if seg.kind == "stance" and seg.fsr_seen:
            if seg.fsr_on:
                f.silent_stances = 0
            elif seg.loaded >= self.model.loaded_share * seg.readings > 0 and self.current.usable:
                f.silent_stances += 1  # the current felt load, the force sensor none
            f.good_stance = seg.fsr_on
            if f.usable and f.silent_stances >= n:
                self._set(
                    f, "fsr", False, f"it read no load through {n} stances the current read load"
                )
        elif seg.kind == "swing" and seg.fsr_seen:
            f.stuck_swings = f.stuck_swings + 1 if not seg.fsr_off else 0
            if f.usable and f.stuck_swings >= n:
                self._set(f, "fsr", False, f"it read load through {n} swings in a row")
            elif not f.usable and f.good_stance and seg.fsr_off:
                f.silent_stances = f.stuck_swings = 0
                self._set(f, "fsr", True, "it read load in a stance and none in the next swing")
            f.good_stance = False

    def _stale(self, s: _Standing, stale: bool, name: Sensor) -> None:
        if stale != s.stale:
            s.stale = stale
            self._refresh(s, name, "its readings stopped (the bus did not read it)")

    def _refresh(self, s: _Standing, name: Sensor, why: str) -> None:
        """The current's standing follows its staleness and noise."""
        usable = not (s.stale or s.noisy)
        if usable != s.usable:
            self._set(s, name, usable, why if not usable else "its readings are sound again")

    def _set(self, s: _Standing, name: Sensor, usable: bool, reason: str) -> None:
        s.usable = usable
        self.changes.append(HealthChange(name, usable, reason))


__all__ = [
    "MIN_SIN",
    "PLANE_MIN_FEET",
    "PLANE_SPREAD_M",
    "ContactEstimate",
    "ContactEstimator",
    "ContactModel",
    "HealthChange",
    "Preference",
    "SensorModel",
    "Source",
    "StanceLoss",
    "depth_below_plane",
    "segment_load",
]
