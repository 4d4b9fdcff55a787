"""Channels: the three overflow policies, per-subscriber buffers, inboxes and outboxes,
and fairness (a turn of port operations per actor)."""

from __future__ import annotations

import asyncio
import itertools
from typing import Any

import anyio
import pytest
from anyio import WouldBlock

from whexar.runtime.channels import (
    DEFAULT_CAPACITY,
    STOP_CHECK_WAITS,
    TURN_OPS,
    Buffer,
    Channel,
    Inbox,
    Outbox,
    Policy,
    Turn,
    capacity_or_default,
)
from whexar.runtime.clock import Clock, run
from whexar.runtime.messages import Heartbeat, Message, TickOverrun
from whexar.testing import run_actors


def beat(seq: int, t: float = 0.0) -> Heartbeat:
    return Heartbeat(t=t, source="test", seq=seq)


def seqs(messages: list[Heartbeat]) -> list[int]:
    return [m.seq for m in messages]


# --------------------------------------------------------------------------- unit level


def test_latest_keeps_the_newest_values_and_counts_drops() -> None:
    ch = Channel("pos", Heartbeat, Policy.LATEST, 1)
    inbox = Inbox("pos", ch.subscribe("reader"))
    for i in range(5):
        ch.send_nowait(beat(i))
    assert seqs(inbox.drain()) == [4]
    stats = ch.stats()
    assert (stats.published, stats.dropped, stats.buffered) == (5, {"reader": 4}, {"reader": 0})

    wide = Channel("pos2", Heartbeat, Policy.LATEST, 3)
    inbox2 = Inbox("pos2", wide.subscribe("reader"))
    for i in range(5):
        wide.send_nowait(beat(i))
    assert seqs(inbox2.drain()) == [2, 3, 4]  # the oldest ones made room
    assert wide.stats().dropped == {"reader": 2}


def test_queue_drops_the_newest_and_never_blocks() -> None:
    ch = Channel("log", Heartbeat, Policy.QUEUE, 2)
    inbox = Inbox("log", ch.subscribe("reader"))

    async def main() -> None:
        for i in range(4):
            await ch.send(beat(i))  # full buffer: returns at once, message dropped

    run(main, virtual=True, deadlock_after_s=1.0)
    assert seqs(inbox.drain()) == [0, 1]
    assert ch.stats().dropped == {"reader": 2}
    assert ch.published == 4


def test_backpressure_send_nowait_refuses_a_full_buffer_for_everyone() -> None:
    observed: list[tuple[str, Message]] = []
    ch = Channel(
        "cmd",
        Heartbeat,
        Policy.BACKPRESSURE,
        1,
        observer=lambda name, msg: observed.append((name, msg)),
    )
    fast = Inbox("cmd", ch.subscribe("fast"))
    slow = Inbox("cmd", ch.subscribe("slow"))
    ch.send_nowait(beat(0))
    assert seqs(fast.drain()) == [0]
    with pytest.raises(WouldBlock):
        ch.send_nowait(beat(1))  # "slow" is still full
    # The refused message reached nobody, and was neither logged nor counted.
    assert fast.drain() == []
    assert seqs(slow.drain()) == [0]
    assert observed == [("cmd", beat(0))]
    stats = ch.stats()
    assert (stats.published, stats.dropped) == (1, {"fast": 0, "slow": 0})


def test_backpressure_send_waits_for_room_and_loses_nothing() -> None:
    ch = Channel("cmd", Heartbeat, Policy.BACKPRESSURE, 2)
    inbox = Inbox("cmd", ch.subscribe("reader"))

    async def main() -> tuple[list[tuple[int, float]], list[int]]:
        clock = Clock()
        sent: list[tuple[int, float]] = []
        got: list[int] = []

        async def publisher() -> None:
            for i in range(5):
                await ch.send(beat(i))
                sent.append((i, clock.now()))

        async def reader() -> None:
            await clock.sleep_until(1.0)
            for _ in range(5):
                got.append((await inbox.receive()).seq)
                await clock.sleep(0.5)

        async with anyio.create_task_group() as tg:
            tg.start_soon(publisher)
            tg.start_soon(reader)
        return sent, got

    sent, got = run(main, virtual=True, deadlock_after_s=1.0)
    assert got == [0, 1, 2, 3, 4]
    # Two fit at once; each further send waits until the reader has taken one.
    assert sent == [(0, 0.0), (1, 0.0), (2, 1.0), (3, 1.5), (4, 2.0)]
    assert ch.stats().dropped == {"reader": 0}


def test_each_subscriber_has_its_own_buffer() -> None:
    ch = Channel("state", Heartbeat, Policy.QUEUE, 2)
    quick = Inbox("state", ch.subscribe("quick"))
    lazy = Inbox("state", ch.subscribe("lazy"))
    for i in range(3):
        ch.send_nowait(beat(i))
        assert quick.receive_nowait().seq == i
    assert seqs(lazy.drain()) == [0, 1]
    assert ch.stats().dropped == {"quick": 0, "lazy": 1}


def test_observer_sees_every_publish_with_the_channel_name() -> None:
    observed: list[tuple[str, Message]] = []
    ch = Channel(
        "x", Heartbeat, Policy.QUEUE, 1, observer=lambda name, msg: observed.append((name, msg))
    )
    ch.subscribe("reader")
    ch.send_nowait(beat(0))
    ch.send_nowait(beat(1))  # dropped for the reader, but it was published
    assert observed == [("x", beat(0)), ("x", beat(1))]


def test_inbox_latest_drain_and_receive_nowait() -> None:
    ch = Channel("q", Heartbeat, Policy.QUEUE, 8)
    inbox = Inbox("q", ch.subscribe("reader"))
    with pytest.raises(WouldBlock):
        inbox.receive_nowait()
    assert inbox.latest() is None
    for i in range(4):
        ch.send_nowait(beat(i))
    assert inbox.receive_nowait().seq == 0
    latest = inbox.latest()
    assert latest is not None
    assert latest.seq == 3
    assert inbox.drain() == []  # latest() consumed the older ones


def test_an_unwired_inbox_is_empty_and_waits_forever() -> None:
    inbox: Inbox[Heartbeat] = Inbox(None, None)
    assert inbox.channel is None
    assert inbox.drain() == []
    assert inbox.latest() is None
    with pytest.raises(WouldBlock):
        inbox.receive_nowait()

    async def main() -> tuple[bool, float]:
        clock = Clock()
        with anyio.move_on_after(3.0) as scope:
            await inbox.receive()
        return scope.cancelled_caught, clock.now()

    assert run(main, virtual=True, deadlock_after_s=1.0) == (True, 3.0)


def test_inbox_iterates_asynchronously() -> None:
    ch = Channel("q", Heartbeat, Policy.QUEUE, 8)
    inbox = Inbox("q", ch.subscribe("reader"))
    for i in range(3):
        ch.send_nowait(beat(i))

    async def main() -> list[int]:
        got: list[int] = []
        async for msg in inbox:
            got.append(msg.seq)
            if len(got) == 3:
                break
        return got

    assert run(main, virtual=True, deadlock_after_s=1.0) == [0, 1, 2]


def test_outbox_publishes_on_every_channel_and_an_empty_one_on_none() -> None:
    a = Channel("a", Heartbeat, Policy.QUEUE, 4)
    b = Channel("b", Heartbeat, Policy.QUEUE, 4)
    in_a = Inbox("a", a.subscribe("r"))
    in_b = Inbox("b", b.subscribe("r"))
    out = Outbox((a, b))

    async def main() -> None:
        await out.send(beat(1))
        out.send_nowait(beat(2))
        empty: Outbox[Heartbeat] = Outbox(())
        await empty.send(beat(3))
        empty.send_nowait(beat(4))

    run(main, virtual=True, deadlock_after_s=1.0)
    assert seqs(in_a.drain()) == [1, 2]
    assert seqs(in_b.drain()) == [1, 2]


def test_default_capacities() -> None:
    assert capacity_or_default(Policy.LATEST, None) == DEFAULT_CAPACITY[Policy.LATEST] == 1
    assert capacity_or_default(Policy.BACKPRESSURE, None) == 16
    assert capacity_or_default(Policy.QUEUE, None) == 256
    assert capacity_or_default(Policy.QUEUE, 7) == 7


# --------------------------------------------------------------------------- in a running graph


def pulse_into_sink(
    policy: str, capacity: int, *, pulse: dict[str, Any], sink: dict[str, Any]
) -> dict[str, Any]:
    return {
        "actors": [
            {
                "name": "pulse",
                "class": "whexar.testing:Pulse",
                "params": pulse,
                "outputs": {"out": "beats"},
            },
            {
                "name": "sink",
                "class": "whexar.testing:Sink",
                "params": sink,
                "inputs": {"inp": "beats"},
                "outputs": {"seen": "seen"},
            },
        ],
        "channels": {
            "beats": {"message": "Heartbeat", "policy": policy, "capacity": capacity},
            "seen": {"message": "Message", "policy": "queue"},
        },
    }


# Eight beats, one every 0.125 s from t = 0; the sink starts reading at 0.5 s and
# takes 0.25 s per message (all times binary fractions, so exact).
PULSE = {"period_s": 0.125, "count": 8}
SLOW_SINK = {"start_s": 0.5, "delay_s": 0.25}


def test_graph_latest_subscriber_sees_only_the_newest() -> None:
    result = run_actors(pulse_into_sink("latest", 1, pulse=PULSE, sink=SLOW_SINK), duration=3.0)
    published = result.messages("beats", of=Heartbeat)
    seen = result.messages("seen", of=Heartbeat)
    assert seqs(published) == list(range(8))
    # At 0.5 the newest is beat 3 (beat 4 is made in the same instant, after the read);
    # each later read takes whatever is newest then.
    assert seqs(seen) == [3, 5, 7]
    stats = result.stats["beats"]
    assert stats.published == 8
    assert stats.dropped == {"sink": 8 - len(seen)}
    assert stats.buffered == {"sink": 0}


def test_graph_queue_drops_the_newest_and_the_publisher_keeps_its_pace() -> None:
    result = run_actors(pulse_into_sink("queue", 3, pulse=PULSE, sink=SLOW_SINK), duration=3.0)
    published = result.messages("beats", of=Heartbeat)
    seen = result.messages("seen", of=Heartbeat)
    # The publisher never waited: every beat on its own grid point, no overrun.
    assert [(m.seq, m.t) for m in published] == [(k, k * 0.125) for k in range(8)]
    assert result.events(TickOverrun) == []
    # The first three were buffered; later ones got in only when there was room.
    assert seqs(seen) == [0, 1, 2, 4, 6]
    assert result.stats["beats"].dropped == {"sink": 3}
    assert len(seen) + result.stats["beats"].dropped["sink"] == 8


def test_graph_backpressure_loses_nothing_and_slows_the_publisher() -> None:
    result = run_actors(
        pulse_into_sink("backpressure", 2, pulse={**PULSE, "burst": 2}, sink=SLOW_SINK),
        duration=6.0,
    )
    published = result.messages("beats", of=Heartbeat)
    seen = result.messages("seen", of=Heartbeat)
    assert seqs(seen) == seqs(published) == list(range(len(published)))
    assert result.stats["beats"].dropped == {"sink": 0}
    # Two beats fit the buffer at t = 0; cycle 1's second beat waits for the sink's
    # first read (0.5) and its second (0.75): the pulse overran and skipped ahead.
    assert [(m.seq, m.t) for m in published] == [
        (0, 0.0),
        (1, 0.0),
        (2, 0.125),
        (3, 0.125),
        (4, 0.75),
        (5, 0.75),
    ]
    overruns = [(o.actor, o.cycle, o.elapsed_s, o.skipped) for o in result.events(TickOverrun)]
    assert overruns == [("pulse", 1, 0.625, 4), ("pulse", 6, 0.5, 3)]


# --------------------------------------------------------------------------- fairness


def test_a_sender_that_never_waits_yields_once_per_turn() -> None:
    async def main() -> list[int]:
        ch = Channel("noise", Heartbeat, Policy.LATEST, 1)
        ch.subscribe("reader")  # latest: a send never has to wait
        out = Outbox((ch,), Turn())
        sent = 0
        others_saw: list[int] = []

        async def other() -> None:
            while sent < 1000:
                others_saw.append(sent)
                await asyncio.sleep(0)

        async with anyio.create_task_group() as tg:
            tg.start_soon(other)
            for i in range(1000):
                await out.send(beat(i))
                sent += 1
        return others_saw

    others_saw = run(main, virtual=True, deadlock_after_s=1.0)
    # The other task ran while the sender was at it, at least once per turn.
    assert others_saw[0] < TURN_OPS
    assert all(b - a <= TURN_OPS for a, b in itertools.pairwise([0, *others_saw, 1000]))


def test_a_receiver_of_a_buffer_that_is_never_empty_yields_once_per_turn() -> None:
    async def main() -> list[int]:
        queue: Buffer[Heartbeat] = Buffer(100_000)
        for i in range(1000):
            queue.put_nowait(beat(i))
        inbox = Inbox("backlog", queue, Turn())
        got = 0
        others_saw: list[int] = []

        async def other() -> None:
            while got < 1000:
                others_saw.append(got)
                await asyncio.sleep(0)

        async with anyio.create_task_group() as tg:
            tg.start_soon(other)
            for _ in range(1000):
                await inbox.receive()
                got += 1
        return others_saw

    others_saw = run(main, virtual=True, deadlock_after_s=1.0)
    assert others_saw[0] < TURN_OPS
    assert all(b - a <= TURN_OPS for a, b in itertools.pairwise([0, *others_saw, 1000]))


def test_an_actor_that_waits_every_half_turn_never_yields_for_fairness() -> None:
    # Ports of one actor share its turn; waiting refills it, so an ordinary
    # actor keeps the interleaving it had before fairness existed.
    async def main() -> list[str]:
        turn = Turn()
        queue: Buffer[Heartbeat] = Buffer(100_000)
        inbox: Inbox[Heartbeat] = Inbox("in", queue, turn)
        out: Outbox[Heartbeat] = Outbox((), turn)
        log: list[str] = []
        done = False

        async def other() -> None:
            while not done:
                log.append("other")
                await asyncio.sleep(0)

        async with anyio.create_task_group() as tg:
            tg.start_soon(other)
            for _ in range(20):
                for i in range(TURN_OPS // 4):
                    queue.put_nowait(beat(i))
                log.append("start")
                for _ in range(TURN_OPS // 4):  # TURN_OPS / 2 operations in all
                    await out.send(await inbox.receive())
                log.append("end")
                await asyncio.sleep(0)  # the actor waits
            done = True
        return log

    log = run(main, virtual=True, deadlock_after_s=1.0)
    assert log.count("end") == 20
    in_batch = False
    for entry in log:
        if entry in ("start", "end"):
            in_batch = entry == "start"
        else:
            assert not in_batch, "the actor yielded for fairness between two waits"


@pytest.mark.usefixtures("hang_guard")
def test_a_stop_gets_through_a_loop_that_awaits_only_send() -> None:
    async def main() -> int:
        out: Outbox[Heartbeat] = Outbox((), Turn())  # unwired: send never has to wait
        sent = 0

        async def flood() -> None:
            nonlocal sent
            while True:
                await out.send(beat(sent))
                sent += 1

        async with anyio.create_task_group() as tg:
            tg.start_soon(flood)
            await anyio.sleep(0)  # the flood starts; this task runs again at its yield
            tg.cancel_scope.cancel()
        return sent

    assert run(main, virtual=True, deadlock_after_s=1.0) == TURN_OPS - 1


def test_a_stop_gets_through_to_the_subscriber_of_a_flooded_channel() -> None:
    # Every wait of the reader ends at once (the flood refills its buffer before
    # anyio delivers the cancellation, which then spares it so as not to lose
    # the message); the reader's own checks let the stop in within a few waits.
    async def main() -> int:
        ch = Channel("noise", Heartbeat, Policy.LATEST, 1)
        inbox = Inbox("noise", ch.subscribe("reader"), Turn())
        out = Outbox((ch,), Turn())
        got = 0

        async def flood() -> None:
            seq = 0
            while True:
                await out.send(beat(seq))
                seq += 1

        async with anyio.create_task_group() as tg:
            tg.start_soon(flood)
            with anyio.CancelScope() as reading:
                while got < 2_000:  # bounded, should the stop never get through
                    await inbox.receive()
                    got += 1
                    if got == 100:
                        reading.cancel()
            tg.cancel_scope.cancel()
        return got

    got = run(main, virtual=True, deadlock_after_s=1.0)
    assert 100 <= got <= 100 + STOP_CHECK_WAITS


# --------------------------------------------------------------------------- the buffer


def _queue_trace(make: Any) -> list[str]:
    """Waiting getters and putters (one cancelled) on a buffer of 2: what each saw, in order."""
    trace: list[str] = []

    async def main() -> None:
        queue = make(2)

        async def getter(name: str) -> None:
            trace.append(f"{name} got {await queue.get()}")

        async def putter(name: str, item: int) -> None:
            await queue.put(item)
            trace.append(f"{name} put {item}")

        tasks = [asyncio.create_task(getter(f"g{k}")) for k in range(3)]
        await asyncio.sleep(0)
        tasks[1].cancel()
        for item in range(7):
            tasks.append(asyncio.create_task(putter(f"p{item}", item)))
        await asyncio.sleep(0)
        for _ in range(3):
            trace.append(f"nowait {queue.get_nowait()}")
            await asyncio.sleep(0)
        try:
            queue.put_nowait(99)
        except asyncio.QueueFull:
            trace.append("full")
        while not queue.empty():
            trace.append(f"drained {queue.get_nowait()}")
            await asyncio.sleep(0)
        await asyncio.gather(*tasks, return_exceptions=True)
        trace.append(f"left {queue.qsize()}")

    asyncio.run(main())
    return trace


def test_a_buffer_wakes_its_waiters_as_asyncio_queue_does() -> None:
    # The buffer slims asyncio's put_nowait/get_nowait: tasks must run in the same order.
    trace = _queue_trace(Buffer)
    assert trace == _queue_trace(asyncio.Queue)
    assert "full" in trace


def test_a_buffer_holds_at_least_one_message_and_counts_no_tasks() -> None:
    with pytest.raises(ValueError, match="at least 1"):
        Channel("x", Heartbeat, Policy.QUEUE, 0).subscribe("reader")
    buffer = Channel("x", Heartbeat, Policy.QUEUE, 1).subscribe("reader")
    with pytest.raises(NotImplementedError):
        buffer.task_done()
