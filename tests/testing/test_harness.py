"""whexar.testing: run_actors, the scenario Harness and the MessageLog."""

from __future__ import annotations

import hashlib
from typing import Any

import pytest

from whexar.runtime.messages import (
    ActorReady,
    ActorStarting,
    Event,
    Heartbeat,
    Message,
    StopRequested,
)
from whexar.runtime.wiring import WiringError, build_graph, parse_graph
from whexar.testing import HARNESS, Harness, LogEntry, MessageLog, run_actors

PULSE = "whexar.testing:Pulse"
SINK = "whexar.testing:Sink"
RELAY = "whexar.testing:Relay"


def fed_sink(policy: str = "backpressure", **sink: Any) -> dict[str, Any]:
    """A sink reading channel ``cmd`` (fed from outside) and republishing on ``seen``."""
    return {
        "actors": [
            {
                "name": "sink",
                "class": SINK,
                "params": sink,
                "inputs": {"inp": "cmd"},
                "outputs": {"seen": "seen"},
            }
        ],
        "channels": {
            "cmd": {"message": "Heartbeat", "policy": policy},
            "seen": {"message": "Message", "policy": "queue"},
        },
    }


def pulse_graph(period_s: float = 0.125) -> dict[str, Any]:
    return {
        "actors": [
            {
                "name": "pulse",
                "class": PULSE,
                "params": {"period_s": period_s},
                "outputs": {"out": "beats"},
            },
            {"name": "sink", "class": SINK, "inputs": {"inp": "beats"}},
        ],
        "channels": {"beats": {"message": "Heartbeat", "policy": "latest"}},
    }


def beat(seq: int, t: float = 0.0, source: str = HARNESS) -> Heartbeat:
    return Heartbeat(t=t, source=source, seq=seq)


# --------------------------------------------------------------------------- Harness


def test_feed_publishes_into_the_graph() -> None:
    got: list[tuple[int, float]] = []

    async def scenario(h: Harness) -> None:
        for i in range(3):
            await h.feed("cmd", beat(i, h.now()))
        last = await h.wait_for(Heartbeat, lambda m: m.seq == 2, channel="seen")
        got.append((last.seq, h.now()))

    result = run_actors(fed_sink(delay_s=0.25), feeds=["cmd"], scenario=scenario)
    assert got == [(2, 0.75)]
    assert [m.seq for m in result.messages("cmd", of=Heartbeat)] == [0, 1, 2]
    assert all(m.source == HARNESS for m in result.messages("cmd"))
    assert [m.seq for m in result.messages("seen", of=Heartbeat)] == [0, 1, 2]
    assert result.stop_reason == "scenario finished"
    assert result.end_time == 0.75


def test_feed_needs_the_channel_declared_in_feeds() -> None:
    async def scenario(h: Harness) -> None:
        raise AssertionError("never runs")  # pragma: no cover

    with pytest.raises(WiringError) as info:
        run_actors(fed_sink(), scenario=scenario)
    assert [p.path for p in info.value.problems] == ["channels.cmd"]
    assert "no actor publishes" in info.value.problems[0].allowed


def test_feeding_a_full_backpressure_channel_waits_for_the_subscriber() -> None:
    times: list[float] = []

    async def scenario(h: Harness) -> None:
        for i in range(4):
            await h.feed("cmd", beat(i))
            times.append(h.now())

    graph = fed_sink(start_s=1.0)
    graph["channels"]["cmd"]["capacity"] = 2
    result = run_actors(graph, feeds=["cmd"], scenario=scenario, duration=2.0)
    assert times == [0.0, 0.0, 1.0, 1.0]
    assert result.stats["cmd"].dropped == {"sink": 0}
    assert result.stop_reason == "duration 2 s elapsed"


def test_wait_for_times_out_on_runtime_time() -> None:
    at: list[float] = []

    async def scenario(h: Harness) -> None:
        with pytest.raises(TimeoutError):
            await h.wait_for(StopRequested, timeout=0.5)
        at.append(h.now())

    result = run_actors(pulse_graph(), scenario=scenario)
    assert at == [0.5]
    assert result.end_time == 0.5


def test_wait_for_filters_by_type_predicate_and_channel_and_looks_ahead_only() -> None:
    found: list[Message] = []

    async def scenario(h: Harness) -> None:
        await h.sleep_until(1.0625)  # beats 0..8 are already logged
        found.append(await h.wait_for(Heartbeat))
        fourth: Heartbeat = await h.wait_for(Heartbeat, lambda b: b.seq % 4 == 0, channel="beats")
        found.append(fourth)
        found.append(await h.wait_for(ActorStarting, channel="beats", timeout=0.25))

    with pytest.raises(TimeoutError):
        run_actors(pulse_graph(), scenario=scenario)
    assert [(m.seq, m.t) for m in found if isinstance(m, Heartbeat)] == [(9, 1.125), (12, 1.5)]
    assert len(found) == 2


def test_sleep_and_sleep_until_move_runtime_time() -> None:
    times: list[float] = []

    async def scenario(h: Harness) -> None:
        times.append(h.now())
        await h.sleep(0.25)
        times.append(h.now())
        await h.sleep_until(2.0)
        times.append(h.clock.now())
        h.stop("enough")

    result = run_actors(pulse_graph(), scenario=scenario)
    assert times == [0.0, 0.25, 2.0]
    assert result.stop_reason == "enough"


def test_the_scenario_starts_once_every_actor_is_ready() -> None:
    started_at: list[tuple[float, list[str]]] = []
    graph = pulse_graph()
    graph["actors"][0]["params"]["open_s"] = 0.375

    async def scenario(h: Harness) -> None:
        started_at.append((h.now(), [e.actor for e in h.log.events(ActorReady)]))

    run_actors(graph, scenario=scenario)
    assert started_at == [(0.375, ["pulse", "sink"])]


# --------------------------------------------------------------------------- run_actors


class BoomError(Exception):
    pass


def test_scenario_exceptions_propagate_unwrapped() -> None:
    async def scenario(h: Harness) -> None:
        await h.sleep(0.5)
        raise BoomError("scenario went wrong")

    with pytest.raises(BoomError, match="scenario went wrong") as info:
        run_actors(pulse_graph(), scenario=scenario)
    assert type(info.value) is BoomError


def test_a_failed_assert_in_a_scenario_is_an_assertion_error() -> None:
    async def scenario(h: Harness) -> None:
        assert h.now() == 1.0, "the clock starts at zero"

    with pytest.raises(AssertionError, match="the clock starts at zero"):
        run_actors(pulse_graph(), scenario=scenario)


def test_run_actors_needs_a_duration_or_a_scenario() -> None:
    with pytest.raises(ValueError, match="duration, a scenario, or both"):
        run_actors(pulse_graph())


def test_run_actors_takes_a_mapping_a_spec_or_a_built_graph() -> None:
    data = pulse_graph()
    results = [
        run_actors(data, duration=0.5),
        run_actors(parse_graph(data), duration=0.5),
        run_actors(build_graph(data), duration=0.5),
    ]
    assert len({r.digest for r in results}) == 1
    assert all(r.started == ["pulse", "sink"] and r.end_time == 0.5 for r in results)


def test_with_a_duration_the_run_outlasts_a_short_scenario() -> None:
    async def scenario(h: Harness) -> None:
        await h.sleep(0.25)

    result = run_actors(pulse_graph(), scenario=scenario, duration=1.0)
    assert result.end_time == 1.0
    assert result.stop_reason == "duration 1 s elapsed"


def test_an_actor_can_end_the_run() -> None:
    ring = {
        "actors": [
            {
                "name": "r1",
                "class": RELAY,
                "params": {"start": True},
                "inputs": {"inp": "a"},
                "outputs": {"out": "b"},
            },
            {
                "name": "r2",
                "class": RELAY,
                "params": {"limit": 10},
                "inputs": {"inp": "b"},
                "outputs": {"out": "a"},
            },
        ],
        "channels": {
            "a": {"message": "Heartbeat", "policy": "queue"},
            "b": {"message": "Heartbeat", "policy": "queue"},
        },
    }
    result = run_actors(ring, duration=100.0)
    assert result.stop_reason == "r2: token reached seq 10"
    assert [m.seq for m in result.messages("b", of=Heartbeat)] == [0, 2, 4, 6, 8, 10]
    assert [m.seq for m in result.messages("a", of=Heartbeat)] == [1, 3, 5, 7, 9]
    assert result.end_time == 0.0  # a token ring costs no virtual time


def test_sink_stop_after() -> None:
    graph = pulse_graph()
    graph["actors"][1]["params"] = {"stop_after": 5}
    result = run_actors(graph, duration=100.0)
    assert result.stop_reason == "sink: consumed 5 messages"
    assert result.end_time == 4 * 0.125


# --------------------------------------------------------------------------- MessageLog


def test_message_log_selects_by_channel_and_type() -> None:
    log = MessageLog()
    ready = ActorReady(t=0.0, source="runtime", actor="a", incarnation=0)
    log("beats", beat(0))
    log("events", ready)
    log("other", beat(1))
    log("events", StopRequested(t=1.0, source="runtime", reason="r"))
    assert log.entries[0] == LogEntry("beats", beat(0))
    assert log.messages() == [m.message for m in log.entries]
    assert log.messages("beats") == [beat(0)]
    assert log.messages(of=Heartbeat) == [beat(0), beat(1)]
    assert log.messages("other", of=Event) == []
    assert log.events() == [ready, StopRequested(t=1.0, source="runtime", reason="r")]
    assert log.events(ActorReady) == [ready]


def test_message_log_digest_is_the_hash_of_its_lines() -> None:
    log = MessageLog()
    log("beats", beat(0, 0.5))
    log("beats", beat(1, 0.75))
    assert log.lines() == [
        "beats Heartbeat(t=0.5, source='harness', seq=0)",
        "beats Heartbeat(t=0.75, source='harness', seq=1)",
    ]
    expected = hashlib.sha256("".join(line + "\n" for line in log.lines()).encode()).hexdigest()
    assert log.digest() == expected

    swapped = MessageLog()
    swapped("beats", beat(1, 0.75))
    swapped("beats", beat(0, 0.5))
    assert swapped.digest() != log.digest()
    other_channel = MessageLog()
    other_channel("beat", beat(0, 0.5))
    other_channel("s", beat(1, 0.75))
    assert other_channel.digest() != log.digest()
    assert MessageLog().digest() == hashlib.sha256(b"").hexdigest()


def test_run_result_mirrors_the_log() -> None:
    result = run_actors(pulse_graph(), duration=0.5)
    assert result.digest == result.log.digest()
    assert result.events() == result.log.events()
    assert result.events(ActorReady) == result.log.events(ActorReady)
    assert result.messages("beats", of=Heartbeat) == result.log.messages("beats", of=Heartbeat)
    assert [b.seq for b in result.messages("beats", of=Heartbeat)] == [0, 1, 2, 3, 4]
    assert set(result.stats) == {"beats", "events"}
    assert result.stats["events"].published == len(result.events())


def test_a_scenario_still_waiting_is_cancelled_when_the_run_ends() -> None:
    reached: list[float] = []

    async def scenario(h: Harness) -> None:
        await h.sleep(100.0)  # far beyond the run's duration
        reached.append(h.now())

    result = run_actors(pulse_graph(), duration=1.0, scenario=scenario)
    assert result.exit_code == 0
    assert result.end_time == 1.0
    assert reached == []
