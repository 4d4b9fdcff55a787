"""Measurements printed in the reference thesis, for tests that check against them."""

from __future__ import annotations

from typing import Final

TABLE_6_4: Final[tuple[tuple[float, float, float, float, float], ...]] = (
    (-90, -0.06, -10.00, 0.08, -90.45),
    (-80, -0.09, -9.81, 1.72, -80.04),
    (-70, -0.25, -9.30, 3.36, -70.13),
    (-60, -0.53, -8.51, 4.88, -60.17),
    (-50, -0.39, -7.48, 6.25, -50.10),
    (-40, 0.30, -6.23, 7.40, -40.13),
    (-30, -0.38, -4.82, 8.32, -30.06),
    (-20, -0.25, -3.27, 8.98, -20.00),
    (-10, 0.34, -1.66, 9.35, -10.05),
    (0, 0.00, 0.00, 9.79, 0.00),
    (10, -0.10, 1.66, 9.31, 10.08),
    (20, -0.30, 3.23, 8.87, 20.05),
    (30, 0.16, 4.76, 8.16, 30.26),
    (40, -0.42, 6.09, 7.24, 40.07),
    (50, -0.55, 7.23, 6.03, 50.14),
    (60, -0.21, 8.29, 4.80, 59.96),
    (70, -0.32, 9.01, 3.28, 70.02),
    (80, -0.29, 9.49, 1.67, 80.03),
    (90, -0.28, 9.66, -0.01, 90.09),
)
"""Žák 2023, Table 6.4 (6.1.3), as printed: set angle [°], X, Y, Z [m/s²], calculated angle [°].

The calculated angle is the one from Y and Z. Row 1 prints Z = +0.08, but its
−90.45° needs Z = −0.08: a sign lost in print (``tests/test_sensing.py``).
"""

__all__ = ["TABLE_6_4"]
