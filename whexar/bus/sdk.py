"""The servo port through dynamixel-sdk, and the one owner that may touch it.

Theory of operation
-------------------
:class:`DxlBus` is the whole of whexar's use of dynamixel-sdk: ping, read,
write, reboot, Sync Read (plain or fast) and Sync Write, each returning the
SDK's result code checked per transaction. It is synchronous, like the SDK,
and must only ever be called by the port's owner:

* :class:`ThreadPortOwner` — a dedicated thread owns a real port (a U2D2, a
  pseudo-terminal) and runs jobs from a queue. The SDK busy-polls while it
  waits for status packets, so it must never run on the event loop.
* :class:`InlinePortOwner` — for the in-process emulator: the job runs at
  once on the loop (the emulator answers instantly), then the actor sleeps
  the bus time the emulator charged. On virtual time that makes every
  transaction cost exactly its wire time; it is how tests, benchmarks and the
  simulator drive the real SDK deterministically.

Sync Read is built from the SDK's own ``syncReadTx``/``readRx`` (what
``GroupSyncRead`` does) so that each status packet's ERR byte is kept — the
SDK's group drops it and with it the Alert bit — and so that the servos read
before a failure keep their data: the SDK stops at the first failing servo
and reports nothing. Fast Sync Read uses ``syncReadTx(fast)`` and
``fastSyncReadRx``; its single status packet is split per servo here.

A real port is a :class:`WaitingPortHandler`: the SDK's ``PortHandler``
opens pyserial with ``timeout=0`` and its packet loop polls ``readPort``
without sleeping, which burns a core and holds the GIL against every other
thread; this one waits for bytes in ``poll()`` until the SDK's own packet
deadline, so the owning thread sleeps while the servos talk.

A cycle's goal writes are built by the SDK before its reads
(:meth:`DxlBus.prepare_sync_write`) and ride on the last read
(``sync_read(…, then=…)``): they go out the moment the last servo's status
packet is complete in the port's buffer — the half-duplex bus is free — while
the statuses are still being decoded.

Port errors (a vanished USB device raises ``OSError`` in pyserial) become
:class:`~whexar.errors.DeviceGoneError`.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import math
import os
import queue
import select
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final, NamedTuple, Protocol, TypeVar

import anyio
import anyio.lowlevel
import dynamixel_sdk as dxl
from dynamixel_sdk.protocol2_packet_handler import TXPACKET_MAX_LEN, Protocol2PacketHandler

from whexar.bus import wire
from whexar.bus.control_table import Register
from whexar.bus.portlock import PortLock
from whexar.bus.protocol import ALERT, crc16
from whexar.errors import DeviceGoneError, PortUnavailableError
from whexar.runtime.channels import LinkTap
from whexar.runtime.clock import Clock, monotonic

T = TypeVar("T")

COMM_SUCCESS: Final[int] = dxl.COMM_SUCCESS
COMM_RX_CORRUPT: Final[int] = dxl.COMM_RX_CORRUPT


def comm_name(result: int) -> str:
    """A short name of an SDK result code: ``timeout``, ``corrupt``, ``busy``…"""
    return {
        dxl.COMM_SUCCESS: "ok",
        dxl.COMM_PORT_BUSY: "busy",
        dxl.COMM_TX_FAIL: "tx_fail",
        dxl.COMM_RX_FAIL: "rx_fail",
        dxl.COMM_TX_ERROR: "tx_error",
        dxl.COMM_RX_WAITING: "rx_waiting",
        dxl.COMM_RX_TIMEOUT: "timeout",
        dxl.COMM_RX_CORRUPT: "corrupt",
        dxl.COMM_NOT_AVAILABLE: "not_available",
    }.get(result, f"result {result}")


class Port(Protocol):
    """What dynamixel-sdk needs of a port (a ``PortHandler`` or an emulated one), and a cap.

    ``timeout_cap_ms``, when set, bounds every packet timeout the SDK arms
    (:meth:`DxlBus.ping` sets it for a probe that must not stall a cycle).
    """

    is_using: bool
    timeout_cap_ms: float | None

    def clearPort(self) -> None: ...  # noqa: N802 — the SDK's names
    def writePort(self, packet: Any) -> int: ...  # noqa: N802
    def readPort(self, length: int) -> Any: ...  # noqa: N802
    def getBaudRate(self) -> int: ...  # noqa: N802


@dataclass(frozen=True, slots=True)
class Reply:
    """One unicast transaction: the SDK result, the status ERR byte and the value read."""

    result: int
    error: int = 0
    value: int = 0

    @property
    def ok(self) -> bool:
        """The status packet arrived intact (its ERR byte may still report a problem)."""
        return self.result == COMM_SUCCESS

    @property
    def alert(self) -> bool:
        """The servo's Hardware Error Status is set."""
        return bool(self.error & ALERT)


@dataclass(slots=True)
class SyncReadResult:
    """A Sync Read: data and ERR byte per servo that answered before any failure.

    ``failed`` is the first servo whose status did not arrive intact (``None``
    on success); servos after it were not decoded.
    """

    result: int
    data: dict[int, bytes] = field(default_factory=dict)
    errors: dict[int, int] = field(default_factory=dict)
    failed: int | None = None
    sent: list[int] = field(default_factory=list)
    """Result codes of the packets sent after the read (``then`` of :meth:`DxlBus.sync_read`)."""

    @property
    def ok(self) -> bool:
        return self.result == COMM_SUCCESS


_LENGTH_L: Final = 5
_INSTRUCTION: Final = 7
"""Protocol 2.0 packet offsets: LEN_L at 5, the instruction at 7 (e-manual)."""
_STUFFED: Final = b"\xff\xff\xfd\xfd"
_TO_STUFF: Final = b"\xff\xff\xfd"


def _none_of(packet: Any, pattern: bytes, *, crc_bytes: int, max_end: int | None = None) -> bool:
    """Whether ``packet`` (the SDK's list) surely holds no ``pattern`` from LEN_L up to
    ``crc_bytes`` before its end, where the SDK's stuffing loops look. ``False`` whenever
    that loop might do anything else: a packet shorter than its LEN (or longer than
    ``max_end``), a LEN under 2, items that are not bytes."""
    length = packet[_LENGTH_L] | (packet[_LENGTH_L + 1] << 8)
    end = _INSTRUCTION + length
    if length < 2 or end > len(packet) or (max_end is not None and end > max_end):
        return False
    try:
        return bytes(packet).find(pattern, _LENGTH_L, end - crc_bytes) < 0
    except (TypeError, ValueError):
        return False


class PacketHandler(Protocol2PacketHandler):  # type: ignore[misc]
    """dynamixel-sdk's Protocol 2.0 packet handler, with its CRC table built once.

    The SDK's ``updateCRC`` rebuilds its 256-entry table as a list literal on
    every call — one call per packet, 43 per Sync Read of 42 servos. Same
    polynomial and results (:func:`whexar.bus.protocol.crc16`, tested equal);
    ``addStuffing`` and ``removeStuffing`` return a packet with nothing to do
    as it is (tested equal). Everything else is the SDK's own code.
    """

    def updateCRC(self, crc_accum: int, data_blk_ptr: Any, data_blk_size: int) -> int:  # noqa: N802
        return crc16(bytes(data_blk_ptr[:data_blk_size]), crc_accum)

    def addStuffing(self, packet: list[int]) -> list[int]:  # noqa: N802
        """The SDK's, but a packet with no ``FF FF FD`` to stuff (nearly all of them) is
        returned at once: the SDK's byte loop would copy it through a 1 KiB list onto itself.

        The SDK's own loop runs whenever it might do anything else: a packet shorter than
        its LEN or longer than ``TXPACKET_MAX_LEN`` (it raises), a LEN under 2, bytes that
        are not bytes.
        """
        # The SDK looks for FF FF FD starting from LEN_L, up to the CRC.
        if _none_of(packet, _TO_STUFF, crc_bytes=2, max_end=TXPACKET_MAX_LEN):
            return packet
        result: list[int] = super().addStuffing(packet)
        return result

    def removeStuffing(self, packet: list[int]) -> list[int]:  # noqa: N802
        """The SDK's, but a packet with no stuffed ``FF FF FD FD`` (nearly all of them) is
        returned at once: the SDK's byte loop would copy each byte onto itself.

        As in :meth:`addStuffing`, the SDK's loop runs whenever it might do anything else.
        """
        # The SDK looks for FF FF FD FD starting from LEN_L, up to CRC_L included.
        if _none_of(packet, _STUFFED, crc_bytes=1):
            return packet
        result: list[int] = super().removeStuffing(packet)
        return result


class _Capture:
    """A port that keeps the packet the SDK writes to it instead of sending it."""

    is_using = False
    timeout_cap_ms: float | None = None

    def __init__(self) -> None:
        self.packet = b""

    def clearPort(self) -> None:  # noqa: N802 — the SDK's names
        pass

    def writePort(self, packet: Any) -> int:  # noqa: N802
        self.packet = bytes(packet)
        return len(self.packet)


class DxlBus:
    """Every transaction whexar makes, through dynamixel-sdk's Protocol 2.0 packet handler.

    With ``native`` (the default) and :mod:`whexar.bus.wire`'s compiled path built, the
    cycle's transactions — Sync Read, Fast Sync Read, the Sync Write packets — take that
    path on a real port (:class:`WaitingPortHandler`) and on a port that hands replies
    over whole (``peek()``: the emulated and the replayed ones), with the SDK's results;
    everything else, and every other port, is the SDK's.
    """

    def __init__(self, port: Port, *, native: bool = True) -> None:
        self.port = port
        self.ph = PacketHandler()
        self.native = native and wire.NATIVE is not None
        """Whether the cycle's transactions take the compiled path."""
        self._requests: dict[tuple[int, int, bool, bytes], bytes | None] = {}
        self._bus_free_at = 0.0
        """When the goals the last read carried are off the wire (monotonic s): the next
        read's statuses cannot start before (:func:`whexar.bus.wire`'s ``transact``)."""

    def _lost(self, exc: OSError) -> DeviceGoneError:
        """The error to raise, from ``exc``, for a port that raised it."""
        self.port.is_using = False  # the SDK leaves it set when the port raises
        name = getattr(self.port, "port_name", "the servo port")
        return DeviceGoneError(f"servo port {name}: {exc}")

    @contextlib.contextmanager
    def _gone(self) -> Iterator[None]:
        # The cycle's hot paths (sync_read, _write) spell this out as try/except: a
        # generator context manager costs about a microsecond per use.
        try:
            yield
        except OSError as exc:  # pyserial's SerialException is an OSError
            raise self._lost(exc) from exc

    def ping(self, servo: int, *, timeout_ms: float | None = None) -> Reply:
        """Ping ``servo``; ``value`` is its model number.

        ``timeout_ms`` bounds the wait for its status (default: the SDK's,
        about 34 ms with its 16 ms latency allowance): a probe of a servo that
        may be dead costs at most that.
        """
        port = self.port
        cap = port.timeout_cap_ms
        port.timeout_cap_ms = timeout_ms
        try:
            with self._gone():
                model, result, error = self.ph.ping(port, servo)
        finally:
            port.timeout_cap_ms = cap
        return Reply(result, error, model)

    def read(self, servo: int, reg: Register) -> Reply:
        """Read one register of one servo."""
        with self._gone():
            data, result, error = self.ph.readTxRx(self.port, servo, reg.address, reg.size)
        value = reg.decode(bytes(data), reg.address) if result == COMM_SUCCESS else 0
        return Reply(result, error, value)

    def write(self, servo: int, reg: Register, value: int) -> Reply:
        """Write one register of one servo and wait for its status."""
        with self._gone():
            result, error = self.ph.writeTxRx(
                self.port, servo, reg.address, reg.size, list(reg.encode(value))
            )
        return Reply(result, error)

    def reboot(self, servo: int) -> Reply:
        """Reboot ``servo`` (clears a latched hardware error; torque comes back off)."""
        with self._gone():
            result, error = self.ph.reboot(self.port, servo)
        return Reply(result, error)

    def sync_write(self, start: int, length: int, values: Mapping[int, bytes]) -> int:
        """One Sync Write of ``length`` bytes at ``start`` per servo; the SDK result."""
        if not values:
            return COMM_SUCCESS
        return self.send(self.prepare_sync_write(start, length, values))

    def prepare_sync_write(self, start: int, length: int, values: Mapping[int, bytes]) -> bytes:
        """The Sync Write packet, built now (by the SDK, or the same bytes compiled), to
        :meth:`send` later.

        A cycle builds its goal writes before its reads, while the bus is busy
        anyway: once the last status arrives, the writes go out at once.
        """
        if self.native:
            built = wire.sync_write_request(start, length, values)
            if built is not None:
                return built
        param: list[int] = []
        for servo, data in values.items():
            param.append(servo)
            param.extend(data)
        capture = _Capture()
        self.ph.syncWriteTxOnly(capture, start, length, param, len(param))
        return capture.packet

    def send(self, packet: bytes) -> int:
        """Send a packet that needs no status (a prepared Sync Write); the SDK result code."""
        if self.port.is_using:
            return int(dxl.COMM_PORT_BUSY)
        return self._write(packet)

    def _write(self, packet: bytes) -> int:
        try:
            # No clearPort() as the SDK's txPacket does: nothing answers this packet, and the
            # next transaction that waits for an answer clears the input first.
            written = self.port.writePort(packet)
        except OSError as exc:  # as _gone()
            raise self._lost(exc) from exc
        return COMM_SUCCESS if written == len(packet) else int(dxl.COMM_TX_FAIL)

    def sync_read(
        self,
        ids: Sequence[int],
        start: int,
        length: int,
        *,
        fast: bool = False,
        then: Sequence[bytes] = (),
    ) -> SyncReadResult:
        """One Sync Read (or Fast Sync Read) of ``length`` bytes at ``start`` from ``ids``.

        ``then``: packets that need no answer (prepared Sync Writes), sent as soon
        as the bus is free again — once the last servo's status packet lies complete
        in the port's buffer, before the others are decoded — or after the read
        when that cannot be seen. Their results are :attr:`SyncReadResult.sent`.
        """
        if not ids:
            return SyncReadResult(COMM_SUCCESS, sent=[self.send(p) for p in then])
        if self.native:
            native = self._native_read(ids, start, length, fast, then)
            if native is not None:
                if len(native.sent) < len(then):
                    native.sent = [self.send(p) for p in then]
                return native
        try:
            result = self.ph.syncReadTx(self.port, start, length, list(ids), len(ids), fast)
            if result != COMM_SUCCESS:
                out = SyncReadResult(result, failed=ids[0])
            else:
                out = self._fast_rx(ids, length) if fast else self._rx(ids, length, then)
        except OSError as exc:  # as _gone()
            raise self._lost(exc) from exc
        if len(out.sent) < len(then):
            out.sent = [self.send(p) for p in then]
        return out

    def _tail_complete(self, last: int, length: int) -> bool:
        """The last servo's status packet is whole at the end of the port's buffer: nothing
        more will answer, so the half-duplex bus is free (a stuffed packet is not matched)."""
        peek = getattr(self.port, "peek", None)
        if peek is None:
            return False
        return _tail_of(peek(), last, length)

    def _rx(self, ids: Sequence[int], length: int, then: Sequence[bytes] = ()) -> SyncReadResult:
        out = SyncReadResult(COMM_SUCCESS)
        pending = bool(then)
        read, port = self.ph.readRx, self.port
        got, errors = out.data, out.errors
        for servo in ids:
            if pending and self._tail_complete(ids[-1], length):
                # Mid-read the SDK still marks the port in use; the bus itself is free.
                out.sent = [self._write(p) for p in then]
                pending = False
            data, result, error = read(port, servo, length)
            if result != COMM_SUCCESS:
                out.result, out.failed = result, servo
                return out
            got[servo] = bytes(data)
            errors[servo] = error
        return out

    def _fast_rx(self, ids: Sequence[int], length: int) -> SyncReadResult:
        # One packet from 0xFE: [ERR, ID, data…, CRC₂] per servo (e-manual, Fast Sync Read).
        raw, result, _ = self.ph.fastSyncReadRx(
            self.port, dxl.BROADCAST_ID, (length + 4) * len(ids)
        )
        if result != COMM_SUCCESS:
            return SyncReadResult(result, failed=ids[0])
        return _split_fast(bytes(raw), ids, length)

    # ---------------------------------------------------------- the compiled path

    def _request(self, start: int, length: int, ids: bytes, fast: bool) -> bytes | None:
        key = (start, length, fast, ids)
        request = self._requests.get(key, b"")
        if request == b"":
            if len(self._requests) > 64:  # a cycle repeats a few; a scan must not pile up
                self._requests.clear()
            request = self._requests[key] = wire.sync_read_request(start, length, ids, fast=fast)
        return request

    def _native_read(
        self, ids: Sequence[int], start: int, length: int, fast: bool, then: Sequence[bytes]
    ) -> SyncReadResult | None:
        """:meth:`sync_read` on the compiled path; ``None`` where it does not apply (a
        port of another kind, a request the SDK would build otherwise)."""
        port = self.port
        fd = getattr(port, "_fd", None) if isinstance(port, WaitingPortHandler) else None
        if fd is None and (isinstance(port, WaitingPortHandler) or not hasattr(port, "peek")):
            return None
        try:
            id_bytes = bytes(ids)
        except ValueError:  # not a servo ID: the SDK's path says what it makes of it
            return None
        request = self._request(start, length, id_bytes, fast)
        if request is None or len(ids) > 253:
            return None
        if port.is_using:  # as the SDK's txPacket
            return SyncReadResult(int(dxl.COMM_PORT_BUSY), failed=ids[0])
        ask = _Ask(request, ids, id_bytes, length, fast, then)
        try:
            if fd is not None:
                return self._native_fd(port, fd, ask)
            return self._native_buffered(port, ask)
        except OSError as exc:  # as _gone()
            raise self._lost(exc) from exc

    def _native_fd(self, port: Any, fd: int, ask: _Ask) -> SyncReadResult:
        """A real port: the whole transaction in ``_wire.transact``, the GIL released."""
        request, ids, id_bytes, length, fast, then = ask
        port.clearPort()  # as the SDK's txPacket
        port.setPacketTimeout((11 + length) * len(ids))  # as its syncReadTx: the same deadline
        assert wire.NATIVE is not None
        result, failed, data, errors, taken, received, events, sent, free = wire.NATIVE.transact(
            fd,
            request,
            id_bytes,
            length,
            fast,
            port.packet_timeout,
            tuple(then),
            10.0 / port.getBaudRate(),  # 8N1: 10 bits a byte
            self._bus_free_at,
        )
        self._bus_free_at = free
        if taken < len(received):  # left unread, as the SDK would have left them
            port._rx += received[taken:]
        direct = getattr(port, "tap_direct", None)
        if direct is not None:
            report, now = direct
            offset = now() - monotonic()  # the events are stamped on the monotonic clock
            left = taken
            for kind, t, chunk in events:
                if kind == "rx":
                    if left <= 0:
                        continue
                    chunk = chunk[:left]
                    left -= len(chunk)
                report(kind, t + offset, chunk)
        return _native_result(result, failed, data, errors, ask, sent)

    def _native_buffered(self, port: Any, ask: _Ask) -> SyncReadResult:
        """A port that hands the reply over whole: the SDK's calls on it, in its order —
        write, arm the timeout, read what it would read, ask for the timeout where it
        would — and ``_wire.parse`` for the rest."""
        request, ids, id_bytes, length, fast, then = ask
        port.clearPort()
        if port.writePort(request) != len(request):
            port.is_using = False
            return SyncReadResult(int(dxl.COMM_TX_FAIL), failed=ids[0])
        port.setPacketTimeout((11 + length) * len(ids))
        received: bytes = port.peek()
        sent: list[int] = []
        if then and not fast and _tail_of(received, ids[-1], length):
            sent = [self._write(p) for p in then]
        assert wire.NATIVE is not None
        parse = wire.NATIVE.parse
        read, timed_out = 0, False
        while True:
            done, taken, result, failed, data, errors, _ = parse(
                received, id_bytes, length, fast, timed_out
            )
            # Read as the SDK reads — at least once, nothing there or not: a port that is
            # gone says so when it is read.
            if taken > read or not done:
                port.readPort(taken - read)
                read = taken
            if done:
                break
            if port.isPacketTimeout():
                timed_out = True
            else:
                received = received[:read] + port.peek()
        return _native_result(result, failed, data, errors, ask, sent)


class _Ask(NamedTuple):
    """One Sync Read on the compiled path: its request packet, the servos, the bytes of
    each, fast or not, the packets that ride on it."""

    request: bytes
    ids: Sequence[int]
    id_bytes: bytes
    """The same IDs, as ``_wire`` takes them."""
    length: int
    fast: bool
    then: Sequence[bytes]


def _native_result(
    result: int,
    failed: int | None,
    data: Any,
    errors: dict[int, int] | None,
    ask: _Ask,
    sent: list[int],
) -> SyncReadResult:
    """What ``_wire`` handed back, as :meth:`DxlBus.sync_read` returns it."""
    ids = ask.ids
    if ask.fast:
        if result != COMM_SUCCESS:
            out = SyncReadResult(result, failed=ids[0])
        else:
            out = _split_fast(data, ids, ask.length)
    else:
        out = SyncReadResult(result, data, errors or {}, None if failed is None else ids[failed])
    out.sent = sent
    return out


def _tail_of(buf: bytes, last: int, length: int) -> bool:
    """:meth:`DxlBus._tail_complete` of the bytes ``buf``."""
    n = 11 + length
    return (
        len(buf) >= n
        and buf[-n : -n + 5] == bytes((0xFF, 0xFF, 0xFD, 0x00, last))
        and buf[-n + 5] | (buf[-n + 6] << 8) == n - 7
    )


def _split_fast(raw: bytes, ids: Sequence[int], length: int) -> SyncReadResult:
    """A Fast Sync Read's data, ``[ERR, ID, data…, CRC₂]`` per servo, cut per servo."""
    out = SyncReadResult(COMM_SUCCESS)
    step = length + 4
    for k, expected in enumerate(ids):
        seg = raw[k * step : (k + 1) * step]
        if len(seg) < step or seg[1] != expected:
            out.result, out.failed = COMM_RX_CORRUPT, expected
            return out
        out.errors[expected] = seg[0]
        out.data[expected] = seg[2 : 2 + length]
    return out


# --------------------------------------------------------------------------- owners


class PortOwner(Protocol):
    """The one task or thread that may use a :class:`DxlBus`; others send it jobs."""

    async def call(self, job: Callable[[DxlBus], T]) -> T:
        """Run ``job`` on the bus and return its result."""
        ...

    def close(self) -> None:
        """Release the port."""
        ...


class InlinePortOwner:
    """Runs jobs on the loop against an in-process emulated port, then sleeps their bus time.

    ``port`` must offer ``take_elapsed()`` (the bus time its transactions
    cost); :class:`~whexar.bus.emulator.port.EmulatedPort` does.
    """

    def __init__(self, port: Any, clock: Clock, *, native: bool = True) -> None:
        self.bus = DxlBus(port, native=native)
        self._port = port
        self._clock = clock
        # The bus is busy until a job's time has passed. asyncio's lock: the
        # runtime is always asyncio, and it costs a fraction of anyio's per cycle.
        self._lock = asyncio.Lock()

    async def call(self, job: Callable[[DxlBus], T]) -> T:
        async with self._lock:
            try:
                return job(self.bus)
            finally:
                # Charge the bus time even when the job raised: the wire was busy.
                with anyio.CancelScope(shield=True):
                    await self._clock.sleep(self._port.take_elapsed())
                # Every wait above is shielded: deliver a pending cancellation here.
                await anyio.lowlevel.checkpoint_if_cancelled()

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self._port.closePort()


_STOP = object()


class ThreadPortOwner:
    """A dedicated thread owns a real port; the event loop sends it jobs through a queue.

    Each job's result (or exception) comes back to the awaiting task through
    ``call_soon_threadsafe``. The thread is a daemon so that a wedged port
    cannot keep the process alive.
    """

    def __init__(self, port: Any, *, name: str = "servo-port", native: bool = True) -> None:
        self.bus = DxlBus(port, native=native)
        self._port = port
        self._jobs: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._thread = threading.Thread(target=self._serve, name=name, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        while True:
            item = self._jobs.get()
            if item is _STOP:
                return
            job, loop, future = item
            try:
                result = job(self.bus)
            except BaseException as exc:  # handed to the awaiting task, never lost
                loop.call_soon_threadsafe(_settle, future, None, exc)
            else:
                loop.call_soon_threadsafe(_settle, future, result, None)

    async def call(self, job: Callable[[DxlBus], T]) -> T:
        loop = asyncio.get_running_loop()
        future: asyncio.Future[T] = loop.create_future()
        self._jobs.put((job, loop, future))
        # Not cancellable midway: the SDK cannot abandon a transaction (it
        # times out within tens of ms), so a cancelled caller waits for the
        # job it queued; the next job then finds the port free.
        with anyio.CancelScope(shield=True):
            result = await future
        # The wait was shielded: deliver a pending cancellation now, or a
        # caller that only ever awaits the port could never be stopped.
        await anyio.lowlevel.checkpoint_if_cancelled()
        return result

    def close(self) -> None:
        self._jobs.put(_STOP)
        self._thread.join(timeout=1.0)
        with contextlib.suppress(Exception):
            self._port.closePort()


def _settle(future: asyncio.Future[Any], result: Any, exc: BaseException | None) -> None:
    if future.done():
        return
    if exc is not None:
        future.set_exception(exc)
    else:
        future.set_result(result)


class WaitingPortHandler(dxl.PortHandler):  # type: ignore[misc]
    """dynamixel-sdk's ``PortHandler`` that waits for bytes instead of polling for them.

    The SDK reads with ``timeout=0`` in a loop until its packet deadline
    (``setPacketTimeout``: bytes × 10/baud + 2 × 16 ms + 2 ms). Here a read
    that finds nothing waits in ``poll()`` — no CPU, the GIL released —
    until bytes arrive or that deadline passes; a read that finds bytes
    returns them at once, so nothing is slower than the SDK's loop. Each
    system read takes everything that has arrived (a USB adapter hands over
    a millisecond's worth at a time) and the SDK's small reads, a status
    packet's header then its body, are served from that: one system call
    per chunk, not two per servo. The deadline is kept on
    :func:`whexar.runtime.clock.monotonic` (the SDK's own uses the wall
    clock, which may jump).
    """

    timeout_cap_ms: float | None = None
    """When set, no packet timeout is longer (see :meth:`DxlBus.ping`)."""
    lock: PortLock | None = None
    """The port's lock (:func:`open_port` takes it); closing the port lets it go."""
    packet_start_time: float
    packet_timeout: float
    ser: Any
    _CHUNK: Final = 4096
    """Bytes taken from the OS per read: more than any reply of 42 servos."""

    def getCurrentTime(self) -> float:  # noqa: N802 — the SDK's name; milliseconds
        return monotonic() * 1000.0

    def setPacketTimeout(self, packet_length: int) -> None:  # noqa: N802
        super().setPacketTimeout(packet_length)
        armed: float = self.packet_timeout
        if self.timeout_cap_ms is not None:
            self.packet_timeout = min(armed, self.timeout_cap_ms)

    def setupPort(self, cflag_baud: int) -> bool:  # noqa: N802
        self._rx = bytearray()
        ok: bool = super().setupPort(cflag_baud)
        self._fd: int = self.ser.fileno()
        self._poll = select.poll()
        self._poll.register(self._fd, select.POLLIN)
        return ok

    def clearPort(self) -> None:  # noqa: N802
        self._rx.clear()
        super().clearPort()

    def closePort(self) -> None:  # noqa: N802
        try:
            super().closePort()
        finally:
            if self.lock is not None and not self._rebauding:
                self.lock.release()
                self.lock = None

    _rebauding = False
    """The SDK's ``setBaudRate`` closes the port and opens it again: the lock stays."""

    def setBaudRate(self, baudrate: int) -> bool:  # noqa: N802
        self._rebauding = True
        try:
            ok: bool = super().setBaudRate(baudrate)
            return ok
        finally:
            self._rebauding = False

    def getBytesAvailable(self) -> int:  # noqa: N802
        waiting: int = self.ser.in_waiting
        return len(self._rx) + waiting

    def peek(self) -> bytes:
        """The bytes received and not yet read (what :meth:`DxlBus.sync_read` looks at)."""
        return bytes(self._rx)

    def readPort(self, length: int) -> bytes:  # noqa: N802
        rx = self._rx
        if not rx:
            # poll() returns at once when bytes are there, else sleeps until they come or
            # the packet deadline passes; then one read takes all that arrived (the fd is
            # non-blocking: pyserial opened it so).
            deadline_ms: float = self.packet_start_time + self.packet_timeout
            left_ms = max(0.0, deadline_ms - self.getCurrentTime())
            if self._poll.poll(math.ceil(left_ms)):
                try:
                    got = os.read(self._fd, self._CHUNK)
                except BlockingIOError:  # a spurious wake-up: nothing yet
                    got = None
                if got == b"":  # readable yet empty: the device is gone (as pyserial says)
                    raise OSError(errno.EIO, "device reports readiness but returned no data")
                if got:
                    rx += got
        data = bytes(rx[:length])
        del rx[:length]
        return data


def tap_port(port: Any, tap: LinkTap, now: Callable[[], float]) -> None:
    """Report every byte the SDK writes to ``port`` and every byte it reads from it.

    ``tap`` gets ``("tx", now(), bytes)`` after each write, ``("rx", t, bytes)`` for
    the bytes read, and ``("timeout", now(), b"")`` when the SDK's wait for a reply
    times out (a recorder: :meth:`whexar.runtime.actor.Actor.tap`); bytes the SDK
    drops unread with ``clearPort()`` never reached it, so they are not reported.

    Reads stamped alike are reported as one chunk, when something else happens on
    the port (a write, a timeout, a read at another time, ``closePort()``): the SDK
    reads a status packet in two or three pieces, and a sync read of 42 servos
    would otherwise be some hundred reports per cycle. The instance's methods are
    wrapped, nothing else: the SDK keeps using the port's own attributes directly.
    """
    write, read, timed_out, close = (
        port.writePort,
        port.readPort,
        port.isPacketTimeout,
        port.closePort,
    )
    got: list[bytes] = []
    got_at = 0.0

    def report() -> None:
        tap("rx", got_at, b"".join(got))
        got.clear()

    def write_port(packet: Any) -> Any:
        if got:
            report()
        sent = write(packet)
        # Stamped once written: on an emulated port that is the transaction's end in bus
        # time, which a replay needs to charge the same time for it.
        tap("tx", now(), bytes(packet))
        return sent

    def read_port(length: int) -> Any:
        # 6,000 calls a second on the course: kept to the least (a closure cell for the
        # time, no copy of what already is bytes).
        nonlocal got_at
        data = read(length)
        if data:
            t = now()
            if got and t != got_at:
                report()
            got.append(data if data.__class__ is bytes else bytes(data))
            got_at = t
        return data

    def is_packet_timeout() -> Any:
        over = timed_out()
        if over:  # stamped once given up: the bus time the wait cost, for a replay
            if got:
                report()
            tap("timeout", now(), b"")
        return over

    def close_port() -> Any:
        if got:
            report()
        return close()

    def direct(kind: str, t: float, data: bytes) -> None:
        # The compiled path reads and writes the port itself and reports here, in order.
        if got:
            report()
        tap(kind, t, data)

    port.writePort = write_port
    port.readPort = read_port
    port.isPacketTimeout = is_packet_timeout
    port.closePort = close_port
    port.tap_direct = (direct, now)


def open_port(name: str, baudrate: int) -> Any:
    """Open a real serial port (U2D2, pty) as a :class:`WaitingPortHandler`.

    Raises :class:`DeviceGoneError` naming the port when it cannot be opened.
    """
    lock = PortLock.take(name)  # before a byte is written: one owner per port
    port = WaitingPortHandler(name)
    port.lock = lock
    try:
        if not port.openPort():
            raise DeviceGoneError(f"servo port {name}: could not open it")
        if not port.setBaudRate(baudrate):
            raise DeviceGoneError(f"servo port {name}: baud rate {baudrate} refused")
    except OSError as exc:
        lock.release()
        why = UNAVAILABLE.get(exc.errno or 0)
        if why is not None:
            raise PortUnavailableError(
                f"servo port {name}: {why}; `whexar doctor --port {name}` says how to fix it"
            ) from exc
        raise DeviceGoneError(f"servo port {name}: {exc}") from exc
    except BaseException:
        lock.release()
        raise
    return port


UNAVAILABLE: Final = {
    errno.ENOENT: "no such device (is the adapter plugged in?)",
    errno.ENODEV: "no such device (is the adapter plugged in?)",
    errno.EACCES: "permission denied (are you in its group, dialout?)",
    errno.EPERM: "permission denied (are you in its group, dialout?)",
    errno.EBUSY: "busy: another program has it open",
}
"""Why a port cannot be opened, by errno, where no restart can help."""


def latency_timer_ms(
    port_name: str, sysfs: Path = Path("/sys/bus/usb-serial/devices")
) -> int | None:
    """The USB-serial latency timer of ``port_name`` (ms), or ``None`` where there is none.

    FTDI adapters (the U2D2 among them) default to 16 ms, which caps a
    request/response bus at a few dozen cycles per second; every project that
    reads fast sets it to 1 ms (notes, "Practice from other Dynamixel users").
    """
    device = Path(port_name).resolve().name
    try:
        return int((sysfs / device / "latency_timer").read_text().strip())
    except (OSError, ValueError):
        return None


LATENCY_FIX = (
    "install config/99-whexar-dynamixel.rules into /etc/udev/rules.d/ and replug the adapter, "
    "or run: echo 1 | sudo tee /sys/bus/usb-serial/devices/{device}/latency_timer"
)
"""How to set the latency timer to 1 ms; ``{device}`` is the port's device name."""
