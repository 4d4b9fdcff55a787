"""The test actors that misbehave on purpose (Flood, Stubborn), Brake, and Pulse's failures."""

from __future__ import annotations

from typing import Any

import pytest

from whexar.runtime.messages import ActorFailed, ActorStopped, Heartbeat
from whexar.runtime.wiring import WiringError, build_graph
from whexar.testing import Braked, run_actors


def one(name: str, cls: str, **params: Any) -> dict[str, Any]:
    return {"name": name, "class": f"whexar.testing:{cls}", "params": params}


def test_flood_publishes_its_count_at_once_then_returns() -> None:
    flood = one("flood", "Flood", count=1000) | {"outputs": {"out": "noise"}}
    result = run_actors(
        {
            "actors": [flood],
            "channels": {"noise": {"message": "Heartbeat", "policy": "queue"}},
        },
        duration=1.0,
    )
    beats = result.messages("noise", of=Heartbeat)
    assert [b.seq for b in beats] == list(range(1000))
    assert {b.t for b in beats} == {0.0}  # it never waited: no time passed
    assert [(e.actor, e.reason, e.t) for e in result.events(ActorStopped)] == [
        ("flood", "returned", 0.0)
    ]


def test_brake_says_when_its_safe_stop_ran_and_only_then() -> None:
    failing = one("flaky", "Pulse", period_s=0.125, fail_after_s=0.25) | {
        "outputs": {"out": "beats"}
    }
    brake = one("brake", "Brake", brake_s=0.125, cleanup_s=0.25)
    spec = {
        "runtime": {"restart": {"max_restarts": 0}, "stop_timeout_s": 0.5},
        "actors": [brake, failing],
        "channels": {"beats": {"message": "Heartbeat", "policy": "latest"}},
    }
    escalated = run_actors(spec, duration=5.0)
    assert [(b.actor, b.t) for b in escalated.events(Braked)] == [("brake", 0.25)]
    assert escalated.events(Braked)[0].reason.startswith("escalation: actor 'flaky' failed")
    # Braked at 0.25, braking until 0.375, then a quarter second of cleanup.
    assert [(e.actor, e.t) for e in escalated.events(ActorStopped)] == [
        ("flaky", 0.25),
        ("brake", 0.625),
    ]
    plain = run_actors({"actors": [brake]}, duration=1.0)
    assert plain.events(Braked) == []


def test_stubborn_shielded_cleanup_is_passed_over_and_outlasts_its_stop() -> None:
    spec = {
        "runtime": {"stop_timeout_s": 0.25},
        "actors": [one("stubborn", "Stubborn", cleanup="shield", cleanup_s=1.0)],
    }
    result = run_actors(spec, duration=1.0)
    (stop,) = result.events(ActorStopped)
    assert (stop.actor, stop.t, stop.timed_out) == ("stubborn", 1.25, True)
    # In process nothing can leave it behind: the run ends with its cleanup.
    assert result.end_time == 2.0


@pytest.mark.parametrize(
    ("how", "error"),
    [
        ("error", "InjectedFailure: p: cannot open"),
        ("SystemExit", "SystemExit: p: cannot open"),
        ("sys.exit", "SystemExit: p: cannot open"),
        ("KeyboardInterrupt", "KeyboardInterrupt: p: cannot open"),
    ],
)
def test_pulse_fails_as_told(how: str, error: str) -> None:
    spec = {
        "runtime": {"restart": {"max_restarts": 0}},
        "actors": [one("p", "Pulse", fail_on_open=True, fail_with=how) | {"outputs": {"out": "b"}}],
        "channels": {"b": {"message": "Heartbeat", "policy": "latest"}},
    }
    (failed,) = run_actors(spec, duration=1.0).events(ActorFailed)
    assert failed.error == error


def test_pulse_refuses_an_unknown_failure_naming_the_key() -> None:
    with pytest.raises(WiringError) as refused:
        build_graph({"actors": [one("p", "Pulse", fail_with="segfault")]})
    assert "actors.p.params.fail_with = 'segfault'" in str(refused.value)
