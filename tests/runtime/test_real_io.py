"""Virtual time refuses real I/O unless the graph or the caller allows it — never silently.

A graph on virtual time that waited on a real device ran away (4,343 virtual
seconds in one second of waiting). Now the virtual loop notices descriptors
and worker threads, and the runtime stops the graph in order and raises
:class:`VirtualTimeRealIOError`. ``RealIO`` (``whexar.testing``) waits on a
worker thread or an OS pipe; the refusal for a pty is in ``test_clock.py``.
"""

from __future__ import annotations

from typing import Any

import pytest

from whexar.runtime.clock import VirtualTimeRealIOError, run
from whexar.runtime.messages import (
    ActorFailed,
    ActorRestarted,
    ActorStopped,
    Heartbeat,
    StopRequested,
)
from whexar.runtime.supervisor import EXIT_CLEAN, Runtime
from whexar.runtime.wiring import build_graph
from whexar.testing import MessageLog, run_actors


def io_graph(real_io_on_virtual_time: bool = False, **io: Any) -> dict[str, Any]:
    """A pulse, then a ``RealIO`` actor, then a sink of the pulse's beats."""
    return {
        "runtime": {
            "real_io_on_virtual_time": real_io_on_virtual_time,
            "restart": {"max_restarts": 3, "delay_s": 0.0625},
        },
        "actors": [
            {
                "name": "heart",
                "class": "whexar.testing:Pulse",
                "params": {"period_s": 0.125},
                "outputs": {"out": "beats"},
            },
            {
                "name": "io",
                "class": "whexar.testing:RealIO",
                "params": io,
                "outputs": {"out": "io"},
            },
            {"name": "tail", "class": "whexar.testing:Sink", "inputs": {"inp": "beats"}},
        ],
        "channels": {
            "beats": {"message": "Heartbeat", "policy": "latest"},
            "io": {"message": "Heartbeat", "policy": "queue"},
        },
    }


def refused(spec: dict[str, Any]) -> tuple[VirtualTimeRealIOError, MessageLog]:
    """Run ``spec`` on virtual time, expecting the refusal; the error and the log.

    No duration: a worker thread is noticed when it first calls back, and
    virtual time may have jumped far meanwhile — the refusal is then the one
    thing that stops the run.
    """
    log = MessageLog()

    async def main() -> int:
        return await Runtime(build_graph(spec), observer=log).run()

    with pytest.raises(VirtualTimeRealIOError) as error:
        run(main, virtual=True, deadlock_after_s=1.0)
    return error.value, log


def test_a_worker_thread_on_virtual_time_is_refused_and_the_graph_stopped_in_order() -> None:
    error, log = refused(io_graph(via="thread"))
    assert "thread 'AnyIO worker thread' called back into the loop" in str(error)
    assert "real_io_on_virtual_time = true under [runtime]" in str(error)
    (request,) = log.events(StopRequested)
    assert request.reason.startswith("refused: real I/O on virtual time (thread 'AnyIO worker")
    assert [e.actor for e in log.events(ActorStopped)] == ["tail", "io", "heart"]


def test_a_descriptor_watched_in_an_actors_task_names_the_actor() -> None:
    error, log = refused(io_graph(via="pipe"))
    assert str(error).startswith("virtual time refuses real I/O: actor 'io': file descriptor")
    assert "(pipe:[" in error.what
    assert "watched for reading" in error.what
    assert [e.actor for e in log.events(ActorStopped)] == ["tail", "io", "heart"]


def test_an_actor_declaring_real_io_is_refused_before_it_opens_anything() -> None:
    error, log = refused(io_graph(via="thread", declare=True))
    assert error.what == "actor 'io': a thread (whexar.testing.RealIO)"
    (failed,) = log.events(ActorFailed)
    assert (failed.actor, failed.phase) == ("io", "start")
    assert failed.error.startswith("VirtualTimeRealIOError: virtual time refuses real I/O")
    # No restart can help: refused at the first failure, before the next actor started.
    assert log.events(ActorRestarted) == []
    assert [e.actor for e in log.events(ActorStopped)] == ["io", "heart"]
    assert all(e.t == 0.0 for e in log.events())


@pytest.mark.parametrize("via", ["thread", "pipe"])
def test_the_graph_may_allow_real_io_on_virtual_time(via: str) -> None:
    result = run_actors(io_graph(real_io_on_virtual_time=True, via=via), duration=0.25)
    assert result.exit_code == EXIT_CLEAN
    assert len(result.messages("io", of=Heartbeat)) >= 1


def test_the_caller_may_allow_real_io_on_virtual_time() -> None:
    result = run_actors(io_graph(via="thread", declare=True), duration=0.25, real_io=True)
    assert result.exit_code == EXIT_CLEAN
    assert len(result.messages("io", of=Heartbeat)) >= 1


def test_run_actors_raises_the_refusal_itself() -> None:
    with pytest.raises(VirtualTimeRealIOError, match="actor 'io': file descriptor"):
        run_actors(io_graph(via="pipe"), duration=1.0)


def test_real_time_needs_no_permission() -> None:
    result = run_actors(io_graph(via="pipe", declare=True), duration=0.05, virtual=False)
    assert result.exit_code == EXIT_CLEAN
    assert result.messages("io", of=Heartbeat)
