"""The terrain estimator's policy, called directly: readings with their times in, the
window's metrics (4.2.3) out."""

from __future__ import annotations

import math

import pytest

from whexar.actors.messages import (
    BodyTilt,
    ImuSample,
    LegState,
    LocomotionState,
    ObstacleRanges,
    SwingEnded,
)
from whexar.actors.reactive.terrain import SETTLE_S, TerrainEstimator
from whexar.config import RobotConfig
from whexar.testing.reflexes import leg_state, locomotion_state

CFG = RobotConfig()


def swing(t: float, outcome: str, offset_m: float = 0.0, confidence: float = 1.0) -> SwingEnded:
    return SwingEnded(
        t=t,
        source="leg-RF",
        leg=0,
        outcome=outcome,  # type: ignore[arg-type]
        ground_offset_m=offset_m,
        confidence=confidence,
    )


def walking(t: float, cycle_s: float) -> LocomotionState:
    return LocomotionState(
        t=t,
        source="coordinator",
        activity="walking",
        mode="walk",
        gait="tripod",
        stance="default",
        twist=(0.1, 0.0, 0.0),
        gait_phase=0.0,
        swing_legs=(),
        margin_m=0.1,
        upside_down=False,
        cycle_s=cycle_s,
    )


def leg(t: float, phase: str, contact: bool, confidence: float = 0.9) -> LegState:
    return leg_state(t, 2, phase, contact=contact, confidence=confidence)


def test_the_window_is_one_gait_cycle_while_walking_else_the_still_one() -> None:
    est = TerrainEstimator(CFG)
    assert est.estimate(1.0).window_s == CFG.terrain.still_window_s
    est.locomotion(walking(1.0, 1.6))
    assert est.estimate(1.0).window_s == pytest.approx(1.6)
    est.locomotion(walking(1.0, 0.5))  # a fast cycle: the window's floor
    assert est.estimate(1.0).window_s == CFG.terrain.min_window_s


def test_the_step_height_is_the_highest_ground_met_above_the_expected_in_the_window() -> None:
    est = TerrainEstimator(CFG)
    est.locomotion(walking(0.0, 1.6))
    est.swing(swing(1.0, "early_contact", 0.005))  # the flat's compliance: no step
    assert est.estimate(1.1).step_height_m == 0.0
    est.swing(swing(1.2, "early_contact", 0.06))
    est.swing(swing(1.5, "blocked", 0.09))
    est.swing(swing(1.6, "completed", 0.2))  # completed: where expected
    assert est.estimate(1.7).step_height_m == pytest.approx(0.09)
    assert est.estimate(3.0).step_height_m == pytest.approx(0.09)  # 1.5 s ago, within 1.6 s
    assert est.estimate(3.2).step_height_m == 0.0  # out of the window


def test_pitch_and_roll_are_the_window_means_apart() -> None:
    est = TerrainEstimator(CFG)
    for k in range(20):
        t = 0.1 * k
        est.tilt(
            BodyTilt(
                t=t,
                source="imu",
                seq=k,
                sensor="imu",
                roll_rad=math.radians(4.0),
                pitch_rad=math.radians(10.0 + (2.0 if k % 2 else -2.0)),
                accel_g=(0.0, 0.0, 1.0),
            )
        )
    e = est.estimate(2.0)  # the readings up to 1.95 s: all twenty
    assert math.degrees(e.pitch_rad) == pytest.approx(10.0)
    assert math.degrees(e.roll_rad) == pytest.approx(4.0)
    assert e.tilt_known
    assert not TerrainEstimator(CFG).estimate(1.95).tilt_known


def test_bumps_count_jolts_once_each() -> None:
    est = TerrainEstimator(CFG)
    readings = [(0.00, 1.0), (0.02, 1.7), (0.04, 1.8), (0.06, 0.3), (0.30, 1.0), (0.32, 1.6)]
    for k, (t, z) in enumerate(readings):
        est.imu(ImuSample(t=t, source="imu", seq=k, accel_g=(0.0, 0.0, z), gyro_dps=(0, 0, 0)))
    est.imu(ImuSample(t=0.4, source="imu", seq=9, accel_g=(math.nan, 0, 1), gyro_dps=(0, 0, 0)))
    assert est.estimate(0.5).bumps == 2  # 0.02–0.06 s one jolt, 0.32 s another


def test_an_obstacle_is_counted_as_it_comes_near_then_again_once_clear() -> None:
    est = TerrainEstimator(CFG)
    track = [math.inf, 0.8, 0.35, 0.3, 0.45, 0.38, 0.7, 0.39, None]
    for k, d in enumerate(track):
        est.ranges(
            ObstacleRanges(t=0.1 * k, source="sensors", seq=k, counts=(0, 0), distances_m=(d, None))
        )
    # Near at 0.35 (one); 0.45 then 0.38 is the same obstacle (not beyond 0.6); 0.7 clears.
    assert est.estimate(1.0).obstacles == 2


def test_keeping_still_the_floor_near_the_feet_is_no_obstacle() -> None:
    est = TerrainEstimator(CFG)
    est.locomotion(locomotion_state(0.0, "seated"))
    for k, d in enumerate([0.23, 0.8, 0.23]):  # the floor, seated; standing; seated again
        est.ranges(ObstacleRanges(t=0.1 * k, source="s", seq=k, counts=(0, 0), distances_m=(d, d)))
    assert est.estimate(0.5).obstacles == 0
    est.locomotion(walking(0.6, 2.0))
    est.ranges(ObstacleRanges(t=0.7, source="s", seq=5, counts=(0, 0), distances_m=(0.3, None)))
    assert est.estimate(1.0).obstacles == 1


def test_lost_supports_count_believed_no_contact_swings_and_stances_that_lose_ground() -> None:
    est = TerrainEstimator(CFG)
    est.locomotion(walking(0.0, 2.0))
    est.swing(swing(0.5, "no_contact"))
    est.swing(swing(0.6, "no_contact", confidence=0.2))  # a dead FSR's: not believed
    # RM in stance, supported, then the ground goes: counted once touchdown_s has passed.
    est.leg(leg(0.7, "stance", True))
    for k in range(40):
        est.leg(leg(0.8 + 0.01 * k, "stance", False))
    assert est.estimate(1.2).lost_supports == 2
    # A stance that never had contact (a swing already counted) adds nothing.
    est.leg(leg(1.3, "swing", False))
    for k in range(40):
        est.leg(leg(1.4 + 0.01 * k, "stance", False))
    assert est.estimate(1.9).lost_supports == 2


def test_an_estimate_leaves_out_the_readings_of_its_last_instants() -> None:
    # A reading of the same instant may or may not have arrived: none counts until SETTLE_S.
    est = TerrainEstimator(CFG)
    est.swing(swing(1.0, "early_contact", 0.05))
    assert est.estimate(1.0).step_height_m == 0.0
    assert est.estimate(1.0 + SETTLE_S).step_height_m == pytest.approx(0.05)
