"""Benchmarks behind ``whexar bench …``: speed targets are measured here, not in tests.

One module per suite (:mod:`~whexar.bench.kin`, :mod:`~whexar.bench.runtime`,
:mod:`~whexar.bench.bus`, :mod:`~whexar.bench.sensors`, :mod:`~whexar.bench.cycle`), each with a
``run(progress) -> Report``. These are the only modules besides the clock
that read the wall clock.

May import: :mod:`whexar.campaign` and everything below it; never the test helpers or the
command line.
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

Progress = Callable[[str], None] | None


def percentile(values: list[float], q: float) -> float:
    """The nearest-rank ``q`` quantile of ``values`` (0 < q ≤ 1): a value measured."""
    ordered = sorted(values)
    k = max(0, min(len(ordered) - 1, math.ceil(q * len(ordered)) - 1))
    return ordered[k]


def median_seconds(fn: Callable[[], object], repeats: int, *, warmup: int = 20) -> float:
    """Median wall time of one call of ``fn`` over ``repeats`` calls, in seconds."""
    for _ in range(warmup):
        fn()
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - start)
    return statistics.median(samples)


@dataclass(frozen=True)
class Figure:
    """One measured figure next to its target: an upper bound, or a lower one if ``at_least``."""

    key: str
    label: str
    value: float
    unit: str
    target: float
    at_least: bool = False

    @property
    def passed(self) -> bool:
        """True when the measured value meets the target."""
        return self.value >= self.target if self.at_least else self.value <= self.target


@dataclass(frozen=True)
class Report:
    """The figures of one benchmark suite."""

    suite: str
    items: list[Figure] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    """Lines printed under the table: context, comparisons, how the figures were taken."""
    data: dict[str, Any] | None = None
    """What ``--json`` prints when a suite has more structure than key → value."""

    @property
    def figures(self) -> dict[str, float]:
        """Key → value, for ``--json``."""
        return {f.key: round(f.value, 3) for f in self.items}

    @property
    def json(self) -> dict[str, Any]:
        """What ``--json`` prints: :attr:`data` if the suite gave it, else :attr:`figures`
        (as strict JSON: a figure that is not finite, a rate over no time, is ``null``)."""
        return self.data if self.data is not None else dict(self.figures)

    @property
    def passed(self) -> bool:
        """True when every figure meets its target."""
        return all(f.passed for f in self.items)

    def render(self) -> str:
        """A table for the terminal."""
        lines = [f"whexar bench {self.suite}"]
        for f in self.items:
            verdict = "ok" if f.passed else "MISSED"
            bound = ">=" if f.at_least else "<="
            lines.append(
                f"  {f.label:<44}{f.value:12.3f} {f.unit:<5} (target {bound} {f.target:g} {f.unit})"
                f"  {verdict}"
            )
        lines.extend(f"  {note}" for note in self.notes)
        return "\n".join(lines)
