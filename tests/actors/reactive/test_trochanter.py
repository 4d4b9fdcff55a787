"""The trochanter reflex's policy, called directly: past a filtered tilt the trochanters
follow the pitch; below a lower one they are released — and the coordinator holds what
it is asked, within its limit."""

from __future__ import annotations

import math

import pytest

from tests.actors.locomotion.test_planner import drive, standing
from whexar.actors.messages import BodyMotion, BodyTilt, ReflexRequest
from whexar.actors.reactive import check_params
from whexar.actors.reactive.trochanter import Trochanter
from whexar.config import RobotConfig


def trochanter(**params: object) -> Trochanter:
    return Trochanter(check_params(Trochanter, params), name="reflex-trochanter", cfg=RobotConfig())


def tilt(t: float, pitch_deg: float) -> BodyTilt:
    return BodyTilt(
        t=t,
        source="sensors",
        seq=None,
        sensor="board",
        roll_rad=0.0,
        pitch_rad=math.radians(pitch_deg),
        accel_g=(0.0, 0.0, 1.0),
    )


def run(r: Trochanter, pitch_deg: float, t0: float, t1: float) -> list[ReflexRequest]:
    out = []
    for k in range(round((t1 - t0) / 0.02)):
        t = t0 + k * 0.02
        out += [c for c in r.react(t, tilt(t, pitch_deg)) if isinstance(c, ReflexRequest)]
    return out


def test_a_slope_past_the_threshold_turns_the_legs_and_level_ground_releases_them() -> None:
    r = trochanter()
    assert run(r, 2.0, 0.0, 5.0) == []  # below on_deg: nothing
    assert not r.active
    asked = run(r, 20.0, 5.0, 10.0)  # the board tilted to 20°: the filter follows in ~1 s
    assert r.active
    first = asked[0]
    assert first.t - 5.0 < 0.5  # 5° of the 18° step is passed within a fifth of filter_s
    assert math.degrees(asked[-1].trochanter_rad or 0.0) == pytest.approx(20.0, abs=0.65)
    # Bounded requests: one per step_deg, not one per reading.
    assert len(asked) < 45
    held = run(r, 4.0, 10.0, 15.0)  # between off_deg and on_deg: followed, not released
    assert r.active
    assert math.degrees(held[-1].trochanter_rad or 0.0) == pytest.approx(4.0, abs=0.65)
    *following, release = run(r, 0.0, 15.0, 20.0)  # down to off_deg, then released
    assert all((f.trochanter_rad or 0.0) > 0.0 for f in following)
    assert release.trochanter_rad == 0.0
    assert not r.active


def test_the_hysteresis_must_be_below_the_threshold() -> None:
    with pytest.raises(ValueError, match=r"params\.off_deg = 6\.0: .*below on_deg"):
        trochanter(on_deg=5.0, off_deg=6.0)


def test_the_coordinator_holds_the_angle_asked_within_its_limit() -> None:
    planner, legs = standing()
    limit = planner.max_trochanter
    ask = ReflexRequest(t=0.0, source="reflex", reflex="trochanter", trochanter_rad=2.0)
    said = drive(planner, legs, 3.0, 3.2, requests={3.0: ask})
    motion = [m for m in said if isinstance(m, BodyMotion)]
    assert motion[-1].trochanter_rad == pytest.approx(limit)
    off = ReflexRequest(t=0.0, source="reflex", reflex="trochanter", trochanter_rad=0.0)
    said = drive(planner, legs, 3.2, 3.4, requests={3.2: off})
    assert [m for m in said if isinstance(m, BodyMotion)][-1].trochanter_rad == 0.0
