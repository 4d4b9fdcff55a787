"""The servo emulator behind a pseudo-terminal, in real time.

Theory of operation
-------------------
:class:`PtyEmulator` opens a pty pair and serves a
:class:`~whexar.bus.emulator.chain.ServoChain` on its master side. Any program that
opens :attr:`PtyEmulator.path` as a serial port — dynamixel-sdk's
``PortHandler``, pyserial, whexar's own bus owner — sees 42 servos on a
Protocol 2.0 bus. pyserial accepts 1 Mbps (any rate) on a pty; a pty has no
wire, so the timing comes from here.

One thread (or the caller, with :meth:`PtyEmulator.run`) reads instruction
bytes from the master and frames them: it looks for the header
``FF FF FD 00``, reads LEN, waits for ``7 + LEN`` bytes and hands the
complete packet to ``chain.transact(packet, t)``, where ``t`` is emulator
time, seconds since the emulator was made. Bytes outside a packet are
counted as garbage and skipped; a packet left incomplete for longer than
:data:`PACKET_GAP_S` when more bytes arrive is abandoned and counted. An
exception from the chain (or from a fault hook) is counted and kept in
:attr:`PtyEmulator.last_error`; the thread keeps serving.

Real time: the bus is one shared wire. The emulator keeps ``bus_free_at``;
a request that arrives at ``a`` is handled at ``start = max(a, bus_free_at)``,
its last status byte is written at ``start + cost`` (the chain's modelled
cost: wire time both ways, return delays, turnaround), and ``bus_free_at``
becomes ``start + cost``. Before that, the status packets are written as the
servos would have sent them, in 1 ms chunks as a USB adapter delivers them
(:data:`USB_FLUSH_S`), so that a host can decode the first servos' answers
while the last ones are still on the wire. A Sync Write has no reply but
still occupies the bus for its wire time, so a read right behind it waits.
With ``realtime=False`` every reply is written at once.

Only :mod:`whexar.runtime.clock` reads the wall clock: ``monotonic()`` for
arrival times and ``wait_until()`` to hold a reply until its time.
"""

from __future__ import annotations

import errno
import os
import select
import threading
from dataclasses import dataclass
from types import TracebackType
from typing import TYPE_CHECKING, Final

from whexar.runtime.clock import monotonic, wait_until
from whexar.runtime.pty import ServedPty

if TYPE_CHECKING:
    from whexar.bus.emulator.chain import ServoChain, Transaction

__all__ = ["PACKET_GAP_S", "PtyEmulator", "PtyStats"]

_HEADER: Final = b"\xff\xff\xfd\x00"
"""Protocol 2.0 header and reserved byte (e-manual, Protocol 2.0 "Instruction Packet")."""
_MIN_LENGTH: Final = 3
"""LEN of the shortest packet: instruction + CRC."""
_MAX_LENGTH: Final = 4096
"""LEN above this is taken for garbage (dynamixel-sdk's TXPACKET_MAX_LEN is 1024 bytes)."""
PACKET_GAP_S: Final = 0.05
"""An incomplete packet older than this is dropped when new bytes arrive.

The device's own limit is 1.5 ms between bytes (e-manual); a pty delivers a
packet written in one ``write()`` at once, but this thread may be descheduled
for a few milliseconds, so the emulator is lenient.
"""
USB_FLUSH_S: Final = 0.001
"""A USB-serial adapter (the U2D2's FTDI chip) hands received bytes to the host when its
latency timer expires, 1 ms once set right (config/99-whexar-dynamixel.rules): replies
arrive in 1 ms chunks as the servos send them, not all at the end."""
_WRITE_STALL_S: Final = 0.5
"""How long a reply may wait for room in the pty before it is dropped (no reader)."""


@dataclass(slots=True)
class PtyStats:
    """What the emulator saw, for tests and for ``whexar emulate``."""

    requests: int = 0
    """Complete instruction packets handed to the chain."""
    reply_bytes: int = 0
    """Status bytes written back."""
    garbage_bytes: int = 0
    """Bytes outside any packet, skipped."""
    partial_packets: int = 0
    """Packets abandoned incomplete."""
    errors: int = 0
    """Requests on which the chain raised."""
    unsent_bytes: int = 0
    """Status bytes dropped because nobody read the pty."""


class PtyEmulator:
    """Serve ``chain`` on a pseudo-terminal; :attr:`path` is the port to open.

    Use :meth:`start` for a background thread or :meth:`run` in the
    foreground; :meth:`close` stops either and closes the pty. The emulator
    is a context manager that starts on entry and closes on exit.
    """

    def __init__(self, chain: ServoChain, *, realtime: bool = True) -> None:
        self.chain = chain
        self.realtime = realtime
        self.stats = PtyStats()
        self.last_error: BaseException | None = None
        self.last_transaction: Transaction | None = None
        """The last request the chain handled, with its reply and bus cost."""
        self._pty = ServedPty.open()  # raw, the slave held open, a wake-up pipe
        self.path: str = self._pty.path
        self._buffer = bytearray()
        self._last_rx = 0.0
        self._t0 = monotonic()
        self._bus_free_at = self._t0
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._serving = False
        self._released = False

    # ------------------------------------------------------------------ lifecycle

    def now(self) -> float:
        """Emulator time: seconds since the emulator was made."""
        return monotonic() - self._t0

    def start(self) -> PtyEmulator:
        """Serve in a daemon thread; returns ``self``."""
        if self._thread is not None or self._released:
            raise RuntimeError("a PtyEmulator starts once")
        self._thread = threading.Thread(target=self.run, name=f"pty-emulator {self.path}")
        self._thread.daemon = True
        self._thread.start()
        return self

    def run(self) -> None:
        """Serve in the calling thread until :meth:`close`."""
        with self._lock:
            if self._released or self._serving:
                raise RuntimeError("this PtyEmulator is closed or already serving")
            self._serving = True
        try:
            while not self._stop.is_set():
                ready, _, _ = select.select([self._pty.master, self._pty.wake_r], [], [])
                if self._pty.wake_r in ready:
                    break
                try:
                    data = os.read(self._pty.master, 65536)
                except BlockingIOError:
                    continue
                except OSError as exc:
                    if exc.errno == errno.EIO:  # cannot happen while we hold the slave
                        continue
                    raise
                self._receive(data, monotonic())
        finally:
            with self._lock:
                self._serving = False
            if self._stop.is_set():
                self._release()

    def close(self) -> None:
        """Stop serving and close the pty (idempotent; safe from a signal handler)."""
        self._stop.set()
        self._pty.wake()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join()
        with self._lock:
            serving = self._serving
        if not serving:
            self._release()

    def _release(self) -> None:
        with self._lock:
            if self._released:
                return
            self._released = True
        self._pty.close()

    def __enter__(self) -> PtyEmulator:
        if self._thread is None:
            self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    # ------------------------------------------------------------------ framing

    def _receive(self, data: bytes, arrival: float) -> None:
        """Frame ``data`` into instruction packets and handle each complete one."""
        buf = self._buffer
        if buf and arrival - self._last_rx > PACKET_GAP_S:
            self.stats.partial_packets += 1
            buf.clear()
        buf += data
        self._last_rx = arrival
        while buf:
            at = buf.find(_HEADER)
            if at < 0:
                # Keep a tail that may be the start of a header split across reads.
                keep = next(
                    (n for n in (3, 2, 1) if len(buf) >= n and _HEADER.startswith(buf[-n:])), 0
                )
                self.stats.garbage_bytes += len(buf) - keep
                del buf[: len(buf) - keep]
                return
            if at:
                self.stats.garbage_bytes += at
                del buf[:at]
            if len(buf) < 7:
                return
            length = buf[5] | (buf[6] << 8)
            if not _MIN_LENGTH <= length <= _MAX_LENGTH:
                self.stats.garbage_bytes += 1
                del buf[:1]
                continue
            if len(buf) < 7 + length:
                return
            packet = bytes(buf[: 7 + length])
            del buf[: 7 + length]
            self._handle(packet, arrival)

    def _handle(self, packet: bytes, arrival: float) -> None:
        start = max(arrival, self._bus_free_at) if self.realtime else arrival
        try:
            transaction = self.chain.transact(packet, start - self._t0)
        except Exception as exc:  # a bad request must not stop the bus
            self.stats.errors += 1
            self.last_error = exc
            return
        self.stats.requests += 1
        self.last_transaction = transaction
        reply = transaction.reply
        if not reply:
            if self.realtime:
                self._bus_free_at = start + transaction.cost_s
            return
        if not self.realtime:
            self._write(reply)
            return
        done = start + transaction.cost_s
        self._bus_free_at = done
        self._stream(reply, start, done, transaction.arrivals)

    def _stream(
        self, reply: bytes, start: float, done: float, arrivals: tuple[tuple[int, float], ...]
    ) -> None:
        """Write ``reply`` as a USB adapter hands it over: every :data:`USB_FLUSH_S`, the
        status bytes complete by then; the last byte exactly at ``done``."""
        sent = 0
        k = 0
        flush = start + USB_FLUSH_S
        while sent < len(reply):
            if flush >= done:
                upto, flush = len(reply), done
            else:
                upto = sent
                while k < len(arrivals) and start + arrivals[k][1] <= flush:
                    upto = arrivals[k][0]
                    k += 1
            if upto > sent:
                if upto == len(reply):
                    wait_until(flush)
                else:
                    # Between chunks a coarse sleep will do; only the last byte is exact.
                    left = flush - monotonic()
                    if left > 0:
                        select.select([self._pty.wake_r], [], [], left)
                self._write(reply[sent:upto])
                sent = upto
            flush += USB_FLUSH_S

    def _write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            try:
                sent = os.write(self._pty.master, view)
            except BlockingIOError:
                # The pty is full: nobody reads it. Wait a little, then give up
                # (the next client's open or clearPort() flushes it anyway).
                readable, writable, _ = select.select(
                    [self._pty.wake_r], [self._pty.master], [], _WRITE_STALL_S
                )
                if readable or not writable:
                    self.stats.unsent_bytes += len(view)
                    return
                continue
            self.stats.reply_bytes += sent
            view = view[sent:]
