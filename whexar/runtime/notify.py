"""Telling systemd how the run is doing: the sd_notify protocol, with no dependency.

Theory of operation
-------------------
Under a ``Type=notify`` unit systemd names a socket in ``$NOTIFY_SOCKET``; the
service sends it datagrams of newline-separated ``KEY=VALUE`` assignments
(sd_notify(3)). Three matter here:

* ``READY=1`` once the graph is up: every actor of the graph has reported
  ready for the first time (the moment :meth:`Runtime.run
  <whexar.runtime.supervisor.Runtime.run>` reports started). For the robot
  that means the bus scheduler has pinged and configured every servo,
  enabled torque and armed the servos' Bus Watchdog;
* ``WATCHDOG=1`` while the control loop makes progress. With
  ``WatchdogSec=`` systemd passes ``$WATCHDOG_USEC`` (and ``$WATCHDOG_PID``,
  which must be this process: sd_watchdog_enabled(3)); the service must feed
  it within that time or be killed with SIGABRT and, with ``Restart=``,
  started again (systemd.service(5)). A feed is sent only when a *progress*
  message was observed (a cycle of the control loop: ``ServoStates`` for the
  robot), and at most once per half period (sd_watchdog_enabled(3) advises
  half). No timer feeds it: a loop that hangs publishes nothing, so nothing
  feeds systemd, and systemd kills the process while the servos' own Bus
  Watchdog stops the wheels.
* ``STOPPING=1`` when a stop is requested (SIGTERM from ``systemctl stop``,
  an escalation, the end of ``--duration``), before the normal stop runs:
  systemd then waits ``TimeoutStopSec`` for the robot to sit down and park.

:class:`ServiceNotes` decides what to send from the runtime's own messages
(its events, and the progress messages); it reads no clock and does no I/O.
:class:`Notifier` sends datagrams; it is a no-op when ``$NOTIFY_SOCKET`` is
unset (not under systemd). :func:`service_observer` joins them into a
channel observer for the runtime.
"""

from __future__ import annotations

import os
import socket
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Final

from whexar.runtime.channels import Observer
from whexar.runtime.messages import ActorReady, Message, StopRequested
from whexar.runtime.wiring import EVENTS_CHANNEL

NOTIFY_SOCKET: Final = "NOTIFY_SOCKET"
"""The environment variable naming systemd's notification socket (sd_notify(3))."""
WATCHDOG_USEC: Final = "WATCHDOG_USEC"
"""The watchdog period in microseconds, set by ``WatchdogSec=`` (sd_watchdog_enabled(3))."""
WATCHDOG_PID: Final = "WATCHDOG_PID"
"""The process the watchdog is meant for; absent means the main process."""


def watchdog_period_s(env: Mapping[str, str], pid: int) -> float | None:
    """The watchdog period systemd asks ``pid`` to keep, in seconds; ``None`` if none.

    As sd_watchdog_enabled(3): ``$WATCHDOG_USEC`` a positive integer, and
    ``$WATCHDOG_PID``, when set, equal to ``pid``. Anything else disables it.
    """
    text = env.get(WATCHDOG_USEC)
    if not text:
        return None
    owner = env.get(WATCHDOG_PID)
    try:
        usec = int(text)
        if owner and int(owner) != pid:
            return None
    except ValueError:
        return None
    return usec / 1e6 if usec > 0 else None


@dataclass
class ServiceNotes:
    """When to tell systemd what: a plain state machine fed the runtime's messages.

    ``actors`` are the names of the graph's actors (ready when each has reported
    ready once); ``watchdog_s`` the period from :func:`watchdog_period_s` (feeds at
    most every half of it, ``None``: never); ``progress`` the message types that
    show the control loop completed a cycle.
    """

    actors: frozenset[str]
    watchdog_s: float | None
    progress: tuple[type[Message], ...]
    ready: bool = False
    stopping: bool = False
    fed_at: float | None = None
    """When the watchdog was last fed (or READY sent): the next feed is due half a period on."""
    cycles: int = 0
    """Progress messages seen since READY."""
    _seen: set[str] = field(default_factory=set)

    @property
    def feed_interval_s(self) -> float | None:
        """Half the watchdog period (sd_watchdog_enabled(3)); ``None`` without a watchdog."""
        return None if self.watchdog_s is None else self.watchdog_s / 2

    def observe(self, now: float, channel: str, msg: Message) -> list[str]:
        """The datagrams to send after ``msg`` was published on ``channel`` at ``now``."""
        if channel == EVENTS_CHANNEL:
            if isinstance(msg, StopRequested):
                return self._stop(msg.reason)
            if isinstance(msg, ActorReady) and not self.ready:
                self._seen.add(msg.actor)
                if self._seen >= self.actors:
                    return self._ready(now)
            return []
        if isinstance(msg, self.progress):
            return self._progress(now)
        return []

    def _ready(self, now: float) -> list[str]:
        if self.stopping:
            return []
        self.ready = True
        self.fed_at = now
        return [f"READY=1\nSTATUS=running: {len(self.actors)} actors ready"]

    def _progress(self, now: float) -> list[str]:
        interval = self.feed_interval_s
        if not self.ready or self.stopping:
            return []
        self.cycles += 1
        if interval is None or self.fed_at is None or now - self.fed_at < interval:
            return []
        self.fed_at = now
        return ["WATCHDOG=1"]

    def _stop(self, reason: str) -> list[str]:
        if self.stopping:
            return []
        self.stopping = True
        # One line of STATUS: systemctl status shows it as the unit's status.
        status = " ".join(reason.split())
        return [f"STOPPING=1\nSTATUS=stopping: {status}"]


class Notifier:
    """Sends sd_notify datagrams to ``$NOTIFY_SOCKET``; does nothing when it is unset.

    The address is a path, or an abstract socket when it starts with ``@``
    (sd_notify(3)). Sending never blocks and never raises: a notification that
    cannot go out is counted in :attr:`failures`, and the run goes on.
    """

    def __init__(self, env: Mapping[str, str] | None = None) -> None:
        env = os.environ if env is None else env
        address = env.get(NOTIFY_SOCKET, "")
        self.address: str | None = None
        self.failures = 0
        self.sent = 0
        """Datagrams that went out (a count: a service runs for days)."""
        self.last: str | None = None
        """The last datagram that went out."""
        self._sock: socket.socket | None = None
        if not address or address[0] not in "/@":  # vsock addresses are not for us
            return
        self.address = "\0" + address[1:] if address[0] == "@" else address
        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC)
        self._sock.setblocking(False)

    @property
    def enabled(self) -> bool:
        """True under systemd (``$NOTIFY_SOCKET`` names a Unix socket)."""
        return self._sock is not None

    def send(self, text: str) -> bool:
        """Send one datagram; True if it went out."""
        if self._sock is None or self.address is None:
            return False
        try:
            self._sock.sendto(text.encode(), self.address)
        except OSError:  # the socket gone or full: systemd will notice the silence itself
            self.failures += 1
            return False
        self.sent += 1
        self.last = text
        return True

    def close(self) -> None:
        """Close the socket (safe to call twice)."""
        if self._sock is not None:
            self._sock.close()
            self._sock = None


def service_observer(notes: ServiceNotes, notifier: Notifier, now: Callable[[], float]) -> Observer:
    """A channel observer that sends what ``notes`` decides, timed by ``now`` (the run's
    clock). It is called inside every publish: it only compares numbers and, at most
    once per half watchdog period, sends one non-blocking datagram."""

    def observe(channel: str, msg: Message) -> None:
        for text in notes.observe(now(), channel, msg):
            notifier.send(text)

    return observe
