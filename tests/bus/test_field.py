"""A field log's bus played back by time: the servos answer what the recording says they were,
whatever the replayed scheduler asks and whenever it asks it."""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Mapping, Sequence
from typing import Any

import pytest

from whexar.actors.messages import ServoDegraded, ServoStates
from whexar.bus.control_table import CENTER_TICKS, HardwareError, model, ticks_to_rad
from whexar.bus.emulator.chain import SERVO_CHAIN, Hook, ServoChain
from whexar.bus.emulator.port import EmulatedPort
from whexar.bus.field import (
    STALE_AFTER_S,
    Answered,
    FieldBus,
    Silent,
    Written,
    decode,
)
from whexar.bus.protocol import Instruction, Packet
from whexar.bus.sdk import DxlBus, tap_port
from whexar.config import RobotConfig
from whexar.robot import JOINT_NAMES
from whexar.runtime.devices import DEVICES
from whexar.runtime.harness import RunResult, run_actors
from whexar.testing.bus import bus_graph, servo_chain

Events = list[tuple[str, float, bytes]]

CFG = RobotConfig()
MODELS = CFG.servos()
MX = model("MX-64")
POSITION = MX.register("present_position")
TORQUE = MX.register("torque_enable")
HARDWARE_ERROR = MX.register("hardware_error_status")
GOAL = MX.register("goal_position")
WIGGLE = {"amplitude_rad": 0.3, "frequency_hz": 1.0}
CYCLIC = {
    leg.servo_ids[JOINT_NAMES.index(joint)]
    for leg in CFG.legs
    for joint in ("coxa", "femur", "tibia", "tarsus")
}
"""The servos whose positions the ``default`` plan reads every cycle."""
RECORDED_S = 1.5


# --------------------------------------------------------------------------- recording


class Session:
    """dynamixel-sdk on an emulated chain, its port tapped as a recording taps it, on a
    clock the test moves."""

    def __init__(self, chain: ServoChain) -> None:
        self.chain = chain
        self.t = 0.0
        self.port = EmulatedPort(chain, now=lambda: self.t)
        self.events: Events = []
        tap_port(
            self.port,
            lambda d, t, b: self.events.append((d, t, b)),
            lambda: self.t + self.port.elapsed_s,
        )
        self.bus = DxlBus(self.port)

    def at(self, t: float) -> DxlBus:
        """The bus, once the last calls' bus time has passed and the clock is at ``t``."""
        self.t += self.port.take_elapsed()
        assert t >= self.t
        self.t = t
        return self.bus

    def done(self) -> Events:
        self.port.closePort()  # the last reads are reported once something else happens
        return self.events


def record_bus(duration: float, *, hook: Hook | None = None) -> tuple[Events, RunResult]:
    """A bus scheduler swaying every joint on the emulator for ``duration`` s (virtual
    time): its link's events, as a recording holds them, and what it published."""
    chain = servo_chain()
    if hook is not None:
        chain.hooks.append(hook)
    events: Events = []

    def observe(link: str, direction: str, t: float, data: bytes) -> None:
        if link == "bus":
            events.append((direction, t, bytes(data)))

    with DEVICES.registered(SERVO_CHAIN, "recorded", chain):
        result = run_actors(
            bus_graph("emulator:recorded", wiggle=WIGGLE),
            duration=duration,
            link_observer=observe,
        )
    return events, result


def play(
    events: Iterable[tuple[str, float, bytes]],
    duration: float,
    *,
    params: Mapping[str, Any] | None = None,
    wiggle: Mapping[str, Any] = WIGGLE,
    **options: Any,
) -> tuple[FieldBus, RunResult]:
    """The same graph against ``events`` played back by time (port ``emulator:field``)."""
    bus = FieldBus(events, models=MODELS, baudrate=CFG.bus.baudrate, **options)
    with DEVICES.registered(SERVO_CHAIN, "field", bus.chain):
        result = run_actors(bus_graph("emulator:field", params, wiggle=wiggle), duration=duration)
    return bus, result


@pytest.fixture(scope="module")
def recorded() -> tuple[Events, RunResult]:
    return record_bus(RECORDED_S)


def _positions(states: ServoStates) -> dict[int, float | None]:
    return {j.servo_id: j.position_rad for j in states.joints if j.servo_id in CYCLIC}


def _last_tick(events: Events, sid: int, address: int) -> int:
    """The last value of the 4-byte register at ``address`` the recording gives for ``sid``."""
    ticks = [
        int.from_bytes(data[address - start : address - start + 4], "little", signed=True)
        for f in decode(events)
        if isinstance(f, Answered) and f.servo_id == sid
        for start, data in f.spans
        if start <= address and address + 4 <= start + len(data)
    ]
    return ticks[-1]


# --------------------------------------------------------------------------- decoding


def test_a_recorded_exchange_decodes_into_answers_silences_and_writes() -> None:
    chain = servo_chain()
    chain.faults.silent_until = {9: math.inf}
    chain.servos[4].raise_error(HardwareError.OVERLOAD)
    chain.servos[5].set_state(1234)
    s = Session(chain)
    goal = s.bus.prepare_sync_write(GOAL.address, 4, {3: (2100).to_bytes(4, "little")})
    assert s.at(0.1).ping(8).ok
    assert not s.at(0.2).ping(9).ok
    read = s.at(0.3).sync_read([4, 5, 9, 10], POSITION.address, 4, then=[goal])
    assert read.failed == 9
    assert s.at(0.4).read(4, HARDWARE_ERROR).value == HardwareError.OVERLOAD
    facts = list(decode(s.done()))

    answers = {(f.servo_id, round(f.t, 1)): f for f in facts if isinstance(f, Answered)}
    ping = answers[8, 0.1]
    number = model(MODELS[8]).model_number
    assert dict(ping.spans)[0] == number.to_bytes(2, "little")  # Model Number (0)
    assert [(f.servo_id, round(f.t, 1)) for f in facts if isinstance(f, Silent)] == [
        (9, 0.2),  # the ping waited for it in vain
        (9, 0.3),  # so did the sync read, which read servo 10 on the way
    ]
    assert dict(answers[5, 0.3].spans) == {POSITION.address: (1234).to_bytes(4, "little")}
    assert (10, 0.3) in answers
    assert answers[4, 0.3].error & 0x80  # the Alert bit of every status of an overloaded servo
    assert dict(answers[4, 0.4].spans) == {HARDWARE_ERROR.address: bytes((0x20,))}
    written = [f for f in facts if isinstance(f, Written)]
    assert [(w.servo_id, w.instruction, w.start, w.data) for w in written] == [
        (3, Instruction.SYNC_WRITE, GOAL.address, (2100).to_bytes(4, "little"))
    ]
    # An answer is stamped when its reply was all there: no earlier than its request.
    sent = [t for d, t, _ in s.events if d == "tx"]
    assert answers[5, 0.3].t >= sent[2]


def test_a_fast_sync_read_decodes_into_each_servos_answer() -> None:
    chain = servo_chain(fast_sync_read=True)
    for sid in (1, 2, 3):
        chain.servos[sid].set_state(2000 + sid)
    s = Session(chain)
    assert s.at(0.1).sync_read([1, 2, 3], POSITION.address, 4, fast=True).ok
    facts = [f for f in decode(s.done()) if isinstance(f, Answered)]
    assert [(f.servo_id, f.fast, dict(f.spans)[POSITION.address]) for f in facts] == [
        (sid, True, (2000 + sid).to_bytes(4, "little")) for sid in (1, 2, 3)
    ]


# --------------------------------------------------------------------------- the servos


def _positions_session() -> Events:
    """Servo 1 read at 2000 at 0.1 s and at 2100 at 0.5 s, its torque read off at both."""
    chain = servo_chain()
    s = Session(chain)
    for t, tick in ((0.1, 2000), (0.5, 2100)):
        chain.servos[1].set_state(tick)
        s.at(t).read(1, POSITION)
        s.bus.read(1, TORQUE)
    return s.done()


def test_the_servos_answer_the_latest_recorded_values_held_between_them() -> None:
    played = FieldBus(_positions_session(), models=MODELS, baudrate=CFG.bus.baudrate)
    s = Session(played.chain)
    assert s.at(0.0).read(1, POSITION).value == 2000  # before the first: the first holds
    assert s.at(0.3).read(1, POSITION).value == 2000
    assert s.at(0.6).read(1, POSITION).value == 2100
    assert s.at(0.5 + STALE_AFTER_S - 0.01).read(1, POSITION).value == 2100
    assert not s.at(0.5 + STALE_AFTER_S + 0.01).ping(1).ok  # stale: it answers no more
    assert played.recording_end is not None
    assert played.stale_servos == {}  # past the recording's end, every servo goes stale
    assert not s.bus.ping(2).ok  # never heard of on the recording: not on its bus


def test_a_setting_holds_what_the_replay_wrote_over_a_later_recorded_read() -> None:
    played = FieldBus(_positions_session(), models=MODELS, baudrate=CFG.bus.baudrate)
    s = Session(played.chain)
    assert s.at(0.2).read(1, TORQUE).value == 0
    assert s.at(0.3).write(1, TORQUE, 1).ok
    assert s.at(0.6).read(1, TORQUE).value == 1  # the robot's read of 0 at 0.5 s came before
    assert played.chain.servos[1].torque_enabled
    mismatch = played.mismatches[0]  # the robot never turned it on
    assert (mismatch.servo_id, mismatch.register, mismatch.recorded, mismatch.written) == (
        1,
        "torque_enable",
        None,
        1,
    )


def _goals_session(goals: Sequence[tuple[float, int]]) -> Events:
    s = Session(servo_chain())
    for t, tick in goals:
        s.at(t).sync_write(GOAL.address, 4, {3: tick.to_bytes(4, "little")})
    return s.done()


def test_a_write_agrees_within_the_span_of_the_goals_recorded_around_it() -> None:
    recorded = [(1.00, 2100), (1.01, 2110), (1.02, 2120), (1.50, 2120), (2.00, 2300), (3.0, 0)]
    played = FieldBus(_goals_session(recorded), models=MODELS, baudrate=CFG.bus.baudrate)
    s = Session(played.chain)
    for t, tick in ((1.005, 2104), (1.015, 2150), (1.025, 2120), (2.5, 2300)):
        s.at(t).sync_write(GOAL.address, 4, {3: tick.to_bytes(4, "little")})
    assert played.writes_compared == 4
    beyond, missed = played.mismatches
    # 2104 lies between the goals recorded around it, 2150 beyond them: it is compared
    # with the one nearest in time.
    assert beyond.t == pytest.approx(1.015)
    assert (beyond.servo_id, beyond.register, beyond.recorded, beyond.written) == (
        3,
        GOAL.name,
        2110,
        2150,
    )
    # At 1.50 s the robot sent 2120 again, which the replay's servo held already: no
    # difference. At 2.00 s it sent 2300, which the replay sent only at 2.5 s: missed then
    # (and at 2.5 s the replay agrees with what the robot's servo held).
    assert missed.t == pytest.approx(2.0, abs=1e-3)
    assert (missed.recorded, missed.written) == (2300, None)
    assert played.mismatch_counts == {"goal_position": 2}


# --------------------------------------------------------------------------- the scheduler


def test_a_replayed_scheduler_reads_the_recorded_positions_at_their_times(
    recorded: tuple[Events, RunResult],
) -> None:
    events, run = recorded
    played, replay = play(events, RECORDED_S)
    assert replay.exit_code == 0
    cycles = replay.messages("state", of=ServoStates)
    assert len(cycles) == len(run.messages("state", of=ServoStates))
    for again, then in zip(cycles, run.messages("state", of=ServoStates), strict=True):
        assert again.t == pytest.approx(then.t, abs=1e-9)
        assert _positions(again) == _positions(then)
    # Every exchange was the recording's, every goal written agrees with it.
    assert played.paced == played.packets == sum(d == "tx" for d, _, _ in events)
    assert played.reused > len(cycles)  # the cycle's reads: answered with the recorded bytes
    assert played.writes_compared > 40 * len(cycles)
    assert played.mismatched == 0
    assert "0 differing" in played.describe()


@pytest.mark.parametrize("pace", [True, False])
def test_on_a_slower_clock_the_positions_read_are_those_recorded_then(
    recorded: tuple[Events, RunResult], pace: bool
) -> None:
    # A robot whose bus is 30 % slower (USB latency): the same bytes, later.
    slower = 1.3
    events, run = recorded
    stretched = [(d, t * slower, b) for d, t, b in events]
    played, replay = play(stretched, RECORDED_S * slower, pace=pace)
    then = [(s.t * slower, _positions(s)) for s in run.messages("state", of=ServoStates)]
    cycle = slower * RECORDED_S / len(then)
    cycles = [s for s in replay.messages("state", of=ServoStates) if s.t > 0.5]
    assert len(cycles) > 0.8 * len(then)  # nothing stalled
    for again in cycles:
        near = [p for t, p in then if again.t - 2 * cycle <= t <= again.t + cycle]
        assert _positions(again) in near, f"t = {again.t:.3f} s"
    assert (played.paced > 0) == pace
    assert played.silenced == {}
    assert played.stale_servos == {}


def test_a_servo_recorded_silent_is_silent_and_the_scheduler_degrades_it() -> None:
    def silence(chain: ServoChain, t: float, packets: Sequence[Packet]) -> None:
        if t >= 0.8:
            chain.faults.silent_until[1] = math.inf

    events, run = record_bus(1.8, hook=silence)
    played, replay = play(events, 1.8)
    assert played.silenced.keys() == {1}
    assert played.silenced[1] == pytest.approx(0.8, abs=0.05)
    recorded = [e.t for e in run.events(ServoDegraded) if e.servo_id == 1]
    replayed = [e.t for e in replay.events(ServoDegraded) if e.servo_id == 1]
    assert len(recorded) == len(replayed) == 1
    assert replayed[0] == pytest.approx(recorded[0], abs=0.02)
    assert "silent as recorded: servo 1 from 0.8" in played.describe()


def test_a_different_goal_is_reported_with_its_register_and_both_values(
    recorded: tuple[Events, RunResult],
) -> None:
    events, _ = recorded
    played, replay = play(events, RECORDED_S, wiggle={**WIGGLE, "amplitude_rad": 0.4})
    assert replay.exit_code == 0
    assert played.mismatched > 100
    first = played.mismatches[0]
    assert first.register == "goal_position"
    assert isinstance(first.recorded, int)
    assert isinstance(first.written, int)
    assert first.recorded != first.written
    assert played.mismatch_counts["goal_position"] == played.mismatched
    assert f"{played.mismatched} differing (goal_position" in played.describe()


def test_past_the_recordings_end_nothing_stalls_and_nothing_raises(
    recorded: tuple[Events, RunResult],
) -> None:
    events, _ = recorded
    played, replay = play(events, RECORDED_S + 2 * STALE_AFTER_S)
    assert replay.exit_code == 0
    assert played.recording_end == pytest.approx(events[-1][1])
    assert played.writes_past_end > 0  # not compared: nothing was recorded then
    assert played.stale_servos == {}  # going stale past the end is no finding
    # The servos went silent a bound after the end: the scheduler's reads failed.
    last = replay.messages("state", of=ServoStates)[-1]
    assert last.t < events[-1][1] + STALE_AFTER_S + 0.1


def test_another_read_plan_gets_the_recorded_values_and_says_which_were_stale(
    recorded: tuple[Events, RunResult],
) -> None:
    # Recorded on the default plan (24 servos' positions each cycle), replayed reading all
    # 42: the others' are the last the robot read of them (at start-up), counted stale.
    events, _ = recorded
    played, replay = play(events, RECORDED_S, params={"plan": "full_feedback"})
    assert replay.events(ServoDegraded) == []  # each answered its health reads meanwhile
    assert played.reads.stale["present_position"] > 0
    assert played.reads.unknown == {}
    held = {
        j.position_rad
        for s in replay.messages("state", of=ServoStates)
        for j in s.joints
        if j.servo_id == 2
    }
    assert held == {ticks_to_rad(_last_tick(events, 2, POSITION.address))}
    # A register no read of the recording covers: the emulator's value, counted unknown.
    plan = {"name": "trajectory", "reads": [{"registers": ["position_trajectory"]}]}
    played, replay = play(events, 0.5, params={"plan": plan})
    assert played.reads.unknown["position_trajectory"] > 0
    assert played.chain.servos[1].register_value("position_trajectory") == CENTER_TICKS
    assert "never recorded" in played.describe()


def test_the_recording_is_read_as_the_replay_goes(recorded: tuple[Events, RunResult]) -> None:
    events, _ = recorded
    read_to = [0.0]

    def reading() -> Iterator[tuple[str, float, bytes]]:
        for event in events:
            read_to[0] = event[1]
            yield event

    # Read ahead by the bound (above the 0.6 s in which the health reads reach each servo).
    played, _ = play(reading(), 0.3, stale_after_s=0.7)
    # 0.3 s replayed, and the park after it: the recording was read that far and no further.
    assert read_to[0] < 0.3 + 0.7 + 0.15 < events[-1][1]
    assert not played.ended
