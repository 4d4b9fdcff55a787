"""Small actors for tests, benchmarks and demonstrations of the runtime.

Each is configurable from the wiring's ``params``, so a test builds any graph
it needs from configuration alone, as the robot's graph is built:

* :class:`Pulse` — ticks and publishes numbered heartbeats; can take time to
  open, send bursts, run slow cycles (overruns), fail, or clean up slowly;
* :class:`Relay` — forwards heartbeats, adding one to the number; can start a
  token around a ring;
* :class:`Sink` — consumes messages at a set pace and republishes what it
  consumed, so a test sees what a subscriber actually got;
* :class:`Flood` — publishes in a tight loop that awaits nothing but ``send``
  (the runtime must stay fair to everyone else);
* :class:`Stubborn` — a cleanup that ignores the stop: shielded without
  bound, swallowing cancellation, or blocking the event loop;
* :class:`Brake` — stands for the servos: its safe stop emits :class:`Braked`;
* :class:`RealIO` — waits on real I/O (a worker thread or an OS pipe), which
  virtual time refuses unless the graph allows it.

The misbehaving ones are bugs on purpose: the runtime must survive them.
"""

from __future__ import annotations

import os
import sys
from typing import Literal

import anyio
import anyio.to_thread
from pydantic import Field

from whexar.runtime.actor import Actor, ActorParams, Input, Output
from whexar.runtime.clock import monotonic, wait_until
from whexar.runtime.messages import Event, Heartbeat, Message, message
from whexar.runtime.schema import NonNegative, Positive


class InjectedFailure(RuntimeError):  # noqa: N818 - a failure on purpose, not an error of ours
    """Raised by a test actor told to fail."""


Failure = Literal["error", "SystemExit", "sys.exit", "KeyboardInterrupt"]
"""How a test actor fails: :class:`InjectedFailure`, or what would end a plain program."""


def fail(how: Failure, text: str) -> None:
    """Raise the failure ``how`` with ``text``."""
    if how == "SystemExit":
        raise SystemExit(text)
    if how == "sys.exit":
        sys.exit(text)
    if how == "KeyboardInterrupt":
        raise KeyboardInterrupt(text)
    raise InjectedFailure(text)


class Pulse(Actor):
    """Publishes ``Heartbeat(seq)`` every ``period_s`` on its ``out`` port."""

    class Params(ActorParams):
        period_s: Positive = 0.01
        open_s: NonNegative = 0.0
        """Time taken to 'open resources' before reporting ready."""
        burst: int = Field(1, ge=1)
        """Heartbeats published per cycle."""
        count: int | None = Field(None, ge=0)
        """Cycles to run before returning; ``None`` runs until stopped."""
        slow_cycles: tuple[int, ...] = ()
        """Cycles that take ``slow_s`` of work (to cause overruns)."""
        slow_s: NonNegative = 0.0
        fail_after_s: NonNegative | None = None
        """Fail (see ``fail_with``) this long after each start..."""
        heal_at_s: NonNegative | None = None
        """...unless the clock has reached ``heal_at_s``."""
        fail_on_open: bool = False
        """Fail before reporting ready (a device that will not open)."""
        fail_with: Failure = "error"
        """What a failure raises: ``error`` (:class:`InjectedFailure`), ``SystemExit``,
        ``sys.exit`` (calls it) or ``KeyboardInterrupt``."""
        cleanup_s: NonNegative = 0.0
        """Shielded cleanup time when stopped (servos to a safe state)."""

    params: Params
    out = Output(Heartbeat)

    def _failing(self) -> bool:
        heal = self.params.heal_at_s
        return heal is None or self.now() < heal

    async def run(self) -> None:
        p = self.params
        started = self.now()
        try:
            await self.clock.sleep(p.open_s)
            if p.fail_on_open and self._failing():
                fail(p.fail_with, f"{self.name}: cannot open")
            self.ready()
            seq = 0
            async for tick in self.ticker(p.period_s):
                if p.count is not None and tick.cycle >= p.count:
                    return
                due = p.fail_after_s is not None and self.now() - started >= p.fail_after_s
                if due and self._failing():
                    fail(p.fail_with, f"{self.name}: failed at cycle {tick.cycle}")
                for _ in range(p.burst):
                    await self.out.send(Heartbeat(t=tick.t, source=self.name, seq=seq))
                    seq += 1
                if tick.cycle in p.slow_cycles:
                    await self.clock.sleep(p.slow_s)
        finally:
            if p.cleanup_s > 0:
                with self.shielded():
                    await self.clock.sleep(p.cleanup_s)


class Relay(Actor):
    """Forwards each heartbeat from ``inp`` to ``out`` with ``seq + 1``."""

    class Params(ActorParams):
        start: bool = False
        """Publish ``Heartbeat(seq=0)`` once ready: the token of a ring."""
        limit: int | None = Field(None, ge=0)
        """On a heartbeat with ``seq >= limit``, stop the runtime instead of forwarding."""

    params: Params
    inp = Input(Heartbeat)
    out = Output(Heartbeat)

    async def run(self) -> None:
        self.ready()
        if self.params.start:
            await self.out.send(Heartbeat(t=self.now(), source=self.name, seq=0))
        limit = self.params.limit
        async for beat in self.inp:
            if limit is not None and beat.seq >= limit:
                self.request_stop(f"token reached seq {beat.seq}")
                continue
            # The token keeps the time it was made: what it is valid for.
            await self.out.send(Heartbeat(t=beat.t, source=self.name, seq=beat.seq + 1))


class Sink(Actor):
    """Consumes ``inp`` taking ``delay_s`` per message; republishes each on ``seen``."""

    class Params(ActorParams):
        delay_s: NonNegative = 0.0
        start_s: NonNegative = 0.0
        """Do not read before this clock time (lets a backlog build up)."""
        stop_after: int | None = Field(None, ge=1)
        """Stop the runtime after consuming this many messages."""

    params: Params
    inp = Input(Message)
    seen = Output(Message, optional=True)

    async def run(self) -> None:
        self.ready()
        await self.clock.sleep_until(self.params.start_s)
        consumed = 0
        async for msg in self.inp:
            if self.params.delay_s:
                await self.clock.sleep(self.params.delay_s)
            await self.seen.send(msg)
            consumed += 1
            if consumed == self.params.stop_after:
                self.request_stop(f"consumed {consumed} messages")


class Flood(Actor):
    """Publishes ``Heartbeat(seq)`` on ``out`` as fast as it can, awaiting nothing but ``send``.

    A tight loop on a ``latest`` or ``queue`` channel never has to wait, so it
    stands for a greedy or buggy publisher: every other actor must still run
    and a stop must still get through (see fairness in
    :mod:`whexar.runtime.channels`). Each beat is stamped with the clock's time.
    """

    class Params(ActorParams):
        count: int | None = Field(None, ge=0)
        """Heartbeats to publish before returning; ``None`` floods until stopped."""

    params: Params
    out = Output(Heartbeat)

    async def run(self) -> None:
        self.ready()
        count = self.params.count
        seq = 0
        while count is None or seq < count:
            await self.out.send(Heartbeat(t=self.now(), source=self.name, seq=seq))
            seq += 1


class Stubborn(Actor):
    """Ready at once; when stopped, its cleanup ignores the stop — a bug the runtime survives.

    ``cleanup`` says how, for ``cleanup_s`` (``None``: forever):

    * ``shield`` — sleeps on the runtime clock in a shielded scope of its own,
      with no bound (unlike :meth:`Actor.shielded`);
    * ``swallow`` — catches every cancellation and sleeps on. anyio delivers
      the cancellation again on every turn of the loop, so the loop never
      idles: on virtual time, time stands still (use it on real time);
    * ``block`` — blocks the event loop's thread in wall time (a blocking
      call in cleanup): nothing else runs meanwhile, signals included.
    """

    class Params(ActorParams):
        cleanup: Literal["shield", "swallow", "block"] = "shield"
        cleanup_s: NonNegative | None = None
        """How long the cleanup takes (clock seconds; wall seconds for ``block``);
        ``None``, the default, is forever."""

    params: Params

    async def run(self) -> None:
        self.ready()
        try:
            await anyio.sleep_forever()
        finally:
            await self._clean_up()

    async def _clean_up(self) -> None:
        p = self.params
        end = None if p.cleanup_s is None else self.now() + p.cleanup_s
        if p.cleanup == "block":
            wall_end = None if p.cleanup_s is None else monotonic() + p.cleanup_s
            while wall_end is None or monotonic() < wall_end:
                wait_until(monotonic() + 3600.0 if wall_end is None else wall_end)
            return
        if p.cleanup == "shield":
            with anyio.CancelScope(shield=True):
                await self._sleep_until(end)
            return
        while end is None or self.now() < end:
            try:
                await self._sleep_until(end)
            except anyio.get_cancelled_exc_class():
                continue  # the bug on purpose: cancellation swallowed

    async def _sleep_until(self, end: float | None) -> None:
        if end is None:
            await anyio.sleep_forever()
        else:
            await self.clock.sleep_until(end)


@message
class Braked(Event):
    """A :class:`Brake`'s safe stop ran: what it drives is now at rest."""

    actor: str
    reason: str


class Brake(Actor):
    """Stands for what drives the robot (the servos): runs until stopped; its safe stop says so.

    :meth:`safe_stop` emits :class:`Braked` and then takes ``brake_s``; a plain
    stop takes ``cleanup_s`` of shielded cleanup (bounded by the stop
    timeout). A test tells from the events whether the safe stop ran.
    """

    class Params(ActorParams):
        brake_s: NonNegative = 0.0
        """Time the safe stop takes after emitting :class:`Braked`."""
        cleanup_s: NonNegative = 0.0
        """Shielded cleanup time when stopped."""

    params: Params

    async def run(self) -> None:
        self.ready()
        try:
            await anyio.sleep_forever()
        finally:
            if self.params.cleanup_s > 0:
                with self.shielded():
                    await self.clock.sleep(self.params.cleanup_s)

    async def safe_stop(self, reason: str) -> None:
        self.emit(Braked(t=self.now(), source=self.name, actor=self.name, reason=reason))
        await self.clock.sleep(self.params.brake_s)


class RealIO(Actor):
    """Waits on real I/O once every ``period_s``, and publishes a heartbeat after each wait.

    ``via`` is what it waits on: ``thread`` — a call in a worker thread
    (``anyio.to_thread``, as a blocking driver is run); ``pipe`` — an OS pipe
    it writes one byte to and then waits to read (a descriptor the event loop
    watches, as a serial port is). With ``declare`` it first says so through
    :meth:`~whexar.runtime.clock.Clock.uses_real_io`, as a device actor
    should before it opens a real device. On virtual time all of this is
    refused unless the graph allows real I/O.
    """

    class Params(ActorParams):
        via: Literal["thread", "pipe"] = "thread"
        period_s: Positive = 0.01
        declare: bool = False
        """Call ``clock.uses_real_io()`` before the first wait."""

    params: Params
    out = Output(Heartbeat, optional=True)

    async def run(self) -> None:
        p = self.params
        if p.declare:
            self.clock.uses_real_io(f"a {p.via} (whexar.testing.RealIO)")
        read, write = os.pipe()
        try:
            self.ready()
            async for tick in self.ticker(p.period_s):
                if p.via == "thread":
                    await anyio.to_thread.run_sync(os.getpid)
                else:
                    os.write(write, b"x")
                    await anyio.wait_readable(read)
                    os.read(read, 1)
                await self.out.send(Heartbeat(t=tick.t, source=self.name, seq=tick.cycle))
        finally:
            os.close(read)
            os.close(write)
