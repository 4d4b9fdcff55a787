"""Telling systemd: the notes (a plain class), the client on a fake notify socket, and a
graph on virtual time whose loop hangs.

The fake socket is what systemd makes: an AF_UNIX datagram socket whose name is in
``$NOTIFY_SOCKET``; each test reads back the datagrams the client sent.
"""

from __future__ import annotations

import os
import socket
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from whexar.runtime.channels import fan_out
from whexar.runtime.clock import run
from whexar.runtime.messages import ActorReady, Heartbeat, Message, StopRequested
from whexar.runtime.notify import (
    Notifier,
    ServiceNotes,
    service_observer,
    watchdog_period_s,
)
from whexar.runtime.supervisor import Runtime
from whexar.runtime.wiring import EVENTS_CHANNEL, RUNTIME, build_graph


@pytest.fixture
def notify_socket() -> Iterator[tuple[socket.socket, str]]:
    """A bound datagram socket, as systemd's, and its path (short: AF_UNIX caps it at 108)."""
    with tempfile.TemporaryDirectory(prefix="sdn") as folder:
        path = os.path.join(folder, "notify")
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        sock.bind(path)
        sock.setblocking(False)
        try:
            yield sock, path
        finally:
            sock.close()


def received(sock: socket.socket) -> list[str]:
    """Every datagram waiting on ``sock``, in order."""
    out: list[str] = []
    while True:
        try:
            out.append(sock.recv(4096).decode())
        except BlockingIOError:
            return out


def ready(actor: str, t: float = 0.0) -> ActorReady:
    return ActorReady(t=t, source=RUNTIME, actor=actor, incarnation=0)


def beat(t: float) -> Heartbeat:
    return Heartbeat(t=t, source="loop", seq=0)


# --------------------------------------------------------------------------- the period


def test_the_watchdog_period_is_watchdog_usec_for_this_process_only() -> None:
    assert watchdog_period_s({"WATCHDOG_USEC": "2000000"}, 42) == 2.0
    assert watchdog_period_s({"WATCHDOG_USEC": "2000000", "WATCHDOG_PID": "42"}, 42) == 2.0
    assert watchdog_period_s({"WATCHDOG_USEC": "2000000", "WATCHDOG_PID": "7"}, 42) is None
    assert watchdog_period_s({"WATCHDOG_USEC": "0"}, 42) is None
    assert watchdog_period_s({"WATCHDOG_USEC": "soon"}, 42) is None
    assert watchdog_period_s({}, 42) is None


# --------------------------------------------------------------------------- the notes


def notes(watchdog_s: float | None = 1.0) -> ServiceNotes:
    return ServiceNotes(frozenset({"bus", "legs"}), watchdog_s, (Heartbeat,))


def test_ready_waits_for_every_actor_and_is_sent_once() -> None:
    n = notes()
    assert n.observe(0.1, EVENTS_CHANNEL, ready("bus")) == []
    assert n.observe(0.2, "beats", beat(0.2)) == []  # no feed before READY
    assert n.observe(0.3, EVENTS_CHANNEL, ready("bus")) == []  # a restart is not the rest
    assert n.observe(0.4, EVENTS_CHANNEL, ready("legs")) == [
        "READY=1\nSTATUS=running: 2 actors ready"
    ]
    assert n.observe(0.5, EVENTS_CHANNEL, ready("legs", 0.5)) == []


def test_the_watchdog_is_fed_every_half_period_while_cycles_come() -> None:
    n = notes(watchdog_s=1.0)
    n.observe(0.0, EVENTS_CHANNEL, ready("bus"))
    n.observe(0.0, EVENTS_CHANNEL, ready("legs"))
    fed = [t / 100 for t in range(1, 201) if n.observe(t / 100, "beats", beat(t / 100))]
    assert fed == [0.5, 1.0, 1.5, 2.0]
    assert n.cycles == 200


def test_no_cycle_no_feed_and_none_on_other_channels() -> None:
    n = notes(watchdog_s=1.0)
    n.observe(0.0, EVENTS_CHANNEL, ready("bus"))
    n.observe(0.0, EVENTS_CHANNEL, ready("legs"))
    other = Message(t=5.0, source="x")  # not a progress type
    assert n.observe(5.0, "other", other) == []
    assert n.observe(5.0, EVENTS_CHANNEL, beat(5.0)) == []  # events are never progress
    assert n.observe(5.0, "beats", beat(5.0)) == ["WATCHDOG=1"]  # late, but a cycle: feed


def test_without_a_watchdog_cycles_feed_nothing() -> None:
    n = notes(watchdog_s=None)
    n.observe(0.0, EVENTS_CHANNEL, ready("bus"))
    n.observe(0.0, EVENTS_CHANNEL, ready("legs"))
    assert all(n.observe(t, "beats", beat(t)) == [] for t in (1.0, 2.0, 3.0))


def test_a_stop_request_says_stopping_once_and_ends_the_feeds() -> None:
    n = notes(watchdog_s=1.0)
    n.observe(0.0, EVENTS_CHANNEL, ready("bus"))
    n.observe(0.0, EVENTS_CHANNEL, ready("legs"))
    stop = StopRequested(t=1.0, source=RUNTIME, reason="signal SIGTERM")
    assert n.observe(1.0, EVENTS_CHANNEL, stop) == ["STOPPING=1\nSTATUS=stopping: signal SIGTERM"]
    assert n.observe(1.1, EVENTS_CHANNEL, stop) == []
    assert n.observe(9.0, "beats", beat(9.0)) == []  # systemd's stop timeout applies now


def test_a_stop_during_start_up_never_says_ready() -> None:
    n = notes()
    n.observe(0.0, EVENTS_CHANNEL, ready("bus"))
    n.observe(0.1, EVENTS_CHANNEL, StopRequested(t=0.1, source=RUNTIME, reason="signal SIGTERM"))
    assert n.observe(0.2, EVENTS_CHANNEL, ready("legs")) == []


# --------------------------------------------------------------------------- the client


def test_the_client_sends_datagrams_to_notify_socket(
    notify_socket: tuple[socket.socket, str],
) -> None:
    sock, path = notify_socket
    notifier = Notifier({"NOTIFY_SOCKET": path})
    assert notifier.enabled
    assert notifier.send("READY=1")
    assert notifier.send("WATCHDOG=1")
    notifier.close()
    assert received(sock) == ["READY=1", "WATCHDOG=1"]


def test_the_client_reaches_an_abstract_socket() -> None:
    name = f"whexar-test-{os.getpid()}"
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind("\0" + name)
    sock.setblocking(False)
    try:
        notifier = Notifier({"NOTIFY_SOCKET": "@" + name})
        assert notifier.send("STOPPING=1")
        notifier.close()
        assert received(sock) == ["STOPPING=1"]
    finally:
        sock.close()


def test_the_client_is_a_no_op_outside_systemd(tmp_path: Path) -> None:
    quiet = Notifier({})
    assert not quiet.enabled
    assert not quiet.send("READY=1")
    gone = Notifier({"NOTIFY_SOCKET": str(tmp_path / "nobody")})  # no one listens: counted
    assert gone.enabled
    assert not gone.send("READY=1")
    assert gone.failures == 1
    gone.close()
    gone.close()


# --------------------------------------------------------------------------- a run that hangs


HANG_AT_CYCLE = 300
"""The loop's cycle that never ends (at t = 3 s: 100 Hz)."""


def hanging_graph() -> dict[str, Any]:
    """A 100 Hz loop whose cycle 300 takes far longer than the run; a consumer beside it."""
    return {
        "actors": [
            {
                "name": "loop",
                "class": "whexar.testing:Pulse",
                "params": {"period_s": 0.01, "slow_cycles": [HANG_AT_CYCLE], "slow_s": 1000.0},
                "outputs": {"out": "beats"},
            },
            {"name": "tail", "class": "whexar.testing:Sink", "inputs": {"inp": "beats"}},
        ],
        "channels": {"beats": {"message": "Heartbeat", "policy": "latest"}},
    }


def test_a_hung_loop_stops_the_feeds_on_virtual_time(
    notify_socket: tuple[socket.socket, str],
) -> None:
    sock, path = notify_socket
    graph = build_graph(hanging_graph())
    notes = ServiceNotes(frozenset(a.name for a in graph.actors), 1.0, (Heartbeat,))
    notifier = Notifier({"NOTIFY_SOCKET": path})
    sent: list[tuple[float, str]] = []
    runtime: Runtime

    def clock() -> float:
        return runtime.clock.now()

    inner = service_observer(notes, notifier, clock)

    def timed(channel: str, msg: Message) -> None:
        before = notifier.sent
        inner(channel, msg)  # one datagram at most per message
        if notifier.sent > before:
            assert notifier.sent == before + 1
            assert notifier.last is not None
            sent.append((clock(), notifier.last))

    runtime = Runtime(graph, observer=fan_out(timed))

    async def main() -> int:
        return await runtime.run(duration=6.0)

    assert run(main, virtual=True) == 0
    notifier.close()
    assert received(sock) == [text for _, text in sent]
    kinds = [text.split("\n")[0] for _, text in sent]
    assert kinds[0] == "READY=1"
    assert kinds[-1] == "STOPPING=1"
    feeds = [t for t, text in sent if text == "WATCHDOG=1"]
    # Every half period while the loop cycles; the last at its hung cycle, none after.
    assert feeds == pytest.approx([0.5, 1.0, 1.5, 2.0, 2.5, 3.0])
    assert sent[-1][0] == pytest.approx(6.0)  # the run went on; only the loop was stuck
