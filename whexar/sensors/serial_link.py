"""Byte links to the sensor board: a real serial port through pyserial-asyncio.

Theory of operation
-------------------
The sensor reader only needs three things from its link — bytes as they
arrive, a way to send a short command, and to know when the device went
away — so a link is the small :class:`ByteLink` protocol. :class:`SerialLink`
is the one the robot runs: pyserial-asyncio registers the port's descriptor
with the event loop, and every chunk the kernel hands over is queued by the
protocol callback and returned by :meth:`SerialLink.receive` in the same loop
iteration; there is no polling and no thread. A vanished device (USB
unplugged, a pty whose other end closed) ends the connection, and
``receive`` raises :class:`~whexar.errors.DeviceGoneError` once the bytes
that did arrive are consumed. The in-process board emulator
(:mod:`whexar.sensors.board_emulator`) provides the same protocol on virtual time.
"""

from __future__ import annotations

import asyncio
from collections import deque
from collections.abc import Callable
from typing import Protocol

import serial
import serial_asyncio

from whexar.errors import DeviceGoneError
from whexar.runtime.channels import LinkTap


class ByteLink(Protocol):
    """What a sensor reader needs from its connection to a board."""

    name: str

    async def receive(self) -> bytes:
        """The next chunk of bytes; raises DeviceGoneError when the device is gone."""
        ...

    async def send(self, data: bytes) -> None:
        """Send ``data`` to the device (a command); raises DeviceGoneError when gone."""
        ...

    async def aclose(self) -> None:
        """Close the link; safe to call twice."""
        ...


class _Receiver(asyncio.Protocol):
    """pyserial-asyncio's callbacks, turned into a queue of chunks and an end."""

    def __init__(self) -> None:
        self.chunks: deque[bytes] = deque()
        self.gone: str | None = None
        self.waiter: asyncio.Future[None] | None = None

    def data_received(self, data: bytes) -> None:
        self.chunks.append(data)
        self._wake()

    def connection_lost(self, exc: Exception | None) -> None:
        self.gone = f"{type(exc).__name__}: {exc}" if exc is not None else "closed"
        self._wake()

    def _wake(self) -> None:
        waiter = self.waiter
        if waiter is not None and not waiter.done():
            waiter.set_result(None)


class SerialLink:
    """A serial port (a USB serial device or a pty) opened with pyserial-asyncio."""

    def __init__(self, name: str, transport: asyncio.Transport, receiver: _Receiver) -> None:
        self.name = name
        self._transport = transport
        self._rx = receiver

    @classmethod
    async def open(cls, port: str, baudrate: int) -> SerialLink:
        """Open ``port`` at ``baudrate`` 8N1; a missing or busy device is DeviceGoneError."""
        loop = asyncio.get_running_loop()
        try:
            transport, receiver = await serial_asyncio.create_serial_connection(
                loop, _Receiver, port, baudrate=baudrate
            )
        except (serial.SerialException, OSError, ValueError) as exc:
            raise DeviceGoneError(f"{port}: cannot open at {baudrate} bps: {exc}") from exc
        return cls(port, transport, receiver)

    async def receive(self) -> bytes:
        rx = self._rx
        while not rx.chunks:
            if rx.gone is not None:
                raise DeviceGoneError(f"{self.name}: {rx.gone}")
            rx.waiter = asyncio.get_running_loop().create_future()
            try:
                await rx.waiter
            finally:
                rx.waiter = None
        if len(rx.chunks) == 1:
            return rx.chunks.popleft()
        data = b"".join(rx.chunks)
        rx.chunks.clear()
        return data

    async def send(self, data: bytes) -> None:
        if self._rx.gone is not None or self._transport.is_closing():
            raise DeviceGoneError(f"{self.name}: {self._rx.gone or 'closed'}")
        try:
            self._transport.write(data)
        except (serial.SerialException, OSError) as exc:
            raise DeviceGoneError(f"{self.name}: write failed: {exc}") from exc

    async def aclose(self) -> None:
        if not self._transport.is_closing():
            self._transport.close()
        # Let the transport's close callbacks run, so the descriptor is released.
        await asyncio.sleep(0)

    def __repr__(self) -> str:
        return f"SerialLink({self.name!r})"


__all__ = ["ByteLink", "SerialLink"]


class TappedLink:
    """A :class:`ByteLink` that reports every chunk it receives and sends to ``tap``
    (``("rx" | "tx", now(), bytes)``: a recorder, :meth:`whexar.runtime.actor.Actor.tap`)."""

    def __init__(self, inner: ByteLink, tap: LinkTap, now: Callable[[], float]) -> None:
        self.inner = inner
        self.name = inner.name
        self._tap = tap
        self._now = now

    async def receive(self) -> bytes:
        """The next chunk from the device, reported as received; the device's going
        away is reported as ``gone`` with the reason."""
        try:
            data = await self.inner.receive()
        except DeviceGoneError as exc:
            self._tap("gone", self._now(), str(exc).encode())
            raise
        if data:
            self._tap("rx", self._now(), data)
        return data

    async def send(self, data: bytes) -> None:
        """Send ``data``, reported as sent (and ``gone``, if the device went away)."""
        self._tap("tx", self._now(), bytes(data))
        try:
            await self.inner.send(data)
        except DeviceGoneError as exc:
            self._tap("gone", self._now(), str(exc).encode())
            raise

    async def aclose(self) -> None:
        """Close the link under it."""
        await self.inner.aclose()
