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

Fairness: a turn of at most ``TURN_OPS`` port operations
-------------------------------------------------------
The fast path never yields, so an actor whose loop awaits nothing but
``send`` on a ``latest`` or ``queue`` channel (or ``receive`` on a buffer it
keeps full itself) would never give the event loop back: no other actor
would run, and no signal or stop would be seen. So every actor has a
:class:`Turn`, shared by its ports: each send, and each receive that found a
message waiting, spends one operation of it, and the operation that finds
it spent yields once (``asyncio.sleep(0)``: every other ready task runs, the
loop polls its descriptors and signals, and a pending cancellation is
delivered right there) before it takes effect. The turn is refilled whenever
the loop gets control back — by a no-op callback it schedules once half of
it is spent — so an actor that waits at least every ``TURN_OPS / 2``
operations (a ticker, an empty inbox) never yields for fairness, and the
interleaving of every ordinary graph is what it was; ``TURN_OPS`` operations
without a wait always yield. The count is deterministic, so virtual-time
runs stay reproducible. (On virtual time a loop that never waits also never
lets time pass: the others run, but only at the current instant.)

A stop must also get through an actor that does wait, but whose every wait
ends at once — the subscriber of a flooded channel. anyio does not cancel a
task whose awaited future has already completed (that would lose the
result); it expects the task's next checkpoint to raise, and a fast-path
receive has none — so the subscriber's stop waited forever. So before one
in :data:`STOP_CHECK_WAITS` receives (or backpressure sends) that are about
to wait, the port checks for a pending cancellation, before it takes
anything: no message is lost, and a stop gets through within that many
waits. Cancel scopes of the actor's own (a timeout around a loop of
receives) are covered the same way.

Why ``asyncio.Queue`` buffers and not anyio memory object streams
-----------------------------------------------------------------
The runtime is anyio on the asyncio backend (see :mod:`whexar.runtime.clock`),
and cancellation reaches a task waiting on an ``asyncio.Queue`` like any
other await. The buffer is most of what a hop costs: anyio memory object
streams checkpoint on every ``receive`` and wait on an anyio ``Event``, and
a hop through them alone took more than the runtime's whole budget per hop
(20 µs through the actor machinery, ``whexar bench runtime``); through
``asyncio.Queue`` a fraction of it (docs/runtime.md has the figures). So the
buffers are asyncio queues; the interface keeps anyio's vocabulary
(``send``/``receive``/``*_nowait``, :class:`anyio.WouldBlock`).
"""

from __future__ import annotations

import asyncio
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum
from typing import Generic, TypeVar

import anyio
from anyio import WouldBlock
from anyio.lowlevel import checkpoint_if_cancelled

from whexar.runtime.messages import Message

M = TypeVar("M", bound=Message)

Observer = Callable[[str, Message], None]


def fan_out(*observers: Observer) -> Observer:
    """One observer that hands every message to each of ``observers`` in turn."""

    def each(channel: str, msg: Message) -> None:
        for observe in observers:
            observe(channel, msg)

    return each


LinkObserver = Callable[[str, str, float, bytes], None]
"""Sees the raw bytes of a device link: ``(link, direction, t, data)``, direction ``"tx"``
(to the device) or ``"rx"`` (from it), ``t`` on the runtime clock. A recorder is one."""
LinkTap = Callable[[str, float, bytes], None]
"""One link's share of a :data:`LinkObserver`: ``(direction, t, data)``."""
"""Called with the channel name and the message on every publish (the message log)."""


class Policy(StrEnum):
    """What a full subscriber buffer does to the next message (see the module docstring)."""

    LATEST = "latest"
    BACKPRESSURE = "backpressure"
    QUEUE = "queue"


DEFAULT_CAPACITY: dict[Policy, int] = {Policy.LATEST: 1, Policy.BACKPRESSURE: 16, Policy.QUEUE: 256}
"""Buffer size per subscriber when the wiring gives none."""

TURN_OPS = 256
"""Port operations an actor may make without waiting before it yields once (fairness).

The default ``queue`` capacity, so draining a full default buffer never
yields, and a flooding actor holds the loop for a fraction of a millisecond
per turn. A smaller budget makes a sink yield several times per full buffer,
which the runtime bench's message rate shows (docs/runtime.md).
"""


STOP_CHECK_WAITS = 16
"""A port checks for a pending cancellation before one in this many real waits.

anyio's ``checkpoint_if_cancelled`` before every wait made the runtime
bench's hop markedly slower (docs/runtime.md); before one wait in 16 its cost
is lost in the noise, and a stop still gets through within 16 waits.
"""


class Turn:
    """One actor's fairness budget, shared by its ports (see the module docstring).

    The ports count :attr:`left` down in place and call :meth:`running_low`
    only when it reaches :attr:`check_at`: half way, to arm the refill, then
    at zero, to yield. The hot path is a decrement and a comparison.
    """

    __slots__ = ("check_at", "left", "waits")

    def __init__(self) -> None:
        self.left = TURN_OPS
        self.check_at = TURN_OPS // 2
        self.waits = STOP_CHECK_WAITS

    async def check_for_stop(self) -> None:
        """Let a pending cancellation in; ports call it before one real wait in
        :data:`STOP_CHECK_WAITS`, counting :attr:`waits` down themselves."""
        self.waits = STOP_CHECK_WAITS
        await checkpoint_if_cancelled()

    def running_low(self) -> bool:
        """Called when :attr:`left` reaches :attr:`check_at`; ``True``: yield now."""
        if self.left <= 0:
            self._refill()  # the yield is the loop's turn: this one starts afresh
            return True
        # Refilled as soon as the loop runs callbacks again, i.e. once this actor
        # waits: only an actor that never waits runs the turn down to zero.
        self.check_at = 0
        asyncio.get_running_loop().call_soon(self._refill)
        return False

    def _refill(self) -> None:
        self.left = TURN_OPS
        self.check_at = TURN_OPS // 2


@dataclass(frozen=True)
class ChannelStats:
    """Counters of one channel: messages published, and per subscriber, drops and backlog."""

    channel: str
    published: int
    dropped: dict[str, int]
    buffered: dict[str, int]


class Buffer(asyncio.Queue[M]):
    """A subscriber's buffer: ``asyncio.Queue`` (bounded), its two hot calls slimmed.

    ``put_nowait`` and ``get_nowait`` run for every message a subscriber gets, and
    asyncio's spend most of their time keeping the count of unfinished tasks for
    ``join``/``task_done``, which the runtime never calls (they raise here). The
    waiters are woken exactly as asyncio's own are, so tasks run in the same order.
    """

    _queue: deque[M]
    _maxsize: int
    _getters: deque[asyncio.Future[None]]
    _putters: deque[asyncio.Future[None]]
    _wakeup_next: Callable[[deque[asyncio.Future[None]]], None]
    """asyncio's own: wakes the first waiter not cancelled."""

    def put_nowait(self, item: M) -> None:
        queue = self._queue
        if len(queue) >= self._maxsize:  # never unbounded: a capacity is at least 1
            raise asyncio.QueueFull
        queue.append(item)
        if self._getters:
            self._wakeup_next(self._getters)

    def get_nowait(self) -> M:
        queue = self._queue
        if not queue:
            raise asyncio.QueueEmpty
        item = queue.popleft()
        if self._putters:
            self._wakeup_next(self._putters)
        return item

    def task_done(self) -> None:
        raise NotImplementedError("a channel buffer keeps no count of unfinished tasks")

    async def join(self) -> None:
        raise NotImplementedError("a channel buffer keeps no count of unfinished tasks")


class _Subscription(Generic[M]):
    __slots__ = ("dropped", "queue", "subscriber")

    def __init__(self, subscriber: str, capacity: int) -> None:
        if capacity < 1:
            raise ValueError(f"a channel buffer holds at least 1 message (got {capacity})")
        self.subscriber = subscriber
        self.queue: Buffer[M] = Buffer(capacity)
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
        # The policy as flags: an enum member lookup costs more than the rest of a check.
        self.may_wait = policy is Policy.BACKPRESSURE
        """Whether a publisher may have to wait (``backpressure``): :meth:`send` then awaits."""
        self._latest = policy is Policy.LATEST

    def subscribe(self, subscriber: str) -> Buffer[M]:
        """A new buffer for ``subscriber``; returns it."""
        sub = _Subscription[M](subscriber, self.capacity)
        self._subs.append(sub)
        return sub.queue

    async def send(self, msg: M, turn: Turn | None = None) -> None:
        """Publish ``msg`` to every subscriber, applying the channel's policy.

        ``turn`` is the publishing actor's (see fairness in the module docstring).
        """
        if not self.may_wait:
            self.send_nowait(msg)  # latest and queue never wait
            return
        self._count(msg)
        for sub in self._subs:
            if sub.queue.full():
                if turn is not None:
                    turn.waits -= 1
                    if turn.waits <= 0:
                        await turn.check_for_stop()
                await sub.queue.put(msg)
            else:
                sub.queue.put_nowait(msg)

    def send_nowait(self, msg: M) -> None:
        """Publish without waiting; a full ``backpressure`` buffer raises :class:`WouldBlock`."""
        if self.may_wait and any(s.queue.full() for s in self._subs):
            raise WouldBlock  # checked first, so a refused message reaches nobody
        if self.observer is not None:  # _count, inlined: every message passes here
            self.observer(self.name, msg)
        self.published += 1
        for sub in self._subs:
            queue = sub.queue
            try:
                queue.put_nowait(msg)  # it checks for room itself: no full() before it
            except asyncio.QueueFull:  # never for backpressure: checked above
                sub.dropped += 1
                if self._latest:
                    queue.get_nowait()
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

    __slots__ = ("_queue", "_turn", "channel")

    def __init__(
        self, channel: str | None, queue: Buffer[M] | None, turn: Turn | None = None
    ) -> None:
        self.channel = channel
        self._queue = queue
        self._turn = Turn() if turn is None else turn

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
        turn = self._turn
        if not queue._queue:  # empty(), without its two calls: every receive asks
            turn.waits -= 1
            if turn.waits <= 0:
                await turn.check_for_stop()
            return await queue.get()
        turn.left -= 1
        if turn.left <= turn.check_at and turn.running_low():
            await asyncio.sleep(0)  # fairness: others run; a stop is delivered here
            if not queue._queue:  # another task of this actor may have read it meanwhile
                return await queue.get()
        return queue.get_nowait()

    def receive_nowait(self) -> M:
        """The next buffered message; :class:`anyio.WouldBlock` if there is none."""
        if self._queue is None or not self._queue._queue:
            raise WouldBlock
        return self._queue.get_nowait()

    def drain(self) -> list[M]:
        """Every buffered message, oldest first, without waiting."""
        # Plain loops, not a generator: actors call this for several inputs every cycle.
        out: list[M] = []
        queue = self._queue
        if queue is not None:
            items = queue._queue
            while items:
                out.append(queue.get_nowait())
        return out

    def latest(self) -> M | None:
        """The newest buffered message (dropping older ones), or ``None``."""
        last: M | None = None
        queue = self._queue
        if queue is not None:
            items = queue._queue
            while items:
                last = queue.get_nowait()
        return last

    def __aiter__(self) -> Inbox[M]:
        return self

    __anext__ = receive
    """The next message (``async for``): :meth:`receive` itself, one coroutine less."""


class Outbox(Generic[M]):
    """An actor's publishing end: one or more channels (none for an unwired optional output)."""

    __slots__ = ("_turn", "channels")

    def __init__(self, channels: tuple[Channel[M], ...], turn: Turn | None = None) -> None:
        self.channels = channels
        self._turn = Turn() if turn is None else turn

    @property
    def connected(self) -> bool:
        """False for an optional output the wiring left unconnected (nothing to build)."""
        return bool(self.channels)

    async def send(self, msg: M) -> None:
        """Publish ``msg`` on every wired channel (yielding first if the actor's turn is spent)."""
        turn = self._turn
        turn.left -= 1
        if turn.left <= turn.check_at and turn.running_low():
            await asyncio.sleep(0)  # fairness: others run; a stop is delivered here
        for channel in self.channels:
            if channel.may_wait:
                await channel.send(msg, turn)
            else:
                channel.send_nowait(msg)  # what send does, without making a coroutine

    def send_nowait(self, msg: M) -> None:
        """Publish without waiting (see :meth:`Channel.send_nowait`)."""
        for channel in self.channels:
            channel.send_nowait(msg)


def capacity_or_default(policy: Policy, capacity: int | None) -> int:
    """The buffer size of a channel: the configured one, else the policy's default."""
    return DEFAULT_CAPACITY[policy] if capacity is None else capacity


__all__ = [
    "DEFAULT_CAPACITY",
    "STOP_CHECK_WAITS",
    "TURN_OPS",
    "Buffer",
    "Channel",
    "ChannelStats",
    "Inbox",
    "Observer",
    "Outbox",
    "Policy",
    "Turn",
    "capacity_or_default",
]
