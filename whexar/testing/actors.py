"""Small actors for tests, benchmarks and demonstrations of the runtime.

Each is configurable from the wiring's ``params``, so a test builds any graph
it needs from configuration alone, as the robot's graph is built:

* :class:`Pulse` — ticks and publishes numbered heartbeats; can take time to
  open, send bursts, run slow cycles (overruns), fail, or clean up slowly;
* :class:`Relay` — forwards heartbeats, adding one to the number; can start a
  token around a ring;
* :class:`Sink` — consumes messages at a set pace and republishes what it
  consumed, so a test sees what a subscriber actually got.
"""

from __future__ import annotations

from pydantic import Field

from whexar.runtime.actor import Actor, ActorParams, Input, Output
from whexar.runtime.messages import Heartbeat, Message
from whexar.runtime.schema import NonNegative, Positive


class InjectedFailure(RuntimeError):  # noqa: N818 - a failure on purpose, not an error of ours
    """Raised by a test actor told to fail."""


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
        """Raise :class:`InjectedFailure` this long after each start..."""
        heal_at_s: NonNegative | None = None
        """...unless the clock has reached ``heal_at_s``."""
        fail_on_open: bool = False
        """Fail before reporting ready (a device that will not open)."""
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
                raise InjectedFailure(f"{self.name}: cannot open")
            self.ready()
            seq = 0
            async for tick in self.ticker(p.period_s):
                if p.count is not None and tick.cycle >= p.count:
                    return
                due = p.fail_after_s is not None and self.now() - started >= p.fail_after_s
                if due and self._failing():
                    raise InjectedFailure(f"{self.name}: failed at cycle {tick.cycle}")
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
