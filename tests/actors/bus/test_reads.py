"""The read side of a cycle, called directly: the plan bound to the servos, suspects asked
again, Fast Sync Read detection and fallback, decoding, statistics (no runtime, no port)."""

from __future__ import annotations

import pytest

from whexar.actors.bus.reads import (
    FAST_FALLBACK_AFTER,
    CycleReads,
    Due,
    ReadMode,
    decode,
    health_readings,
    joint_states,
)
from whexar.actors.bus.servos import servo_table
from whexar.actors.bus.stats import MIN_CYCLE_S, MIN_PROBE_TIMEOUT_MS, BusCounters, NominalCycle
from whexar.actors.messages import BusStats, ReadModeChanged
from whexar.bus import control_table as ct
from whexar.bus.plan import PlanRead, ReadPlan, resolve_plan
from whexar.bus.protocol import ALERT
from whexar.bus.sdk import COMM_SUCCESS, SyncReadResult
from whexar.config import RobotConfig
from whexar.robot import servo_id

CFG = RobotConfig()
TABLE = servo_table(CFG)
ORDERED = sorted(TABLE.values(), key=lambda s: s.id)


def ids(due: Due) -> list[list[int]]:
    return [[s.id for s in servos] for _, servos in due]


def test_a_slow_read_takes_turns_and_a_rate() -> None:
    plan = ReadPlan(
        reads=(
            PlanRead(registers=("present_position",), joints=("femur",)),
            PlanRead(registers=("present_temperature",), joints=("coxa",), rate_hz=10, chunk=4),
        )
    )
    reads = CycleReads(plan, ORDERED)
    femurs = [servo_id(leg, "femur") for leg in range(6)]
    coxas = [servo_id(leg, "coxa") for leg in range(6)]
    assert ids(reads.due(0.0, set(), [])) == [femurs, coxas[:4]]
    assert ids(reads.due(0.05, set(), [])) == [femurs]  # not due yet
    assert ids(reads.due(0.1, set(), [])) == [femurs, coxas[4:] + coxas[:2]]
    # A servo out of the cycle is left out.
    assert ids(reads.due(0.15, {femurs[0]}, [])) == [femurs[1:]]


def test_a_suspect_is_asked_again_in_its_first_read_even_when_that_is_not_due() -> None:
    plan = ReadPlan(
        reads=(
            PlanRead(registers=("present_position",), joints=("femur",)),
            PlanRead(registers=("present_temperature",), joints=("coxa",), rate_hz=1),
        )
    )
    reads = CycleReads(plan, ORDERED)
    reads.due(0.0, set(), [])
    femur, coxa = servo_id(0, "femur"), servo_id(2, "coxa")
    due = reads.due(0.1, set(), [femur, coxa])
    assert ids(due) == [[servo_id(leg, "femur") for leg in range(6)], [coxa]]
    assert [r.spec.joints for r, _ in due] == [("femur",), ("coxa",)]
    assert reads.first_ids({femur}) == [servo_id(leg, "femur") for leg in range(1, 6)]


def test_fast_sync_read_is_detected_and_falls_back_after_repeated_failures() -> None:
    mode = ReadMode("auto", "bus")
    assert mode.detects
    assert not mode.fast
    (said,) = mode.detected(1.0, True, "start-up", report=True)
    assert isinstance(said, ReadModeChanged)
    assert (said.mode, said.reason) == ("fast_sync_read", "start-up: Fast Sync Read answered")
    assert mode.detected(2.0, True, "servo 3 recovered") == []  # no change, nothing said
    for _ in range(FAST_FALLBACK_AFTER - 1):
        assert mode.cycled(3.0, 1) == []
    assert mode.cycled(3.0, 0) == []  # a clean cycle ends the streak
    for _ in range(FAST_FALLBACK_AFTER - 1):
        assert mode.cycled(3.0, 2) == []
    (fallback,) = mode.cycled(3.0, 1)
    assert isinstance(fallback, ReadModeChanged)
    assert fallback.mode == "sync_read"
    assert mode.name == "sync_read"
    assert not ReadMode("on", "bus").detects
    assert ReadMode("on", "bus").fast


def test_what_a_cycle_read_becomes_what_it_publishes() -> None:
    plan = resolve_plan("default")
    reads = CycleReads(plan, ORDERED)
    due = reads.due(0.0, set(), [])
    femur = servo_id(0, "femur")
    first, health = due[0][0].block, due[1][0].block
    results = [SyncReadResult(COMM_SUCCESS) for _ in due]
    results[0].data[femur] = bytes(_encode(first, present_position=2048 + 100))
    results[0].errors[femur] = ALERT
    results[1].data[femur] = bytes(_encode(health, hardware_error_status=0x20))
    values, errors = decode(due, results)
    assert values[femur]["present_position"] == 2148
    assert values[femur]["hardware_error_status"] == 0x20
    assert errors == {femur: ALERT}
    (state,) = joint_states(TABLE, values, errors)
    assert (state.leg, state.joint, state.servo_id, state.alert) == (0, 2, femur, True)
    assert state.position_rad == pytest.approx(ct.ticks_to_rad(2148))
    (reading,) = health_readings(0.5, "bus", values)
    assert (reading.t, reading.servo_id, reading.hardware_error) == (0.5, femur, 0x20)


def _encode(block: ct.Block, **values: int) -> bytearray:
    """The bytes of ``block`` with ``values`` (zeros elsewhere)."""
    out = bytearray(block.length)
    for name, value in values.items():
        reg = ct.MODELS["MX-64"].register(name)
        at = reg.address - block.start
        out[at : at + reg.size] = value.to_bytes(reg.size, "little", signed=True)
    return out


def _report(counters: BusCounters, now: float) -> BusStats | None:
    return counters.report(
        now,
        read_mode="sync_read",
        timeouts=0,
        corrupt=0,
        clamped=0,
        write_failures=0,
        degraded={9, 3},
    )


def test_statistics_cover_the_window_since_the_last() -> None:
    counters = BusCounters("bus")
    counters.start(1.0)
    assert _report(counters, 1.0) is None
    for _ in range(10):
        counters.cycled(retries=1, nbytes=100)
    stats = _report(counters, 2.0)
    assert stats is not None
    assert (stats.cycles, stats.rate_hz, stats.bytes_per_cycle, stats.retries) == (
        10,
        10.0,
        100.0,
        10,
    )
    assert stats.degraded == (3, 9)
    counters.cycled(retries=0, nbytes=50)
    stats = _report(counters, 2.5)
    assert stats is not None
    assert (stats.rate_hz, stats.bytes_per_cycle) == (2.0, 50.0)


def test_the_nominal_cycle_bounds_the_probes_and_the_paced_cycles() -> None:
    nominal = NominalCycle()
    nominal.healthy(0.010)
    assert nominal.s == 0.010  # the first healthy cycle is taken as it is
    nominal.healthy(0.020)
    assert nominal.s == pytest.approx(0.011)
    assert nominal.probe_timeout_ms == pytest.approx(8.8)
    nominal.healthy(0.0)
    nominal.s = 0.0
    assert nominal.probe_timeout_ms == MIN_PROBE_TIMEOUT_MS
    assert nominal.paced_s == MIN_CYCLE_S
