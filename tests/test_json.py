"""``whexar._json``: a float that is not finite is written as ``null``, at any depth."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import NoReturn

import numpy as np
import pytest

from whexar._json import dumps, strict


def _refuse(constant: str) -> NoReturn:
    pytest.fail(f"{constant} is not JSON")


def test_non_finite_floats_become_null_at_any_depth() -> None:
    value = {
        "margin_m": -math.inf,
        "rate": math.inf,
        "mean": math.nan,
        "kept": [1.5, (math.nan, 2), {"deep": [np.float64(np.inf)]}],
        "flags": [True, False, None, 0, "NaN"],
    }
    text = dumps(value)
    assert json.loads(text, parse_constant=_refuse) == {
        "margin_m": None,
        "rate": None,
        "mean": None,
        "kept": [1.5, [None, 2], {"deep": [None]}],
        "flags": [True, False, None, 0, "NaN"],
    }


def test_finite_values_are_written_as_json_writes_them() -> None:
    value = {"t": 0.1 + 0.2, "n": 10**20, "s": "µ", "big": 1e308, "tiny": 5e-324}
    assert dumps(value) == json.dumps(value)
    assert dumps(value, indent=2, sort_keys=True) == json.dumps(value, indent=2, sort_keys=True)
    assert strict((1, [2.0])) == [1, [2.0]]


def test_what_default_makes_is_strict_too_and_nothing_slips_through() -> None:
    class Odd:
        pass

    assert dumps({"p": Path("a/b")}, default=str) == '{"p": "a/b"}'
    assert dumps([Odd()], default=lambda _: math.inf) == "[null]"
    with pytest.raises(TypeError):
        dumps(Odd())
    # A non-finite key is no value strict() rewrites: the encoder refuses it, not writes it.
    with pytest.raises(ValueError, match="JSON compliant"):
        dumps({math.inf: 1})
