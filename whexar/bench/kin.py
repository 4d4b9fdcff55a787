"""``whexar bench kin``: inverse-kinematics speed (targets of the foundation issue).

* IK of all six legs in one call: median ≤ 50 µs;
* 10,000 targets in one vectorised call: median ≤ 5 ms.
"""

from __future__ import annotations

import numpy as np

from whexar.bench import Figure, Progress, Report, median_seconds
from whexar.config import RobotConfig
from whexar.kinematics.body import stance_feet
from whexar.kinematics.leg import ik

SIX_LEG_TARGET_US = 50.0
TEN_K_TARGET_MS = 5.0


def run(progress: Progress = None) -> Report:
    """Measure and return the figures; ``progress`` receives a line per step."""
    cfg = RobotConfig()
    geometry = cfg.leg_geometry()
    feet = stance_feet(cfg.stance("default"))
    rng = np.random.default_rng(7)
    # 10,000 targets spread over the working volume under the default stance,
    # some out of reach: clamping is part of the cost a controller pays.
    many = feet[np.arange(10_000) % 6] + rng.uniform(-0.06, 0.06, (10_000, 3))

    if progress:
        progress("timing IK of six legs (5000 calls)…")
    six = median_seconds(lambda: ik(feet, geometry, target="contact"), 5000)
    if progress:
        progress("timing IK of 10,000 targets (100 calls)…")
    ten_k = median_seconds(lambda: ik(many, geometry, target="contact", clamp=True), 100)
    return Report(
        "kin",
        [
            Figure(
                "ik_six_legs_us",
                "IK, six legs in one call (median)",
                six * 1e6,
                "µs",
                SIX_LEG_TARGET_US,
            ),
            Figure(
                "ik_10k_ms",
                "IK, 10,000 targets in one call (median)",
                ten_k * 1e3,
                "ms",
                TEN_K_TARGET_MS,
            ),
        ],
    )
