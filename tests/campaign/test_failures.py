"""The servo-failure campaign: outcome rule, metrics, report and the campaign file.

The outcome rule is checked on hand-made runs (samples and a message log built
here), then once on a short real run: the RF femur silent during a tripod walk.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from types import SimpleNamespace
from typing import Any, cast

import pytest

from whexar.actors.messages import BusLost, LocomotionState, ServoDegraded, ServoFault
from whexar.campaign import Row, Window, load_campaign, registry
from whexar.campaign.failures import (
    distance_after_m,
    failure,
    heading_change_deg,
    reaction,
    robot_outcome,
    speed_kept,
    write_report,
)
from whexar.config import RobotConfig
from whexar.runtime.messages import Event, SafeStop, StopRequested
from whexar.runtime.wiring import EVENTS_CHANNEL
from whexar.sim.run import Sample, SimResult, simulate
from whexar.sim.series import RunSeries
from whexar.sim.world import SimWorld
from whexar.testing import LogEntry, MessageLog, RunResult
from whexar.testing.reflexes import locomotion_state
from whexar.testing.walk import command

FAIL_AT = 8.0
END = 16.0
SPEED = 0.1
HEIGHT = 0.28


def _state(t: float, activity: str) -> LocomotionState:
    return locomotion_state(t, activity, stance="normal")


def _fake(
    *,
    speed_after: float = SPEED,
    activity_after: str = "walking",
    tilt_after: float = 0.0,
    z_after: float = HEIGHT,
    yaw_rate: float = 0.0,
    events: Sequence[Event] = (),
    servo: int | None = 3,
) -> SimResult:
    """A run walking at :data:`SPEED` until :data:`FAIL_AT`, then as the arguments say."""
    samples: list[Sample] = []
    x = 0.0
    entries: list[LogEntry] = []
    t = 0.0
    while t <= END + 1.5:
        after = t >= FAIL_AT
        late = t >= FAIL_AT + 1.0  # the body goes down a while after the servo
        samples.append(
            Sample(
                t,
                x,
                0.0,
                z_after if late else HEIGHT,
                tilt_after if late else 0.0,
                0.0,
                yaw_rate * max(0.0, t - FAIL_AT),
                50.0,
            )
        )
        activity = activity_after if after else "walking"
        entries.append(LogEntry("locomotion", _state(t, activity)))
        x += 0.05 * (speed_after if after else SPEED)
        t = round(t + 0.05, 6)
    fault: list[Event] = []
    if servo is not None:
        fault = [
            ServoFault(
                t=FAIL_AT + 0.05 * k, source="bus", servo_id=servo, kind="timeout", consecutive=k
            )
            for k in range(1, 6)
        ]
        fault.append(ServoDegraded(t=FAIL_AT + 0.3, source="bus", servo_id=servo, reason="x"))
    everything: list[Event] = sorted([*fault, *events], key=lambda e: e.t)
    entries += [LogEntry(EVENTS_CHANNEL, e) for e in everything]
    entries.sort(key=lambda e: e.message.t)
    log = MessageLog(entries)
    run = RunResult(0, log, None, [], {}, END)
    world = cast(SimWorld, SimpleNamespace(cfg=RobotConfig(), chain=SimpleNamespace(hooks=[])))
    return SimResult(
        samples=samples,
        run=run,
        world=world,
        wall_s=1.0,
        duration_s=END,
        mass_kg=5.0,
        events=log.events(),
        series=RunSeries.of((e.channel, e.message) for e in entries),
    )


WHOLE = Window()


def test_a_walk_that_goes_on_after_the_failure() -> None:
    result = _fake()
    assert robot_outcome(result, WHOLE) == "walk goes on"
    assert registry()["world_stopped_at_s"].fn(result, WHOLE) is None
    f = failure(result)
    # No injector: the bus's first fault names the servo; the run's config names its joint.
    assert f is not None
    assert (f.servo_id, f.leg_name, f.joint_name) == (3, "RF", "femur")
    assert f.t == pytest.approx(FAIL_AT + 0.05)
    distance = distance_after_m(result, WHOLE)
    assert isinstance(distance, float)
    assert distance == pytest.approx(SPEED * (END - 0.1 - f.t), abs=0.01)
    kept = speed_kept(result, WHOLE)
    assert isinstance(kept, float)
    assert kept == pytest.approx(1.0, abs=0.05)


def test_a_robot_that_veers_keeps_walking_and_says_how_far_it_turned() -> None:
    result = _fake(yaw_rate=math.radians(2.0))
    assert robot_outcome(result, WHOLE) == "walk goes on"
    turn = heading_change_deg(result, WHOLE)
    assert isinstance(turn, float)
    assert turn == pytest.approx(2.0 * (END - 0.1 - 8.05), abs=0.2)


def test_a_walk_that_treads_in_place_is_stalled() -> None:
    assert robot_outcome(_fake(speed_after=0.01), WHOLE) == "stalled"


def test_the_runtime_stopping_the_robot_is_a_safe_stop() -> None:
    lost = [
        BusLost(t=FAIL_AT + 0.3, source="bus", reason="servo 3 (RF femur) lost"),
        StopRequested(t=FAIL_AT + 0.3, source="runtime", reason="safe stop: bus: lost"),
        SafeStop(t=FAIL_AT + 0.3, source="runtime", reason="safe stop: bus: lost"),
        StopRequested(t=END, source="runtime", reason="duration 16 s elapsed"),
    ]
    # The coordinator still says "walking": the bus stopped cycling, so it never said more.
    result = _fake(speed_after=0.0, events=lost)
    assert robot_outcome(result, WHOLE) == "safe stop"
    text = reaction(result, WHOLE)
    assert text == "ServoFault×5 ServoDegraded BusLost StopRequested SafeStop"


def test_a_coordinator_that_stands_after_the_failure_made_a_safe_stop() -> None:
    assert robot_outcome(_fake(speed_after=0.0, activity_after="standing"), WHOLE) == "safe stop"


def test_a_tilt_past_60_degrees_or_a_body_on_the_ground_is_a_fall() -> None:
    assert robot_outcome(_fake(tilt_after=math.radians(70)), WHOLE) == "fall"
    assert robot_outcome(_fake(z_after=0.1), WHOLE) == "fall"
    # Lowered on purpose, it is no fall.
    sat = _fake(z_after=0.1, activity_after="sitting_down", speed_after=0.0)
    assert robot_outcome(sat, WHOLE) == "safe stop"


def test_a_run_without_a_failure_or_without_samples_has_no_outcome() -> None:
    assert robot_outcome(_fake(servo=None), WHOLE) is None
    result = _fake()
    result.samples = []
    for name in ("robot_outcome", "distance_after_m", "speed_kept", "heading_change_deg"):
        assert registry()[name].fn(result, WHOLE) is None


def test_the_window_ends_what_counts_as_after_the_failure() -> None:
    result = _fake()
    short = distance_after_m(result, Window(0.0, 10.0))
    assert isinstance(short, float)
    assert short == pytest.approx(SPEED * 1.95, abs=0.01)


def _row(sid: int, outcome: str | None, *, failed: bool = False) -> Row:
    metrics: dict[str, Any] = {
        "failed_servo": sid,
        "failed_leg": "RF",
        "failed_joint": ["coxa", "trochanter", "femur"][sid - 1],
        "robot_outcome": outcome,
        "failed_at_s": 8.0,
        "distance_after_m": 0.7,
        "progress_after_m": 0.5,
        "speed_kept": 0.9,
        "heading_change_deg": -3.0,
        "detected_after_s": 0.33,
        "reaction": "ServoFault×5 ServoDegraded",
    }
    return Row(
        id=f"{sid:04d}",
        label="silent servo",
        variation={"faults.faults[0].ids": [sid]},
        metrics={} if failed else metrics,
        state_hash=None,
        outcome="failed" if failed else "ok",
        error="timed out" if failed else None,
    )


def test_the_report_is_a_table_and_a_grid(tmp_path: Path) -> None:
    rows = [_row(1, "walk goes on"), _row(2, "fall"), _row(3, None, failed=True)]
    written = write_report(rows, tmp_path)
    md, png = tmp_path / "servo-failures.md", tmp_path / "img" / "servo-failures.png"
    assert written == [md, png]
    assert png.stat().st_size > 1000
    text = md.read_text()
    assert "walk goes on: 1, fall: 1, no outcome: 1" in text
    assert (
        "| 1 | RF | coxa | walk goes on | 0.50 | 90% | -3.0 | 0.33 | ServoFault×5 ServoDegraded |"
        in text
    )
    # A failed run is named from its variation, with the default numbering.
    assert "| 3 | RF | femur | – | – | – | – | – | run failed: timed out |" in text
    assert "](img/servo-failures.png)" in text
    assert "at 8 s of the run" in text


def test_the_campaign_silences_each_servo_once() -> None:
    campaign = load_campaign("config/campaigns/servo-failures.toml")
    assert len(campaign.runs) == 42
    ids = sorted(r.variation["faults.faults[0].ids"][0] for r in campaign.runs)
    assert ids == list(range(1, 43))
    names = registry()
    for name in ("robot_outcome", "distance_after_m", "failed_servo", "reaction"):
        assert name in names


@pytest.mark.slow
def test_a_silent_femur_in_a_real_walk_is_a_safe_stop(tmp_path: Path) -> None:
    # 6.5 s simulated: stand up, walk from 2.5 s, the RF femur silent at 4 s. The femur is
    # critical: the bus loses it, the runtime stops the robot, seated.
    plan = tmp_path / "femur.toml"
    plan.write_text('seed = 0\n[[faults]]\nkind = "silent"\nids = [3]\nat_s = 4.0\n')
    result = simulate(
        commands=[(2.5, command(gait="tripod", vx_m_s=0.1))], duration=6.5, faults=plan
    )
    f = failure(result)
    # Named by the injector: the fault's own start, not the bus's first timeout.
    assert f is not None
    assert (f.servo_id, f.leg_name, f.joint_name, f.t) == (3, "RF", "femur", 4.0)
    assert robot_outcome(result, WHOLE) == "safe stop"
    text = reaction(result, WHOLE)
    assert isinstance(text, str)
    assert "BusLost" in text
    assert "ServoDegraded" in text
    distance = distance_after_m(result, WHOLE)
    assert isinstance(distance, float)
    assert distance < 0.2  # 0.4 s more of walking until the bus gave up on it, the sit-down
    # The bus cycled on without the femur while the robot sat down, then parked the servos.
    assert registry()["world_stopped_at_s"].fn(result, WHOLE) is None
    assert registry()["final_activity"].fn(result, WHOLE) == "seated walk/tripod"
    # The bus reads the femur every cycle: it leaves it out within half a second.
    detected = registry()["detected_after_s"].fn(result, WHOLE)
    assert isinstance(detected, float)
    assert 0.0 < detected < 0.5
