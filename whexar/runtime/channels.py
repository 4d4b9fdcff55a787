"""Channels: named, typed, bounded message streams between actors.

Theory of operation
-------------------
A channel carries one message type from its publishers to its subscribers.
Every subscriber has its own bounded buffer, so a slow subscriber never
delays a fast one except under back-pressure, and a restarted actor finds its
buffer where it left it (the runtime, not the actor, owns the buffers). What
happens when a subscriber's buffer is full is the channel's :class:`Policy`:

* ``latest`` — state (positions, sensor values): the oldest buffered value is
  dropped so the newest always gets in. With capacity 1 a subscriber reads
  the latest value, never a stale one. Drops are counted.
* ``backpressure`` — commands: the publisher waits until the subscriber has
  room. Nothing is lost, so a command channel has exactly one publisher.
* ``queue`` — telemetry: the newest message is dropped and counted; the
  publisher never waits.

Publishing takes the fast path (no checkpoint, no task switch) whenever the
buffer has room; only a full ``backpressure`` buffer suspends the publisher.

Why ``asyncio.Queue`` buffers and not anyio memory object streams
-----------------------------------------------------------------
The runtime is anyio on the asyncio backend (see :mod:`whexar.runtime.clock`),
and cancellation reaches a task waiting on an ``asyncio.Queue`` like any
other await. The buffer is what a hop costs, and it was measured here:
a token passed around a ring of ten tasks costs about 28 µs per hop through
anyio memory object streams (every ``receive`` checkpoints and waits on an
anyio ``Event``), 20 µs when the fast path skips the checkpoint, and 5 µs
through ``asyncio.Queue``. The target is 20 µs per hop through the whole
actor machinery, so the buffers are asyncio queues; the interface keeps
anyio's vocabulary (``send``/``receive``/``*_nowait``, :class:`anyio.WouldBlock`).
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from enum import StrEnum
from typing import Generic, TypeVar

import anyio
from anyio import WouldBlock

from whexar.runtime.messages import Message

M = TypeVar("M", bound=Message)

Observer = Callable[[str, Message], None]
"""Called with the channel name and the message on every publish (the message log)."""


class Policy(StrEnum):
    """What a full subscriber buffer does to the next message (see the module docstring)."""

    LATEST = "latest"
    BACKPRESSURE = "backpressure"
    QUEUE = "queue"


DEFAULT_CAPACITY: dict[Policy, int] = {Policy.LATEST: 1, Policy.BACKPRESSURE: 16, Policy.QUEUE: 256}
"""Buffer size per subscriber when the wiring gives none."""


@dataclass(frozen=True)
class ChannelStats:
    """Counters of one channel: messages published, and per subscriber, drops and backlog."""

    channel: str
    published: int
    dropped: dict[str, int]
    buffered: dict[str, int]


class _Subscription(Generic[M]):
    __slots__ = ("dropped", "queue", "subscriber")

    def __init__(self, subscriber: str, capacity: int) -> None:
        self.subscriber = subscriber
        self.queue: asyncio.Queue[M] = asyncio.Queue(capacity)
        self.dropped = 0


class Channel(Generic[M]):
    """One named channel; made by the runtime from the wiring, one per run."""

    def __init__(
        self,
        name: str,
        message_type: type[M],
        policy: Policy,
        capacity: int,
        *,
        observer: Observer | None = None,
    ) -> None:
        self.name = name
        self.message_type = message_type
        self.policy = policy
        self.capacity = capacity
        self.observer = observer
        self.published = 0
        self._subs: list[_Subscription[M]] = []

    def subscribe(self, subscriber: str) -> asyncio.Queue[M]:
        """A new buffer for ``subscriber``; returns it."""
        sub = _Subscription[M](subscriber, self.capacity)
        self._subs.append(sub)
        return sub.queue

    async def send(self, msg: M) -> None:
        """Publish ``msg`` to every subscriber, applying the channel's policy."""
        if self.policy is not Policy.BACKPRESSURE:
            self.send_nowait(msg)  # latest and queue never wait
            return
        self._count(msg)
        for sub in self._subs:
            if sub.queue.full():
                await sub.queue.put(msg)
            else:
                sub.queue.put_nowait(msg)

    def send_nowait(self, msg: M) -> None:
        """Publish without waiting; a full ``backpressure`` buffer raises :class:`WouldBlock`."""
        backpressure = self.policy is Policy.BACKPRESSURE
        if backpressure and any(s.queue.full() for s in self._subs):
            raise WouldBlock  # checked first, so a refused message reaches nobody
        self._count(msg)
        for sub in self._subs:
            queue = sub.queue
            if queue.full():  # never for backpressure: checked above
                sub.dropped += 1
                if self.policy is Policy.LATEST:
                    queue.get_nowait()
                    queue.put_nowait(msg)
            else:
                queue.put_nowait(msg)

    def _count(self, msg: M) -> None:
        if self.observer is not None:
            self.observer(self.name, msg)
        self.published += 1

    def stats(self) -> ChannelStats:
        """A snapshot of the counters."""
        return ChannelStats(
            channel=self.name,
            published=self.published,
            dropped={s.subscriber: s.dropped for s in self._subs},
            buffered={s.subscriber: s.queue.qsize() for s in self._subs},
        )


class Inbox(Generic[M]):
    """An actor's receiving end of one channel (or of none, for an unwired optional input)."""

    __slots__ = ("_queue", "channel")

    def __init__(self, channel: str | None, queue: asyncio.Queue[M] | None) -> None:
        self.channel = channel
        self._queue = queue

    @property
    def connected(self) -> bool:
        """False for an optional input the wiring left unconnected."""
        return self._queue is not None

    async def receive(self) -> M:
        """The next message, waiting for one if the buffer is empty."""
        queue = self._queue
        if queue is None:
            await anyio.sleep_forever()
            raise AssertionError("unreachable")
        if queue.empty():
            return await queue.get()
        return queue.get_nowait()

    def receive_nowait(self) -> M:
        """The next buffered message; :class:`anyio.WouldBlock` if there is none."""
        if self._queue is None or self._queue.empty():
            raise WouldBlock
        return self._queue.get_nowait()

    def drain(self) -> list[M]:
        """Every buffered message, oldest first, without waiting."""
        return list(self._iter_buffered())

    def latest(self) -> M | None:
        """The newest buffered message (dropping older ones), or ``None``."""
        last: M | None = None
        for last in self._iter_buffered():  # noqa: B007 - only the last one is wanted
            pass
        return last

    def _iter_buffered(self) -> Iterator[M]:
        queue = self._queue
        while queue is not None and not queue.empty():
            yield queue.get_nowait()

    def __aiter__(self) -> Inbox[M]:
        return self

    async def __anext__(self) -> M:
        return await self.receive()


class Outbox(Generic[M]):
    """An actor's publishing end: one or more channels (none for an unwired optional output)."""

    __slots__ = ("channels",)

    def __init__(self, channels: tuple[Channel[M], ...]) -> None:
        self.channels = channels

    @property
    def connected(self) -> bool:
        """False for an optional output the wiring left unconnected (nothing to build)."""
        return bool(self.channels)

    async def send(self, msg: M) -> None:
        """Publish ``msg`` on every wired channel."""
        for channel in self.channels:
            await channel.send(msg)

    def send_nowait(self, msg: M) -> None:
        """Publish without waiting (see :meth:`Channel.send_nowait`)."""
        for channel in self.channels:
            channel.send_nowait(msg)


def capacity_or_default(policy: Policy, capacity: int | None) -> int:
    """The buffer size of a channel: the configured one, else the policy's default."""
    return DEFAULT_CAPACITY[policy] if capacity is None else capacity


__all__ = [
    "DEFAULT_CAPACITY",
    "Channel",
    "ChannelStats",
    "Inbox",
    "Observer",
    "Outbox",
    "Policy",
    "capacity_or_default",
]
