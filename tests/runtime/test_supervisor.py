"""The runtime: start order and readiness, supervision, safe stop, shutdown, determinism.

All times below are binary fractions (0.125, 0.0625…), so event times are exact
on virtual time and compared with ``==``.
"""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import textwrap
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

import anyio
import pytest

from whexar.runtime.actor import Actor, ActorParams
from whexar.runtime.clock import run
from whexar.runtime.errors import DeviceUnavailableError
from whexar.runtime.messages import (
    ActorDisabled,
    ActorEscalated,
    ActorFailed,
    ActorReady,
    ActorRestarted,
    ActorStarting,
    ActorStopped,
    Event,
    Heartbeat,
    SafeStop,
    StopRequested,
    message,
)
from whexar.runtime.supervisor import (
    EXIT_CLEAN,
    EXIT_ESCALATED,
    EXIT_UNAVAILABLE,
    Runtime,
    describe,
)
from whexar.runtime.wiring import WiringError, build_graph
from whexar.testing import Harness, MessageLog, RunResult, run_actors

PULSE = "whexar.testing:Pulse"


# --------------------------------------------------------------------------- helpers


@message
class Parked(Event):
    """Emitted by a safe-stop hook or :class:`Parking` when it brings things to rest."""

    who: str
    reason: str


class Parking(Actor):
    """Runs until stopped; its safe stop emits :class:`Parked` and takes ``park_s``."""

    class Params(ActorParams):
        park_s: float = 0.0
        fail: bool = False

    params: Params

    async def run(self) -> None:
        self.ready()
        await anyio.sleep_forever()

    async def safe_stop(self, reason: str) -> None:
        self.emit(Parked(t=self.now(), source=self.name, who=self.name, reason=reason))
        if self.params.fail:
            raise RuntimeError("brakes stuck")
        await self.clock.sleep(self.params.park_s)


class QuitsEarly(Actor):
    """Returns from ``run()`` without ever reporting ready."""

    async def run(self) -> None:
        await self.clock.sleep(0.125)


class Stubborn(Actor):
    """Ready at once; when stopped, cleans up for 2 s ignoring the stop timeout."""

    async def run(self) -> None:
        self.ready()
        try:
            await anyio.sleep_forever()
        finally:
            with anyio.CancelScope(shield=True):
                await self.clock.sleep(2.0)


class FailsOnStop(Actor):
    """Ready at once; its cleanup raises when it is stopped."""

    async def run(self) -> None:
        self.ready()
        try:
            await anyio.sleep_forever()
        finally:
            raise OSError("port already gone")


class Unplugged(Actor):
    """Its device is missing at start (after ready: it was unplugged while running)."""

    class Params(ActorParams):
        after_ready: bool = False

    params: Params

    async def run(self) -> None:
        if self.params.after_ready:
            self.ready()
            await self.clock.sleep(0.25)
        raise DeviceUnavailableError("servo port /dev/ttyUSB7: no such device")


def here(cls: type[Actor]) -> str:
    """The wiring path of an actor class defined in this module."""
    return f"{__name__}:{cls.__name__}"


def actor(name: str, cls: str = PULSE, **params: Any) -> dict[str, Any]:
    """An actor entry; a Pulse publishes on a channel named after itself."""
    spec: dict[str, Any] = {"name": name, "class": cls, "params": params}
    if cls == PULSE:
        spec["outputs"] = {"out": name}
    return spec


def graph(*actors: dict[str, Any], **runtime: Any) -> dict[str, Any]:
    channels = {
        a["name"]: {"message": "Heartbeat", "policy": "latest"} for a in actors if "outputs" in a
    }
    return {"runtime": runtime, "actors": list(actors), "channels": channels}


def lifecycle(result: RunResult | MessageLog) -> list[tuple[str, str, float]]:
    """(event type, actor, time) of every start/ready/stop event."""
    kinds = (ActorStarting, ActorReady, ActorStopped)
    return [
        (type(e).__name__, e.actor, e.t)
        for e in result.events()
        if isinstance(e, kinds)  # all of these have an actor
    ]


def stopped(result: RunResult | MessageLog) -> list[tuple[str, str, float]]:
    return [(e.actor, e.reason, e.t) for e in result.events(ActorStopped)]


# --------------------------------------------------------------------------- start and ready


def test_actors_start_in_graph_order_each_after_the_previous_is_ready() -> None:
    result = run_actors(
        graph(actor("a", open_s=0.25), actor("b", open_s=0.5), actor("c", open_s=0.125)),
        duration=2.0,
    )
    assert lifecycle(result)[:6] == [
        ("ActorStarting", "a", 0.0),
        ("ActorReady", "a", 0.25),
        ("ActorStarting", "b", 0.25),
        ("ActorReady", "b", 0.75),
        ("ActorStarting", "c", 0.75),
        ("ActorReady", "c", 0.875),
    ]
    assert result.started == ["a", "b", "c"]
    assert result.exit_code == EXIT_CLEAN
    assert result.stop_reason == "duration 2 s elapsed"
    assert result.end_time == 2.0


def test_an_actor_that_never_reports_ready_fails_its_start() -> None:
    result = run_actors(
        graph(
            actor("a"),
            actor("slow", open_s=1.0),
            actor("c"),
            ready_timeout_s=0.5,
            restart={"max_restarts": 0},
        ),
        duration=5.0,
    )
    failed = result.events(ActorFailed)
    assert [(f.actor, f.incarnation, f.phase, f.error, f.t) for f in failed] == [
        ("slow", 0, "start", "did not report ready within 0.5 s", 0.5)
    ]
    assert result.exit_code == EXIT_ESCALATED
    # "c" never started, so nothing waits for it or reports it stopped.
    assert result.started == ["a"]
    assert "c" not in {e.actor for e in result.events(ActorStarting)}
    assert stopped(result) == [("slow", "escalated", 0.5), ("a", "stop", 0.5)]
    assert result.end_time == 0.5


def test_run_returning_before_ready_is_a_start_failure() -> None:
    result = run_actors(
        graph(actor("q", here(QuitsEarly)), restart={"max_restarts": 1, "delay_s": 0.0625}),
        duration=5.0,
    )
    failed = result.events(ActorFailed)
    assert [(f.incarnation, f.phase, f.error, f.t) for f in failed] == [
        (0, "start", "run() returned before reporting ready", 0.125),
        (1, "start", "run() returned before reporting ready", 0.3125),
    ]
    assert result.exit_code == EXIT_ESCALATED
    assert result.started == []


def test_an_actor_that_returns_after_ready_just_ends() -> None:
    result = run_actors(graph(actor("a", period_s=0.125, count=3), actor("b")), duration=1.0)
    assert result.events(ActorFailed) == []
    assert stopped(result) == [("a", "returned", 0.375), ("b", "stop", 1.0)]
    assert len(result.messages("a", of=Heartbeat)) == 3
    assert result.exit_code == EXIT_CLEAN


def test_a_stop_during_start_leaves_later_actors_unstarted() -> None:
    result = run_actors(graph(actor("a"), actor("b", open_s=3.0), actor("c")), duration=1.0)
    assert result.started == ["a"]
    assert stopped(result) == [("b", "stop", 1.0), ("a", "stop", 1.0)]
    assert result.end_time == 1.0


# --------------------------------------------------------------------------- supervision


RESTART = {"max_restarts": 2, "window_s": 10.0, "delay_s": 0.0625}


def test_restart_then_escalation() -> None:
    result = run_actors(
        graph(
            actor("first"),
            actor("flaky", period_s=0.125, fail_after_s=0.25),
            actor("last"),
            restart=RESTART,
        ),
        duration=5.0,
    )
    failed = result.events(ActorFailed)
    assert [(f.actor, f.incarnation, f.phase, f.t) for f in failed] == [
        ("flaky", 0, "run", 0.25),
        ("flaky", 1, "run", 0.5625),
        ("flaky", 2, "run", 0.875),
    ]
    assert all(f.error.startswith("InjectedFailure: flaky: failed at cycle 2") for f in failed)
    restarted = result.events(ActorRestarted)
    # Each restart comes delay_s after the failure, numbered and counted.
    assert [(r.incarnation, r.failures, r.t) for r in restarted] == [
        (1, 1, 0.3125),
        (2, 2, 0.625),
    ]
    starting = [(e.incarnation, e.t) for e in result.events(ActorStarting) if e.actor == "flaky"]
    assert starting == [(0, 0.0), (1, 0.3125), (2, 0.625)]
    (escalated,) = result.events(ActorEscalated)
    assert (escalated.actor, escalated.failures, escalated.window_s, escalated.t) == (
        "flaky",
        3,
        10.0,
        0.875,
    )
    (safe,) = result.events(SafeStop)
    assert safe.t == 0.875
    assert result.exit_code == EXIT_ESCALATED == 3
    assert result.stop_reason is not None
    assert result.stop_reason.startswith("escalation: actor 'flaky' failed 3 times within 10 s")
    # The escalated actor is down; the others stop newest first, after the safe stop.
    assert stopped(result) == [
        ("flaky", "escalated", 0.875),
        ("last", "stop", 0.875),
        ("first", "stop", 0.875),
    ]
    kinds = [type(e).__name__ for e in result.events()][-6:]
    assert kinds == [
        "ActorEscalated",
        "StopRequested",
        "ActorStopped",
        "SafeStop",
        "ActorStopped",
        "ActorStopped",
    ]


def test_an_actor_whose_policy_says_disable_stays_down_and_the_run_goes_on() -> None:
    flaky = actor("flaky", period_s=0.125, fail_after_s=0.25)
    flaky["restart"] = {**RESTART, "exhausted": "disable"}
    result = run_actors(
        graph(actor("first", period_s=0.5), flaky, actor("last", period_s=0.5)), duration=5.0
    )
    (disabled,) = result.events(ActorDisabled)
    assert (disabled.actor, disabled.failures, disabled.t) == ("flaky", 3, 0.875)
    assert disabled.error.startswith("InjectedFailure: flaky: failed at cycle 2")
    assert result.events(ActorEscalated) == []
    assert result.events(SafeStop) == []
    assert result.exit_code == EXIT_CLEAN
    # The others ran to the end of the run; the disabled actor was never started again.
    assert stopped(result) == [
        ("flaky", "disabled", 0.875),
        ("last", "stop", 5.0),
        ("first", "stop", 5.0),
    ]
    assert max(m.t for m in result.messages("last", of=Heartbeat)) >= 4.5
    assert max(e.incarnation for e in result.events(ActorStarting) if e.actor == "flaky") == 2


def test_a_restart_policy_with_an_unknown_exhaustion_is_refused() -> None:
    flaky = actor("flaky")
    flaky["restart"] = {"exhausted": "ignore"}
    with pytest.raises(WiringError, match="exhausted"):
        run_actors(graph(flaky), duration=1.0)


def test_a_device_unavailable_at_start_stops_the_run_without_restarts() -> None:
    result = run_actors(
        graph(actor("first"), actor("bus", here(Unplugged)), actor("last"), restart=RESTART),
        duration=5.0,
    )
    (failed,) = result.events(ActorFailed)
    assert (failed.actor, failed.phase, failed.traceback) == ("bus", "start", "")
    assert "no such device" in failed.error
    assert not result.events(ActorRestarted)
    assert not result.events(ActorEscalated)
    assert result.exit_code == EXIT_UNAVAILABLE == 4
    assert result.stop_reason == (
        "device unavailable: actor 'bus': servo port /dev/ttyUSB7: no such device"
    )
    # The run stops where it is: the actor after the missing device never starts.
    assert [e.actor for e in result.events(ActorStarting)] == ["first", "bus"]


def test_a_device_lost_while_running_is_restarted_as_any_failure() -> None:
    result = run_actors(
        graph(actor("bus", here(Unplugged), after_ready=True), restart=RESTART), duration=5.0
    )
    failed = result.events(ActorFailed)
    assert len(failed) == 3  # the restart policy's, then escalation
    assert failed[0].phase == "run"
    assert failed[0].traceback  # after ready, the runtime cannot tell it from a bug
    assert result.exit_code == EXIT_ESCALATED


def test_an_actor_that_heals_is_not_escalated() -> None:
    result = run_actors(
        graph(
            actor("a", period_s=0.125, fail_after_s=0.25, heal_at_s=0.75),
            actor("b"),
            restart=RESTART,
        ),
        duration=2.0,
    )
    assert [f.t for f in result.events(ActorFailed)] == [0.25, 0.5625]
    assert [(r.incarnation, r.t) for r in result.events(ActorRestarted)] == [
        (1, 0.3125),
        (2, 0.625),
    ]
    assert result.events(ActorEscalated) == []
    assert result.exit_code == EXIT_CLEAN
    # The third incarnation keeps publishing to the end.
    assert result.messages("a", of=Heartbeat)[-1].t >= 2.0 - 0.125


def test_failures_spread_wider_than_the_window_do_not_escalate() -> None:
    result = run_actors(
        graph(
            actor("a", period_s=0.125, fail_after_s=0.75),
            restart={"max_restarts": 1, "window_s": 0.5, "delay_s": 0.0625},
        ),
        duration=3.0,
    )
    assert [f.t for f in result.events(ActorFailed)] == [0.75, 1.5625, 2.375]
    assert [r.failures for r in result.events(ActorRestarted)] == [1, 1, 1]
    assert result.events(ActorEscalated) == []
    assert result.exit_code == EXIT_CLEAN


def test_a_per_actor_restart_policy_overrides_the_default() -> None:
    flaky = actor("a", period_s=0.125, fail_after_s=0.75)
    flaky["restart"] = {"max_restarts": 0}
    result = run_actors(
        graph(flaky, restart={"max_restarts": 5, "window_s": 0.5}),
        duration=3.0,
    )
    assert [(e.actor, e.failures, e.window_s) for e in result.events(ActorEscalated)] == [
        ("a", 1, 10.0)
    ]


def test_a_failure_on_open_is_retried_and_holds_back_the_next_actor() -> None:
    result = run_actors(
        graph(
            actor("dev", open_s=0.125, fail_on_open=True, heal_at_s=0.25),
            actor("user"),
            restart=RESTART,
        ),
        duration=1.0,
    )
    failed = result.events(ActorFailed)
    assert [(f.actor, f.phase, f.error, f.t) for f in failed] == [
        ("dev", "start", "InjectedFailure: dev: cannot open", 0.125)
    ]
    assert lifecycle(result)[:5] == [
        ("ActorStarting", "dev", 0.0),
        ("ActorStarting", "dev", 0.1875),
        ("ActorReady", "dev", 0.3125),
        ("ActorStarting", "user", 0.3125),
        ("ActorReady", "user", 0.3125),
    ]
    assert result.exit_code == EXIT_CLEAN
    assert result.started == ["dev", "user"]


def test_a_failure_on_open_that_persists_escalates_during_start() -> None:
    result = run_actors(
        graph(
            actor("a"),
            actor("dev", open_s=0.125, fail_on_open=True),
            actor("c"),
            restart={"max_restarts": 1, "delay_s": 0.0625},
        ),
        duration=5.0,
    )
    assert [f.t for f in result.events(ActorFailed)] == [0.125, 0.3125]
    assert result.exit_code == EXIT_ESCALATED
    assert stopped(result) == [("dev", "escalated", 0.3125), ("a", "stop", 0.3125)]


@pytest.mark.parametrize(
    ("how", "error"),
    [
        ("SystemExit", "SystemExit: flaky: failed at cycle 2"),
        ("sys.exit", "SystemExit: flaky: failed at cycle 2"),
        ("KeyboardInterrupt", "KeyboardInterrupt: flaky: failed at cycle 2"),
    ],
)
def test_what_would_end_a_program_is_an_actors_failure_not_an_exit(how: str, error: str) -> None:
    # Before, SystemExit and KeyboardInterrupt went through the supervisor and
    # ended the whole run (and this test's process).
    result = run_actors(
        graph(
            actor("first"),
            actor("flaky", period_s=0.125, fail_after_s=0.25, fail_with=how),
            restart=RESTART,
        ),
        duration=5.0,
    )
    failed = result.events(ActorFailed)
    assert [(f.actor, f.phase, f.error, f.t) for f in failed] == [
        ("flaky", "run", error, 0.25),
        ("flaky", "run", error, 0.5625),
        ("flaky", "run", error, 0.875),
    ]
    assert len(result.events(ActorRestarted)) == 2
    assert [e.actor for e in result.events(ActorEscalated)] == ["flaky"]
    assert result.exit_code == EXIT_ESCALATED
    assert stopped(result) == [
        ("flaky", "escalated", 0.875),
        ("first", "stop", 0.875),
    ]


def test_a_failure_carries_its_traceback_and_keeps_its_one_line_error() -> None:
    once = {"max_restarts": 0}
    result = run_actors(
        graph(actor("flaky", period_s=0.125, fail_after_s=0.25), restart=once), duration=5.0
    )
    (flaky,) = result.events(ActorFailed)
    assert flaky.error == "InjectedFailure: flaky: failed at cycle 2"
    lines = flaky.traceback.splitlines()
    assert lines[0] == "Traceback (most recent call last):"
    assert lines[-1] == "whexar.testing.actors.InjectedFailure: flaky: failed at cycle 2"
    assert any('whexar/testing/actors.py", line' in line and "in run" in line for line in lines)
    assert "raise InjectedFailure(text)" in flaky.traceback  # the line that raised
    # A failure that raised nothing has no traceback.
    result = run_actors(
        graph(actor("slow", open_s=1.0), ready_timeout_s=0.5, restart=once), duration=5.0
    )
    (slow,) = result.events(ActorFailed)
    assert (slow.actor, slow.error, slow.traceback) == (
        "slow",
        "did not report ready within 0.5 s",
        "",
    )


def _escalate_with_hooks(log: MessageLog, *hooks: Callable[[str], Awaitable[None]]) -> int:
    """A parked arm and an actor that escalates at 0.5 s, with ``hooks`` for the safe stop."""
    spec = graph(
        actor("arm", here(Parking)),
        actor("flaky", period_s=0.125, fail_after_s=0.5),
        restart={"max_restarts": 0},
    )

    async def main() -> int:
        runtime = Runtime(build_graph(spec), observer=log, safe_stop_hooks=list(hooks))
        return await runtime.run(duration=5.0)

    return run(main, virtual=True, deadlock_after_s=1.0)


def test_a_safe_stop_hook_or_actor_raising_system_exit_is_reported_and_the_rest_runs() -> None:
    log = MessageLog()
    ran: list[str] = []

    async def quits(reason: str) -> None:
        ran.append("quits")
        raise SystemExit("hook gave up")

    async def good(reason: str) -> None:
        ran.append("good")

    assert _escalate_with_hooks(log, quits, good) == EXIT_ESCALATED
    assert ran == ["quits", "good"]
    (hook,) = [f for f in log.events(ActorFailed) if f.phase == "safe_stop"]
    assert hook.error.endswith("quits: SystemExit: hook gave up")
    assert "SystemExit: hook gave up" in hook.traceback
    assert [p.who for p in log.events(Parked)] == ["arm"]


def test_the_stop_bound_is_the_sum_of_its_bounded_steps() -> None:
    bounds: list[tuple[float, float]] = []
    spec = graph(
        actor("a"),
        actor("b", here(Parking)),
        actor("flaky", period_s=0.125, fail_after_s=0.5),
        stop_timeout_s=0.25,
        restart={"max_restarts": 0},
    )
    runtime: Runtime

    async def hook(reason: str) -> None:
        bounds.append((runtime.stop_bound_s(), runtime.safe_stop_bound_s()))

    runtime = Runtime(build_graph(spec), safe_stop_hooks=[hook, hook])
    # Before the run: one stop step per actor.
    assert runtime.stop_bound_s() == 3 * 0.25
    assert run(runtime.run, virtual=True, deadlock_after_s=1.0) == EXIT_ESCALATED
    # Escalated: two hooks and three actors' safe stops come first.
    assert bounds == [((2 + 3 + 3) * 0.25, (2 + 3) * 0.25)] * 2


# --------------------------------------------------------------------------- safe stop


def run_with_hooks(spec: dict[str, Any], duration: float) -> tuple[int, MessageLog, list[str]]:
    """Run ``spec`` under a Runtime with one safe-stop hook that takes 0.125 s."""
    log = MessageLog()
    reasons: list[str] = []

    async def main() -> int:
        runtime: Runtime

        async def hook(reason: str) -> None:
            reasons.append(reason)
            clock = runtime.clock
            runtime.emit(Parked(t=clock.now(), source="hook", who="hook", reason=reason))
            await clock.sleep(0.125)

        runtime = Runtime(build_graph(spec), observer=log, safe_stop_hooks=[hook])
        return await runtime.run(duration=duration)

    code = run(main, virtual=True, deadlock_after_s=1.0)
    return code, log, reasons


def test_safe_stop_runs_hooks_then_actors_newest_first_before_any_stop() -> None:
    spec = graph(
        actor("arm", here(Parking), park_s=0.25),
        actor("flaky", period_s=0.125, fail_after_s=0.5),
        actor("leg", here(Parking), park_s=0.25),
        restart={"max_restarts": 0},
    )
    code, log, reasons = run_with_hooks(spec, duration=5.0)
    assert code == EXIT_ESCALATED
    after = [e for e in log.events() if e.t >= 0.5]
    assert [(type(e).__name__, getattr(e, "who", getattr(e, "actor", "")), e.t) for e in after] == [
        ("ActorFailed", "flaky", 0.5),
        ("ActorEscalated", "flaky", 0.5),
        ("StopRequested", "", 0.5),
        ("ActorStopped", "flaky", 0.5),
        ("SafeStop", "", 0.5),
        ("Parked", "hook", 0.5),
        ("Parked", "leg", 0.625),
        ("Parked", "arm", 0.875),
        ("ActorStopped", "leg", 1.125),
        ("ActorStopped", "arm", 1.125),
    ]
    (safe,) = log.events(SafeStop)
    assert reasons == [safe.reason]
    assert all(p.reason == safe.reason for p in log.events(Parked))
    assert "flaky" in safe.reason


def test_safe_stop_is_bounded_and_a_failing_one_is_reported() -> None:
    spec = graph(
        actor("slow", here(Parking), park_s=10.0),
        actor("broken", here(Parking), fail=True),
        actor("flaky", period_s=0.125, fail_after_s=0.5),
        stop_timeout_s=0.25,
        restart={"max_restarts": 0},
    )
    code, log, _ = run_with_hooks(spec, duration=5.0)
    assert code == EXIT_ESCALATED
    parked = [(p.who, p.t) for p in log.events(Parked)]
    assert parked == [("hook", 0.5), ("broken", 0.625), ("slow", 0.625)]
    failed = [(f.actor, f.phase, f.error) for f in log.events(ActorFailed)]
    assert ("broken", "safe_stop", "RuntimeError: brakes stuck") in failed
    # The slow safe stop was cut after stop_timeout_s; then the actors stopped.
    assert [(e.actor, e.t) for e in log.events(ActorStopped)] == [
        ("flaky", 0.5),
        ("broken", 0.875),
        ("slow", 0.875),
    ]


def test_a_failing_hook_does_not_skip_the_rest_of_the_safe_stop() -> None:
    log = MessageLog()
    ran: list[str] = []

    async def broken(reason: str) -> None:
        ran.append("broken")
        raise OSError("bus unplugged")

    async def good(reason: str) -> None:
        ran.append("good")

    assert _escalate_with_hooks(log, broken, good) == EXIT_ESCALATED
    assert ran == ["broken", "good"]
    hook_failures = [(f.actor, f.phase, f.error) for f in log.events(ActorFailed) if f.t == 0.5]
    assert hook_failures[-1][0] == "runtime"
    assert hook_failures[-1][1] == "safe_stop"
    assert "OSError: bus unplugged" in hook_failures[-1][2]
    assert [p.who for p in log.events(Parked)] == ["arm"]
    assert [(e.actor, e.reason) for e in log.events(ActorStopped)] == [
        ("flaky", "escalated"),
        ("arm", "stop"),
    ]


def test_no_safe_stop_without_an_escalation() -> None:
    spec = graph(actor("arm", here(Parking)), actor("p"))
    code, log, reasons = run_with_hooks(spec, duration=1.0)
    assert code == EXIT_CLEAN
    assert reasons == []
    assert log.events(SafeStop) == []
    assert log.events(Parked) == []


# --------------------------------------------------------------------------- shutdown


def test_sigterm_stops_the_actors_in_reverse_start_order() -> None:
    spec = graph(
        actor("a", open_s=0.125),
        actor("b", open_s=0.25, cleanup_s=0.375),
        actor("c", open_s=0.0625),
        stop_timeout_s=1.0,
    )

    async def scenario(h: Harness) -> None:
        await h.sleep_until(1.0)
        os.kill(os.getpid(), signal.SIGTERM)
        await h.wait_for(StopRequested)

    result = run_actors(spec, scenario=scenario, handle_signals=True)
    assert result.exit_code == EXIT_CLEAN
    (request,) = result.events(StopRequested)
    assert "SIGTERM" in request.reason
    assert request.t == 1.0
    assert result.stop_reason == "signal SIGTERM"
    # b's shielded cleanup holds back a's stop by exactly its cleanup time.
    assert stopped(result) == [("c", "stop", 1.0), ("b", "stop", 1.375), ("a", "stop", 1.375)]
    assert not any(e.timed_out for e in result.events(ActorStopped))


def test_a_cleanup_longer_than_the_stop_timeout_is_cut_short() -> None:
    result = run_actors(
        graph(actor("a"), actor("b", cleanup_s=5.0), actor("c"), stop_timeout_s=0.5),
        duration=1.0,
    )
    assert stopped(result) == [("c", "stop", 1.0), ("b", "stop", 1.5), ("a", "stop", 1.5)]
    assert [e.timed_out for e in result.events(ActorStopped)] == [False, True, False]
    assert result.end_time == 1.5


def test_an_actor_overrunning_its_stop_timeout_is_reported_and_passed_over() -> None:
    result = run_actors(
        graph(actor("a"), actor("stubborn", here(Stubborn)), actor("c"), stop_timeout_s=0.5),
        duration=1.0,
    )
    events = [(e.actor, e.t, e.timed_out) for e in result.events(ActorStopped)]
    # Reported once, at the timeout; "a" is stopped then, without waiting for it.
    assert events == [("c", 1.0, False), ("stubborn", 1.5, True), ("a", 1.5, False)]


def test_a_failure_while_stopping_is_reported_but_neither_restarted_nor_escalated() -> None:
    result = run_actors(
        graph(
            actor("a"),
            actor("brittle", here(FailsOnStop)),
            restart={"max_restarts": 0, "window_s": 10.0},
        ),
        duration=1.0,
    )
    assert result.exit_code == EXIT_CLEAN
    (failed,) = result.events(ActorFailed)
    assert (failed.actor, failed.t, failed.error) == ("brittle", 1.0, "OSError: port already gone")
    assert result.events(ActorRestarted) == []
    assert result.events(ActorEscalated) == []
    assert stopped(result) == [("brittle", "stop", 1.0), ("a", "stop", 1.0)]


# --------------------------------------------------------------------------- determinism


def busy_graph(sink_delay_s: float) -> dict[str, Any]:
    return {
        "runtime": {"restart": {"max_restarts": 3, "window_s": 1.0, "delay_s": 0.05}},
        "actors": [
            {
                "name": "pulse",
                "class": PULSE,
                "params": {"period_s": 0.01, "burst": 3, "open_s": 0.02},
                "outputs": {"out": ["beats", "state"]},
            },
            {
                "name": "flaky",
                "class": PULSE,
                "params": {"period_s": 0.03, "fail_after_s": 0.2, "heal_at_s": 0.7},
                "outputs": {"out": "state"},
            },
            {
                "name": "relay",
                "class": "whexar.testing:Relay",
                "inputs": {"inp": "state"},
                "outputs": {"out": "relayed"},
            },
            {
                "name": "sink",
                "class": "whexar.testing:Sink",
                "params": {"delay_s": sink_delay_s},
                "inputs": {"inp": "beats"},
                "outputs": {"seen": "seen"},
            },
            {"name": "tail", "class": "whexar.testing:Sink", "inputs": {"inp": "relayed"}},
        ],
        "channels": {
            "beats": {"message": "Heartbeat", "policy": "queue", "capacity": 4},
            "state": {"message": "Heartbeat", "policy": "latest"},
            "relayed": {"message": "Heartbeat", "policy": "backpressure", "capacity": 2},
            "seen": {"message": "Message", "policy": "queue"},
        },
    }


def test_the_same_graph_gives_the_same_run() -> None:
    first = run_actors(busy_graph(0.007), duration=1.5)
    second = run_actors(busy_graph(0.007), duration=1.5)
    # The run is busy: restarts and drops happened.
    assert len(first.events(ActorRestarted)) >= 2
    assert first.stats["beats"].dropped["sink"] > 0
    assert len(first.log.entries) > 1000
    assert first.digest == second.digest
    assert first.log.lines() == second.log.lines()
    assert first.stats == second.stats


def test_a_different_parameter_gives_a_different_digest() -> None:
    base = run_actors(busy_graph(0.007), duration=1.5)
    changed = run_actors(busy_graph(0.008), duration=1.5)
    assert base.digest != changed.digest


# --------------------------------------------------------------------------- API edges


def test_a_runtime_runs_once_and_has_a_clock_only_while_running() -> None:
    runtime = Runtime(build_graph(graph(actor("a"))))
    with pytest.raises(RuntimeError, match="not running"):
        runtime.clock  # noqa: B018 - the property raises
    runtime.request_stop("before the run: ignored")
    assert runtime.stop_reason is None

    async def main() -> tuple[int, float]:
        code = await runtime.run(duration=0.5)
        with pytest.raises(RuntimeError, match="runs once"):
            await runtime.run(duration=0.5)
        return code, runtime.clock.now()

    assert run(main, virtual=True, deadlock_after_s=1.0) == (EXIT_CLEAN, 0.5)


def test_the_first_stop_reason_is_kept() -> None:
    async def scenario(h: Harness) -> None:
        h.stop("first")
        h.stop("second")

    result = run_actors(graph(actor("a")), scenario=scenario)
    assert result.stop_reason == "first"
    assert [e.reason for e in result.events(StopRequested)] == ["first"]


def test_describe_names_the_first_leaf_of_a_group() -> None:
    assert describe(ValueError("bad")) == "ValueError: bad"
    assert describe(KeyError()) == "KeyError"
    group = ExceptionGroup("outer", [ExceptionGroup("inner", [OSError("gone")])])
    assert describe(group) == "OSError: gone"


# --------------------------------------------------------------------------- real processes


SCRIPT = """
import json
import sys

import anyio

from whexar.runtime.clock import run
from whexar.runtime.messages import ActorStopped
from whexar.runtime.supervisor import Runtime
from whexar.runtime.wiring import build_graph

GRAPH = json.loads({graph!r})


def observer(channel, msg):
    if isinstance(msg, ActorStopped):
        print("stopped", msg.actor, msg.reason, flush=True)


async def main():
    runtime = Runtime(build_graph(GRAPH), observer=observer, handle_signals=True)
    codes = []

    async def go(*, task_status):
        codes.append(await runtime.run(task_status=task_status))

    async with anyio.create_task_group() as tg:
        await tg.start(go)
        print("ready", flush=True)
    return codes[0]


sys.exit(run(main, virtual=False))
"""


def start_script(tmp_path: Path, spec: dict[str, Any]) -> subprocess.Popen[str]:
    script = tmp_path / "run_graph.py"
    script.write_text(textwrap.dedent(SCRIPT).format(graph=json.dumps(spec)))
    return subprocess.Popen(
        [sys.executable, str(script)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def read_line(proc: subprocess.Popen[str], timeout_s: float = 5.0) -> str:
    assert proc.stdout is not None
    readable, _, _ = select.select([proc.stdout], [], [], timeout_s)
    if not readable:
        proc.kill()
        pytest.fail("the runtime process printed nothing in time")
    return proc.stdout.readline().strip()


@pytest.mark.slow
@pytest.mark.serial  # a real process, 5 s of wall time to start and stop
def test_sigterm_to_a_real_process_stops_it_cleanly(tmp_path: Path) -> None:
    spec = graph(actor("a", period_s=0.01), actor("b", period_s=0.01), actor("c", period_s=0.01))
    proc = start_script(tmp_path, spec)
    try:
        assert read_line(proc) == "ready"
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=5.0)
    finally:
        proc.kill()
    assert proc.returncode == EXIT_CLEAN, err
    assert out.splitlines() == ["stopped c stop", "stopped b stop", "stopped a stop"]


@pytest.mark.slow
@pytest.mark.serial  # a real process, 5 s of wall time to start and stop
def test_an_escalation_in_a_real_process_exits_non_zero(tmp_path: Path) -> None:
    spec = graph(
        actor("a", period_s=0.01),
        actor("b", period_s=0.01, fail_after_s=0.05),
        actor("c", period_s=0.01),
        restart={"max_restarts": 0},
    )
    proc = start_script(tmp_path, spec)
    try:
        out, err = proc.communicate(timeout=5.0)
    finally:
        proc.kill()
    assert proc.returncode == EXIT_ESCALATED, err
    assert out.splitlines() == [
        "ready",
        "stopped b escalated",
        "stopped c stop",
        "stopped a stop",
    ]
