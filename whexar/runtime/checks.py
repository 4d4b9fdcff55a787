"""Scalar argument checks, shared by the runtime (the ticker) and the pure-math modules.

Each raises :class:`~whexar.runtime.errors.UsageError` naming the argument, the value
given and what is allowed, so a bad number never becomes a NaN downstream.
"""

from __future__ import annotations

import math

import numpy as np

from whexar.runtime.errors import UsageError


def real(name: str, value: object) -> float:
    """A finite real number (bools and strings are refused)."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise UsageError(f"{name} = {value!r}: expected a real number")
    number = float(value)
    if not math.isfinite(number):
        raise UsageError(f"{name} = {value!r}: must be finite")
    return number


def positive(name: str, value: object, unit: str = "") -> float:
    """A finite number > 0."""
    number = real(name, value)
    if number <= 0.0:
        raise UsageError(f"{name} = {value!r}: must be > 0{f' {unit}' if unit else ''}")
    return number


def non_negative(name: str, value: object, unit: str = "") -> float:
    """A finite number ≥ 0."""
    number = real(name, value)
    if number < 0.0:
        raise UsageError(f"{name} = {value!r}: must be ≥ 0{f' {unit}' if unit else ''}")
    return number
