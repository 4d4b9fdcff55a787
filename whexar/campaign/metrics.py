"""What a campaign keeps of each run: named metrics computed from a :class:`SimResult`.

Theory of operation
-------------------
A metric is a function of a finished run and a measuring :class:`Window`
(seconds of simulated time, from the campaign's ``measure`` keys) that returns
one plain value: a number, a bool, a string or ``None`` (not defined for this
run: a cost of transport when the robot did not move). Metrics register
themselves by name with :func:`metric`; :func:`registry` returns them all, the
generic ones of this module and those of the shipped campaigns'
modules (:data:`METRIC_MODULES`), imported on first use so that a worker
process has the same table as the parent.

Every metric is deterministic: it reads the run's samples and the compact
series of its messages (:class:`~whexar.sim.series.RunSeries`), both on
virtual time, never the wall clock. That is what lets a campaign give
the same rows, bit for bit, on local processes and on Ray.
"""

from __future__ import annotations

import importlib
import itertools
import math
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Final

from whexar.runtime.messages import ActorStopped, StopRequested
from whexar.sim.run import FALLEN_TILT_RAD, Quiet, energy_j, progress, travelled

if TYPE_CHECKING:
    from whexar.sim.run import Sample, SimResult

Value = float | int | bool | str | None
"""What a metric returns: one cell of the results table."""

G: Final = 9.81
"""Gravitational acceleration (m/s²) of the cost of transport, as in thesis 6.8.1."""
METRIC_MODULES: Final = (
    "whexar.campaign.experiments",
    "whexar.campaign.failures",
    "whexar.campaign.reflexes",
)
"""Modules whose metrics :func:`registry` imports: the shipped campaigns' own."""


@dataclass(frozen=True)
class Window:
    """The stretch of a run a metric measures: ``from_s`` to ``to_s`` s (``None``: the end)."""

    from_s: float = 0.0
    to_s: float | None = None

    def samples(self, result: SimResult) -> list[Sample]:
        """The run's samples inside the window (its ends included)."""
        end = math.inf if self.to_s is None else self.to_s
        return [s for s in result.samples if self.from_s - 1e-9 <= s.t <= end + 1e-9]

    def contains(self, t: float) -> bool:
        """Whether time ``t`` lies inside the window."""
        return self.from_s - 1e-9 <= t and (self.to_s is None or t <= self.to_s + 1e-9)


MetricFn = Callable[["SimResult", Window], Value]


@dataclass(frozen=True)
class Metric:
    """A named metric: its unit (``""`` for none), what it is, how it is computed."""

    name: str
    unit: str
    description: str
    fn: MetricFn


_REGISTRY: dict[str, Metric] = {}
_loaded = False


def metric(name: str, unit: str, description: str) -> Callable[[MetricFn], MetricFn]:
    """Register the decorated function as metric ``name``."""

    def register(fn: MetricFn) -> MetricFn:
        if name in _REGISTRY and _REGISTRY[name].fn is not fn:
            raise ValueError(f"metric {name!r} is registered twice")
        _REGISTRY[name] = Metric(name, unit, description, fn)
        return fn

    return register


def registry() -> dict[str, Metric]:
    """Every metric, by name: this module's and those of :data:`METRIC_MODULES`."""
    global _loaded
    if not _loaded:
        for module in METRIC_MODULES:
            importlib.import_module(module)
        _loaded = True
    return dict(sorted(_REGISTRY.items()))


def compute(names: Sequence[str], result: SimResult, window: Window) -> dict[str, Value]:
    """The metrics ``names`` of one run, in that order."""
    table = registry()
    return {name: table[name].fn(result, window) for name in names}


# --------------------------------------------------------------------------- the generic ones


def _summary(key: str) -> MetricFn:
    def fn(result: SimResult, window: Window) -> Value:
        value = result.summary()[key]
        return value if value is None or isinstance(value, int | float | str) else str(value)

    return fn


for _key, _unit, _text in (
    ("progress_m", "m", "net progress: the body's displacement from the run's start to its end"),
    (
        "progress_along_m",
        "m",
        "net progress along the course (the heading at the start), start to end of the run",
    ),
    ("distance_m", "m", "length of the body's path over the whole run, sway included"),
    ("mean_speed_mps", "m/s", "net progress (progress_m) over the time spent walking or riding"),
    ("energy_j", "J", "electric energy of the whole run"),
    ("cost_of_transport", "", "E / (m g d) over the whole run, d the net progress"),
    ("min_stability_margin_m", "m", "least static stability margin while on the legs"),
    ("gait_changes", "", "gait changes the coordinator made"),
    ("gait_selections", "", "gaits the gait selector chose (its first estimate included)"),
    ("falls", "", "times the body tilted past 60°"),
):
    metric(_key, _unit, _text)(_summary(_key))


@metric("window_s", "s", "length of the measuring window")
def window_s(result: SimResult, window: Window) -> Value:
    s = window.samples(result)
    return s[-1].t - s[0].t if len(s) > 1 else 0.0


@metric("speed_mps", "m/s", "net progress over the window, over its duration")
def speed_mps(result: SimResult, window: Window) -> Value:
    return progress_speed(window.samples(result))


@metric("path_speed_mps", "m/s", "path length over the window (sway included), over its duration")
def path_speed_mps(result: SimResult, window: Window) -> Value:
    return path_speed(window.samples(result))


def progress_speed(samples: Sequence[Sample]) -> float | None:
    """Net progress over the samples' time span (m/s); ``None`` for no span."""
    if len(samples) < 2 or samples[-1].t <= samples[0].t:
        return None
    return progress(samples) / (samples[-1].t - samples[0].t)


def path_speed(samples: Sequence[Sample]) -> float | None:
    """Path length over the samples' time span (m/s); ``None`` for no span."""
    if len(samples) < 2 or samples[-1].t <= samples[0].t:
        return None
    return travelled(samples) / (samples[-1].t - samples[0].t)


def mean_power(samples: Sequence[Sample]) -> float | None:
    """Mean electric power over the samples' time span (W); ``None`` for no span."""
    if len(samples) < 2 or samples[-1].t <= samples[0].t:
        return None
    return energy_j(samples) / (samples[-1].t - samples[0].t)


def mean_supply(samples: Sequence[Sample]) -> tuple[float, float] | None:
    """The supply's mean current (A) and mean power (W) over the samples' time span, each
    sample's current being its mean since the one before; ``None`` for no span."""
    if len(samples) < 2 or samples[-1].t <= samples[0].t:
        return None
    charge = energy = 0.0
    for a, b in itertools.pairwise(samples):
        dt = b.t - a.t
        charge += b.supply_a * dt
        energy += b.supply_a * 0.5 * (a.supply_v + b.supply_v) * dt
    span = samples[-1].t - samples[0].t
    return charge / span, energy / span


@metric(
    "supply_current_a",
    "A",
    "mean current drawn from the supply over the window: Σ duty × winding current of the "
    "servos, their standby currents and the electronics (thesis 6.8, the ACS712 on the "
    "12 V line)",
)
def supply_current_a(result: SimResult, window: Window) -> Value:
    found = mean_supply(window.samples(result))
    return None if found is None else found[0]


@metric("supply_power_w", "W", "mean power drawn from the supply over the window (eq. 6.5)")
def supply_power_w(result: SimResult, window: Window) -> Value:
    found = mean_supply(window.samples(result))
    return None if found is None else found[1]


@metric("displacement_m", "m", "straight-line distance from the window's start to its end")
def displacement_m(result: SimResult, window: Window) -> Value:
    s = window.samples(result)
    return math.hypot(s[-1].x - s[0].x, s[-1].y - s[0].y) if s else None


@metric(
    "mean_power_w",
    "W",
    "mean Σ V·|winding current| over the servos in the window (supply_power_w: the supply's)",
)
def mean_power_w(result: SimResult, window: Window) -> Value:
    return mean_power(window.samples(result))


@metric(
    "mean_current_a",
    "A",
    "total servo current, thesis eq. 6.1–6.3: each servo's mean |Present Current| over the "
    "window, summed over the servos the bus reads (the default read plan reads the coxa, "
    "femur, tibia and tarsus: 24 servos; winding_current_a has all 42)",
)
def mean_current_a(result: SimResult, window: Window) -> Value:
    currents = servo_currents(result, window)
    return sum(currents.values()) if currents else None


def servo_currents(result: SimResult, window: Window, joint: int | None = None) -> dict[int, float]:
    """Each servo's current over the window, thesis eq. 6.1: the mean |Present Current| the
    bus read, by servo ID; ``joint`` keeps one joint of every leg (0 coxa … 6 wheel)."""
    sums: dict[int, float] = {}
    counts: dict[int, int] = {}
    inside = [k for k, t in enumerate(result.series.cycle_t) if window.contains(t)]
    for sid, (j, amps) in result.series.servo_amps().items():
        if joint is not None and j != joint:
            continue
        for k in inside:
            if not math.isnan(a := amps[k]):
                sums[sid] = sums.get(sid, 0.0) + a
                counts[sid] = counts.get(sid, 0) + 1
    return {k: sums[k] / counts[k] for k in sums}


@metric("window_cost_of_transport", "", "P / (m g v) over the window (thesis eq. 6.4)")
def window_cost_of_transport(result: SimResult, window: Window) -> Value:
    power, speed = mean_power_w(result, window), speed_mps(result, window)
    if not isinstance(power, float) or not isinstance(speed, float) or speed < 0.01:
        return None
    return power / (result.mass_kg * G * speed)


@metric("max_tilt_deg", "°", "largest |roll| or |pitch| of the body over the window")
def max_tilt_deg(result: SimResult, window: Window) -> Value:
    s = window.samples(result)
    return max(math.degrees(x.tilt) for x in s) if s else None


@metric("fell", "", "whether the body tilted past 60° inside the window")
def fell(result: SimResult, window: Window) -> Value:
    return any(x.tilt > FALLEN_TILT_RAD for x in window.samples(result))


def _final(attr: str) -> MetricFn:
    def fn(result: SimResult, window: Window) -> Value:
        s = window.samples(result)
        return float(getattr(s[-1], attr)) if s else None

    return fn


for _attr, _what in (("x", "x"), ("y", "y"), ("z", "height")):
    metric(f"final_{_attr}_m", "m", f"body centre {_what} at the window's end")(_final(_attr))


@metric("final_activity", "", "what the coordinator was doing at the window's end")
def final_activity(result: SimResult, window: Window) -> Value:
    states = [m for m in result.series.locomotion if window.contains(m.t)]
    return f"{states[-1].activity} {states[-1].mode}/{states[-1].gait}" if states else None


ROUTINE: Final = (*Quiet, ActorStopped, StopRequested)
"""Events every run has (start-up, the end): left out of :func:`events`."""


@metric("events", "", "the run's events other than routine ones, counted by type")
def events(result: SimResult, window: Window) -> Value:
    counts = Counter(
        type(e).__name__
        for e in result.events
        if window.contains(e.t) and not isinstance(e, ROUTINE)
    )
    return " ".join(f"{name}×{n}" for name, n in sorted(counts.items()))


__all__ = [
    "METRIC_MODULES",
    "Metric",
    "MetricFn",
    "Value",
    "Window",
    "compute",
    "mean_power",
    "mean_supply",
    "metric",
    "path_speed",
    "progress_speed",
    "registry",
    "servo_currents",
]
