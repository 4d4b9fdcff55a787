"""Fairness in a running graph: a publisher that never waits cannot starve the others.

``Flood`` awaits nothing but ``send``; before fairness it held the event loop
until it was done, so every other actor (and every stop) waited for it. Here
the log shows the others running *while* it floods. Each test is bounded
even without fairness (a finite flood, a duration), so a regression fails
instead of hanging. The real-time half — other actors keep their pace and
SIGINT stops a flood within its bound — is in ``tests/cli/test_run.py``.
"""

from __future__ import annotations

from typing import Any

import pytest

from whexar.runtime.channels import TURN_OPS
from whexar.runtime.messages import ActorStopped, Heartbeat
from whexar.testing import LogEntry, RunResult, run_actors

FLOOD = "whexar.testing:Flood"
SINK = "whexar.testing:Sink"


def flood_graph(policy: str, count: int, capacity: int = 1, **sink: Any) -> dict[str, Any]:
    """A ``Flood`` of ``count`` beats on ``noise``; a ``Sink`` republishes what it reads."""
    return {
        "actors": [
            {
                "name": "flood",
                "class": FLOOD,
                "params": {"count": count},
                "outputs": {"out": "noise"},
            },
            {
                "name": "sink",
                "class": SINK,
                "params": sink,
                "inputs": {"inp": "noise"},
                "outputs": {"seen": "seen"},
            },
        ],
        "channels": {
            "noise": {"message": "Heartbeat", "policy": policy, "capacity": capacity},
            "seen": {"message": "Message", "policy": "queue", "capacity": 100_000},
        },
    }


def since_first(result: RunResult, channel: str) -> list[LogEntry]:
    """The log from the first message published on ``channel``."""
    entries = result.log.entries
    return entries[next(i for i, e in enumerate(entries) if e.channel == channel) :]


def longest_run_of(entries: list[LogEntry], channel: str) -> int:
    """The most consecutive entries published on ``channel``."""
    longest = run = 0
    for entry in entries:
        run = run + 1 if entry.channel == channel else 0
        longest = max(longest, run)
    return longest


def stopped(result: RunResult) -> dict[str, str]:
    return {e.actor: e.reason for e in result.events(ActorStopped)}


@pytest.mark.parametrize(("policy", "capacity"), [("latest", 1), ("queue", 4096)])
def test_a_tight_loop_publisher_lets_its_subscriber_run_meanwhile(
    policy: str, capacity: int
) -> None:
    result = run_actors(flood_graph(policy, 5000, capacity), duration=1.0)
    noise = result.messages("noise", of=Heartbeat)
    seen = result.messages("seen", of=Heartbeat)
    assert [b.seq for b in noise] == list(range(5000))
    # The sink started and read while the flood went on (starting it took the
    # runtime a few turns of the loop), then never more than a turn apart.
    reading = since_first(result, "seen")
    flooded_meanwhile = [e.channel for e in reading].count("noise")
    assert flooded_meanwhile > 5000 - 6 * TURN_OPS
    assert longest_run_of(reading, "noise") <= TURN_OPS
    if policy == "latest":  # it read a fresh value every turn, not only the last one
        assert len(seen) >= flooded_meanwhile // TURN_OPS
    else:
        assert [b.seq for b in seen] == list(range(5000))  # room for all: nothing lost
    assert stopped(result) == {"sink": "stop", "flood": "returned"}


def test_a_stop_gets_through_a_tight_loop_on_virtual_time() -> None:
    # The sink asks to stop after 300 messages; the flood, mid-loop, is
    # cancelled at its next turn instead of finishing its 200,000.
    result = run_actors(flood_graph("queue", 200_000, 256, stop_after=300), duration=1.0)
    assert result.stop_reason == "sink: consumed 300 messages"
    assert stopped(result) == {"sink": "stop", "flood": "stop"}
    assert result.stats["noise"].published < 20_000
    # A loop that never waits lets no virtual time pass: all of it at t = 0.
    assert result.end_time == 0.0


def test_a_loop_of_receive_and_send_on_its_own_channel_is_fair() -> None:
    # A relay reading its own output never finds its inbox empty: its loop
    # waits neither on receive nor on send.
    graph = {
        "actors": [
            {
                "name": "echo",
                "class": "whexar.testing:Relay",
                "params": {"start": True, "limit": 3000},
                "inputs": {"inp": "echo"},
                "outputs": {"out": "echo"},
            },
            {"name": "sink", "class": SINK, "inputs": {"inp": "echo"}, "outputs": {"seen": "seen"}},
        ],
        "channels": {
            "echo": {"message": "Heartbeat", "policy": "latest"},
            "seen": {"message": "Message", "policy": "queue", "capacity": 100_000},
        },
    }
    result = run_actors(graph, duration=1.0)
    assert result.stop_reason == "echo: token reached seq 3000"
    seen = [b.seq for b in result.messages("seen", of=Heartbeat)]
    assert len(seen) >= 2000 // TURN_OPS
    assert seen[0] < 4 * TURN_OPS  # read early on, not only once the loop was over
    assert longest_run_of(since_first(result, "seen"), "echo") <= TURN_OPS


def test_fairness_keeps_a_run_deterministic() -> None:
    first = run_actors(flood_graph("latest", 3000), duration=0.5)
    second = run_actors(flood_graph("latest", 3000), duration=0.5)
    assert first.digest == second.digest
