"""How far the simulation's figures lie from the thesis's, over the whole table.

Theory of operation
-------------------
The table of :func:`~whexar.campaign.experiments.figures.figures` is read row by
row; :func:`agreement` sums it up in the three numbers a reader of the table
asks first:

* *the median deviation*, |sim − thesis| / |thesis|, over the rows where the
  thesis gives one number other than 0 and the simulation a number (a figure of
  0, such as a direction of travel, has no relative deviation);
* *the rows far off*: those whose sim / thesis lies outside ½…2 (a figure of the
  wrong sign among them);
* *the ranges and bounds* (``"0.07–0.12"``, ``"32–40"``, ``"≥ 50"``, ``">23"``):
  whether the simulation's figure lies inside, and how far outside relative to
  the bound it misses.

A row with a thesis figure and no number from the simulation (the run failed, or
the figure is not simulated) is named apart: it is neither close nor far. So is a
row measured a second way beside one that is counted (``Figure.counted`` false: the
steepest slopes on Table 6.6's fixed inclinations, beside the tilting board's),
so that no figure of the thesis counts twice.
Over seeds, the simulation's figure is the median the table shows.
"""

from __future__ import annotations

import re
import statistics
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Final, TypeGuard

from whexar.campaign.experiments.figures import Figure

FAR_RATIO: Final = 2.0
"""A figure is far off when sim / thesis lies outside 1/FAR_RATIO … FAR_RATIO."""

_RANGE: Final = re.compile(r"^\s*(-?\d+(?:\.\d+)?)\s*[–-]\s*(-?\d+(?:\.\d+)?)\s*$")
_BOUND: Final = re.compile(r"^\s*(?:≥|>=|>)\s*(-?\d+(?:\.\d+)?)\s*$")


def bounds(text: str) -> tuple[float, float] | None:
    """The range or lower bound a thesis figure given as text means: ``"32–40"`` →
    (32, 40), ``"≥ 50"`` or ``">23"`` → (50, inf); ``None`` for other text."""
    if m := _RANGE.match(text):
        low, high = float(m[1]), float(m[2])
        return (low, high) if low <= high else None
    if m := _BOUND.match(text):
        return float(m[1]), float("inf")
    return None


@dataclass(frozen=True)
class Compared:
    """One row of the table set against the thesis's figure."""

    figure: Figure
    deviation: float
    """|sim − thesis| / |thesis| for a number; for a range, 0 inside and otherwise the
    distance to the bound missed, relative to it."""
    ratio: float
    """sim / thesis; for a range, against the bound missed (1 inside)."""

    @property
    def far(self) -> bool:
        """:attr:`ratio` outside 1/:data:`FAR_RATIO` … :data:`FAR_RATIO` (or negative)."""
        return not 1.0 / FAR_RATIO <= self.ratio <= FAR_RATIO

    def to_json(self) -> dict[str, Any]:
        """``{"name", "thesis", "sim", "deviation", "ratio"}``."""
        f = self.figure
        return {
            "name": f.name,
            "thesis": f.thesis,
            "sim": f.sim,
            "deviation": self.deviation,
            "ratio": self.ratio,
        }


def _number(value: object) -> TypeGuard[int | float]:
    """A figure the simulation gave as a number (not text, not none)."""
    return isinstance(value, int | float) and not isinstance(value, bool)


def compare(f: Figure) -> Compared | None:
    """The row against the thesis; ``None`` when there is nothing to compare (no thesis
    figure or a 0, no number from the simulation, text that is no range)."""
    sim, thesis = f.sim, f.thesis
    if not _number(sim) or thesis is None:
        return None
    if isinstance(thesis, str):
        span = bounds(thesis)
        if span is None:
            return None
        low, high = span
        if low <= sim <= high:
            return Compared(f, 0.0, 1.0)
        bound = low if sim < low else high
        if bound == 0:
            return None
        return Compared(f, abs(sim - bound) / abs(bound), sim / bound)
    if thesis == 0:
        return None
    return Compared(f, abs(sim - thesis) / abs(thesis), sim / thesis)


@dataclass(frozen=True)
class Agreement:
    """The table summed up (the module docstring)."""

    numbers: tuple[Compared, ...]
    """The rows with one thesis number (not 0) and a number from the simulation."""
    ranges: tuple[Compared, ...]
    """The rows whose thesis figure is a range or a bound."""
    without_value: tuple[Figure, ...]
    """Rows with a thesis figure and no number from the simulation."""
    second: tuple[Compared, ...] = ()
    """The rows measured a second way (``Figure.counted`` false), set against the thesis:
    in none of the counts above."""

    @property
    def median_deviation(self) -> float | None:
        """The median of :attr:`numbers`' deviations; ``None`` when there are none."""
        return statistics.median(c.deviation for c in self.numbers) if self.numbers else None

    @property
    def far_off(self) -> tuple[Compared, ...]:
        """The rows, numbers and ranges, more than 2× off."""
        return tuple(c for c in (*self.numbers, *self.ranges) if c.far)

    @property
    def inside(self) -> int:
        """How many ranges and bounds the simulation's figure lies inside."""
        return len(self.ranges) - len(self.outside)

    @property
    def outside(self) -> tuple[Compared, ...]:
        """The ranges and bounds the simulation's figure lies outside."""
        return tuple(c for c in self.ranges if c.deviation > 0)

    def to_json(self) -> dict[str, Any]:
        """The ``"agreement"`` of ``whexar sim --experiments --json``."""
        return {
            "numbers": len(self.numbers),
            "median_deviation": self.median_deviation,
            "ranges": len(self.ranges),
            "ranges_inside": self.inside,
            "far_off": [c.to_json() for c in self.far_off],
            "outside": [c.to_json() for c in self.outside],
            "without_value": [f.name for f in self.without_value],
            "second": [c.to_json() for c in self.second],
        }


def agreement(found: Sequence[Figure]) -> Agreement:
    """The table of figures summed up (the module docstring)."""
    numbers: list[Compared] = []
    ranges: list[Compared] = []
    without: list[Figure] = []
    second: list[Compared] = []
    for f in found:
        if f.thesis is None:
            continue
        c = compare(f)
        if not f.counted:
            if c is not None:
                second.append(c)
        elif c is not None:
            (ranges if isinstance(f.thesis, str) else numbers).append(c)
        elif not _number(f.sim):
            without.append(f)
    return Agreement(tuple(numbers), tuple(ranges), tuple(without), tuple(second))


__all__ = ["FAR_RATIO", "Agreement", "Compared", "agreement", "bounds", "compare"]
