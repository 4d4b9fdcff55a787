"""What the configuration's sections share: servo model names, ADC counts, tolerances."""

from __future__ import annotations

from typing import Annotated, Final, Literal

from pydantic import (
    Field,
)

ServoModelName = Literal["MX-28", "MX-64", "MX-106"]

DH_SEGMENT_TOLERANCE_MM: Final = 5.0
"""How far a DH length may differ from the measured segment length of Table 5.2.

The thesis itself differs by 2 mm: trochanter offset d₁ = 65 mm in the DH
table (Table 5.3) against 63 mm measured (Table 5.2). Table 6.5 is reproduced
only with 65 mm, so the DH value drives the kinematics and the check allows
a few millimetres of measuring slack, not a different leg.
"""

AdcCounts = Annotated[int, Field(ge=0, le=1023)]
"""A 10-bit ATmega2560 ADC reading."""
