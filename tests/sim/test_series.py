"""What a run keeps instead of its messages: the series give what the messages give, and
progress is not path length."""

from __future__ import annotations

import math

import numpy as np
import pytest

from whexar.actors.messages import (
    JointGoals,
    LegState,
    LocomotionState,
    ReflexActivity,
    ServoStates,
)
from whexar.campaign.metrics import Window, servo_currents
from whexar.errors import UsageError
from whexar.record import plots
from whexar.sim.run import Sample, SimResult, progress, progress_along, simulate, travelled
from whexar.sim.series import TRACED_JOINTS, RunSeries
from whexar.testing.walk import command


def _swaying(seconds: float = 45.5, amplitude_m: float = 0.03) -> list[Sample]:
    """A body treading in place: swaying sideways and back once a gait cycle (1.3 s; 35
    cycles, so it ends where it began)."""
    out = []
    for k in range(int(seconds / 0.05) + 1):
        t = 0.05 * k
        phase = 2 * math.pi * t / 1.3
        x = 0.5 * amplitude_m * math.sin(2 * phase)
        y = amplitude_m * math.sin(phase)
        out.append(Sample(t, x, y, 0.28, 0.0, 0.0, 0.0, 50.0))
    return out


def test_swaying_in_place_has_a_path_but_no_progress() -> None:
    samples = _swaying()
    assert travelled(samples) > 0.5  # the sway adds up to a path …
    assert progress(samples) == pytest.approx(0.0, abs=1e-9)  # … and it got nowhere
    assert progress_along(samples, 0.0) == pytest.approx(0.0, abs=1e-9)
    # Stopped mid-sway, it is at most the sway's amplitude from where it began.
    assert progress(samples[:-10]) < 0.04


def test_progress_along_the_heading_is_signed() -> None:
    a = Sample(0.0, 1.0, 1.0, 0.28, 0.0, 0.0, 0.0, 0.0)
    b = Sample(10.0, 1.0 - 0.3, 1.0 + 0.4, 0.28, 0.0, 0.0, 0.0, 0.0)
    assert progress([a, b]) == pytest.approx(0.5)
    assert progress_along([a, b], 0.0) == pytest.approx(-0.3)  # went back along +x
    assert progress_along([a, b], math.pi / 2) == pytest.approx(0.4)
    assert progress([]) == progress_along([], 1.0) == 0.0


@pytest.fixture(scope="module")
def walked() -> SimResult:
    """Stand up, walk the tripod gait for two seconds; every message kept to compare."""
    return simulate(commands=[(3.0, command(vx_m_s=0.1))], duration=5.0, keep_log=True)


def test_the_series_give_what_the_messages_give(walked: SimResult) -> None:
    log, series = walked.run.log, walked.series
    assert series.swing_intervals() == plots.swing_intervals(log.messages("legs", of=LegState))
    assert series.activity_intervals() == plots.activity_intervals(
        log.messages("locomotion", of=LocomotionState)
    )
    states = log.messages("servo-state", of=ServoStates)
    assert series.joint_traces() == plots.joint_traces(
        log.messages("goals", of=JointGoals), states, 0, TRACED_JOINTS, source="leg-RF"
    )
    times, amps = series.leg_currents()
    want_t, want = plots.leg_currents(states)
    assert times == want_t
    np.testing.assert_array_equal(amps, want)
    assert series.cycles == len(states) > 100
    assert walked.events == log.events()
    assert [p.margin_m for p in series.locomotion] == [
        m.margin_m for m in log.messages("locomotion", of=LocomotionState)
    ]


def test_servo_currents_come_from_the_series(walked: SimResult) -> None:
    window = Window(3.0, 4.5)
    sums: dict[int, float] = {}
    counts: dict[int, int] = {}
    for msg in walked.run.log.messages(of=ServoStates):
        if window.contains(msg.t):
            for j in msg.joints:
                if j.current_a is not None and j.joint == 2:
                    sums[j.servo_id] = sums.get(j.servo_id, 0.0) + abs(j.current_a)
                    counts[j.servo_id] = counts.get(j.servo_id, 0) + 1
    assert servo_currents(walked, window, joint=2) == {k: sums[k] / counts[k] for k in sums}


def test_a_run_without_its_log_refuses_to_read_it() -> None:
    result = simulate(duration=1.0)
    with pytest.raises(UsageError, match="kept no message log"):
        result.run.log.messages()
    with pytest.raises(UsageError):
        result.run.log.digest()
    assert result.series.cycles > 0
    assert set(result.summary()) >= {"progress_m", "progress_along_m", "distance_m"}


def _activity(t: float, reflex: str, active: bool, inhibited: bool = False) -> ReflexActivity:
    return ReflexActivity(t=t, source=reflex, reflex=reflex, active=active, inhibited=inhibited)


def test_a_reflex_held_back_and_let_go_is_one_spell() -> None:
    # On 30° the elevator's raise outlived eleven of stepping's spells; each hold and
    # release counted as an activation of its own: 19 for 3 blocked swings.
    series = RunSeries.of(
        ("reflex-activity", m)
        for m in [
            _activity(1.0, "reflex-elevator", True),
            _activity(2.0, "reflex-elevator", False, inhibited=True),
            _activity(4.0, "reflex-elevator", True),
            _activity(5.0, "reflex-elevator", False, inhibited=True),
            _activity(7.0, "reflex-elevator", False),
            # Held back while quiet, then let go still quiet: no spell.
            _activity(8.0, "reflex-elevator", False, inhibited=True),
            _activity(9.0, "reflex-elevator", False),
            _activity(10.0, "reflex-elevator", True),
            _activity(11.0, "reflex-elevator", False),
        ]
    )
    assert series.reflex_intervals() == {"elevator": [(1.0, 7.0), (10.0, 11.0)]}
