"""Strict JSON (RFC 8259) for what whexar writes for people and their tools.

Python's :mod:`json` writes a float that is not finite as ``NaN``, ``Infinity`` or
``-Infinity``: JavaScript's literals, not JSON's, so a strict parser (``jq``,
``JSON.parse``, Go's and Rust's decoders) refuses the whole document for one figure.
:func:`dumps` writes such a float as ``null`` instead: the figure has no number. What a
``null`` means for a given field (a margin with fewer than three feet down, a rate over
no time) is said where that output is described, beside the field. Whatever else is not
finite, a value nobody foresaw included, cannot slip through: the encoder is told
``allow_nan=False`` and raises rather than write it.

Every ``--json`` of the command line prints through :func:`dumps`, and the files written
for the same readers: a campaign's ``results.json`` and ``runs.jsonl``, a simulation
report's ``summary.json``. A recording's messages are not among them: they are encoded
by their own rules (:mod:`whexar.record.encoding`).

Imports nothing else of whexar, so that every layer that writes JSON for users can use it.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from typing import Any

__all__ = ["dumps", "strict"]


def strict(value: Any) -> Any:
    """``value`` with every float that is not finite, at any depth of its dicts, lists and
    tuples, replaced by ``None``; tuples become lists, as JSON has them. Anything else is
    returned as it is (the encoder decides what it can write)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: strict(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [strict(item) for item in value]
    return value


def dumps(
    value: Any,
    *,
    indent: int | None = None,
    sort_keys: bool = False,
    default: Callable[[Any], Any] | None = None,
) -> str:
    """``value`` as strict JSON: :func:`strict`, then :func:`json.dumps` with
    ``allow_nan=False``. ``default`` turns what JSON cannot hold into what it can
    (``str`` for paths); its result is made strict too."""
    fallback = None if default is None else (lambda obj: strict(default(obj)))
    return json.dumps(
        strict(value), indent=indent, sort_keys=sort_keys, default=fallback, allow_nan=False
    )
