"""The gait ranking of Table 5.9 holds for WHexaR's own geometry (3.2.1–3.2.2, 5.4)."""

import json

import numpy as np
import pytest

from whexar.cli import main
from whexar.config import RobotConfig, default_geometry
from whexar.errors import UsageError
from whexar.kinematics.body import leg_to_body, stance_feet
from whexar.kinematics.gait import GAIT_RANKING, GAITS
from whexar.kinematics.stability import gait_stability_margin, static_stability_margin
from whexar.kinematics.trajectory import FootTrajectory
from whexar.robot import LEG_NAMES

FEET = leg_to_body(stance_feet(RobotConfig().stance("default")), default_geometry())


@pytest.mark.parametrize("step_length", [0.06, 0.10, 0.14])
def test_more_stable_gaits_keep_larger_margins(step_length: float) -> None:
    margins = []
    for name in GAIT_RANKING[1:]:
        gait = GAITS[name]
        trajectory = FootTrajectory(step_length, 0.04, gait.duty_factor)
        margins.append(gait_stability_margin(gait, FEET, trajectory, samples=240)[0])
    assert margins == sorted(margins)
    assert len(set(margins)) == len(margins)
    assert margins[0] > 0  # even the tripod stays statically stable in the default stance


def test_margin_matches_a_hand_built_support_set() -> None:
    gait = GAITS["tripod"]
    trajectory = FootTrajectory(0.1, 0.04, gait.duty_factor)
    worst, phase = gait_stability_margin(gait, FEET, trajectory, samples=240)
    s, _ = trajectory.at(gait.leg_phase(phase))
    points = FEET[:, :2] + np.stack([s, np.zeros(6)], axis=-1)
    support = points[~gait.in_swing(phase)]
    assert len(support) == 3
    assert worst == pytest.approx(static_stability_margin(support))


def test_longer_steps_lower_the_tripod_margin() -> None:
    gait = GAITS["tripod"]
    short = gait_stability_margin(gait, FEET, FootTrajectory(0.05, 0.04, 0.5))[0]
    long = gait_stability_margin(gait, FEET, FootTrajectory(0.15, 0.04, 0.5))[0]
    assert long < short


def test_bad_sample_count() -> None:
    with pytest.raises(UsageError, match="samples"):
        gait_stability_margin(GAITS["wave"], FEET, FootTrajectory(0.1, 0.04, 5 / 6), samples=0)


def test_cli_gait_chart_and_json(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["kin", "gait", "wave", "--width", "24"]) == 0
    lines = capsys.readouterr().out.splitlines()
    rows = {line.split()[0]: line.split()[1] for line in lines if line.strip()[:2] in LEG_NAMES}
    assert set(rows) == set(LEG_NAMES)
    # Wave: each leg swings for one sixth of the cycle, one leg at a time.
    assert all(row.count("^") == 4 for row in rows.values())
    for column in range(24):
        assert sum(row[column] == "^" for row in rows.values()) == 1

    assert main(["kin", "gait", "tetrapod", "--json", "--step-mm", "80"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["duty_factor"] == pytest.approx(2 / 3)
    assert out["min_margin_mm"] > 0

    assert main(["kin", "gait", "gallop"]) == 2
    assert "tripod, tetrapod, ripple, wave" in capsys.readouterr().err
    assert main(["kin", "gait", "tripod", "--step-mm", "-5"]) == 2
