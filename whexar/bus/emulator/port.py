"""The servo chain as a serial port for dynamixel-sdk, on bus time.

:class:`EmulatedPort` is the duck-typed ``PortHandler`` the SDK drives, so the
real SDK runs unmodified in-process: each write is one transaction of a
:class:`~whexar.bus.emulator.chain.ServoChain` at bus time, its cost added up;
when the SDK waits for bytes that will never come, the port charges the
SDK's own timeout instead of sleeping.
"""

from __future__ import annotations

import errno
from collections.abc import Callable, Sequence
from typing import Final

from whexar.bus.emulator.chain import ServoChain, Transaction

_SDK_BAUDRATES: Final = frozenset(
    {9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 576000, 921600, 1000000}
    | {1152000, 2000000, 2500000, 3000000, 3500000, 4000000}
)
"""Rates dynamixel-sdk 4.1.0's ``PortHandler.setBaudRate`` accepts."""


class EmulatedPort:
    """Duck-typed port for dynamixel-sdk that talks to a :class:`ServoChain` on bus time.

    The SDK uses only ``is_using``, ``clearPort()``, ``writePort(bytes)``,
    ``readPort(n)``, ``setPacketTimeout(n)``, ``setPacketTimeoutMillis(ms)``,
    ``isPacketTimeout()`` and ``getBaudRate()``; the rest of ``PortHandler``'s
    surface is here too. Each write runs one transaction at bus time
    ``now() + elapsed_s`` and adds its cost to :attr:`elapsed_s`. The SDK asks
    whether it has timed out only when bytes are missing; the port then
    charges the rest of the SDK's timeout (``tx_time_per_byte·n + 2·latency
    timer + 2 ms``, counted from the write, as ``PortHandler`` does) and says
    yes, so a failed read costs what it costs on a real bus.
    """

    def __init__(
        self,
        chain: ServoChain,
        now: Callable[[], float] = lambda: 0.0,
        *,
        latency_timer_ms: float = 16.0,
        timer: Callable[[], float] | None = None,
    ) -> None:
        self.chain = chain
        self.now = now
        self.latency_timer_ms = latency_timer_ms
        self.timer = timer
        self.is_open = True
        self.is_using = False
        self.timeout_cap_ms: float | None = None
        """When set, no packet timeout is longer (:meth:`~whexar.bus.sdk.DxlBus.ping`)."""
        self.port_name = "emulated"
        self.baudrate = chain.timing.baudrate
        self.elapsed_s = 0.0
        """Bus time accumulated since the last :meth:`take_elapsed`."""
        self.emulator_s = 0.0
        """Host CPU seconds spent inside the chain (only counted when ``timer`` is given)."""
        self.last: Transaction | None = None
        # Received bytes are _rx[_rx_at:]: a read slices once and moves the mark, where a
        # bytearray would copy twice and shift its contents (two reads per status packet).
        self._rx = b""
        self._rx_at = 0
        self._tx_start = 0.0
        self._deadline = 0.0

    @property
    def tx_time_per_byte(self) -> float:
        """Milliseconds per byte at the port's baud rate (``PortHandler``'s attribute)."""
        return 1000.0 / self.baudrate * 10.0

    def take_elapsed(self) -> float:
        """Return :attr:`elapsed_s` and reset it to 0."""
        elapsed = self.elapsed_s
        self.elapsed_s = 0.0
        self._tx_start -= elapsed
        self._deadline -= elapsed
        return elapsed

    def _check_plugged(self) -> None:
        if self.chain.faults.unplugged:
            raise OSError(errno.EIO, "emulated port: device disconnected")

    def openPort(self) -> bool:  # noqa: N802
        """Always succeeds: there is no device to open."""
        self.is_open = True
        return True

    def closePort(self) -> None:  # noqa: N802
        """Mark the port closed (the chain keeps its state)."""
        self.is_open = False

    def clearPort(self) -> None:  # noqa: N802
        """Drop received bytes not yet read (the SDK does this before every transmit)."""
        self._rx = b""
        self._rx_at = 0

    def setPortName(self, port_name: str) -> None:  # noqa: N802
        """Rename the port (cosmetic)."""
        self.port_name = port_name

    def getPortName(self) -> str:  # noqa: N802
        """The port's name, ``"emulated"`` unless renamed."""
        return self.port_name

    def setBaudRate(self, baudrate: int) -> bool:  # noqa: N802
        """Accept a rate from the SDK's list; servos at another rate will not hear the port."""
        if baudrate not in _SDK_BAUDRATES:
            return False
        self.baudrate = baudrate
        return True

    def getBaudRate(self) -> int:  # noqa: N802
        """The port's baud rate."""
        return self.baudrate

    def getBytesAvailable(self) -> int:  # noqa: N802
        """Received bytes not yet read."""
        return len(self._rx) - self._rx_at

    def peek(self) -> bytes:
        """The received bytes not yet read."""
        return self._rx[self._rx_at :]

    def readPort(self, length: int) -> bytes:  # noqa: N802
        """Up to ``length`` received bytes; ``OSError(EIO)`` when unplugged."""
        if self.chain.faults.unplugged:
            self._check_plugged()
        at = self._rx_at
        # The SDK can ask for a negative count: then slicing the unread bytes decides, as ever.
        data = self._rx[at : at + length] if length >= 0 else self._rx[at:][:length]
        self._rx_at = at + len(data)
        return data

    def writePort(self, packet: bytes | Sequence[int]) -> int:  # noqa: N802
        """Send ``packet``: one chain transaction, its reply buffered, its cost added."""
        self._check_plugged()
        data = bytes(packet)
        self._tx_start = self._deadline = self.elapsed_s
        if self.chain.faults.tx_fail > 0:
            self.chain.faults.tx_fail -= 1
            return 0
        if self.baudrate != self.chain.timing.baudrate:
            # Servos at another rate see framing errors only: nothing answers.
            self.elapsed_s += len(data) * self.chain.timing.bits_per_byte / self.baudrate
            return len(data)
        started = self.timer() if self.timer is not None else 0.0
        tx = self.chain.transact(data, self.now() + self.elapsed_s)
        if self.timer is not None:
            self.emulator_s += self.timer() - started
        self.last = tx
        if tx.reply:
            self._rx = self._rx[self._rx_at :] + tx.reply
            self._rx_at = 0
        self.elapsed_s += tx.cost_s
        return len(data)

    def setPacketTimeout(self, packet_length: int) -> None:  # noqa: N802
        """Arm the SDK's timeout for ``packet_length`` bytes, counted from the last write."""
        # dynamixel_sdk PortHandler: tx_time_per_byte·n + LATENCY_TIMER·2 + 2 ms.
        ms = self.tx_time_per_byte * packet_length + 2.0 * self.latency_timer_ms + 2.0
        if self.timeout_cap_ms is not None:
            ms = min(ms, self.timeout_cap_ms)
        self._deadline = self._tx_start + ms / 1000.0

    def setPacketTimeoutMillis(self, msec: float) -> None:  # noqa: N802
        """Arm a timeout of ``msec`` ms, counted from the last write."""
        self._deadline = self._tx_start + msec / 1000.0

    def isPacketTimeout(self) -> bool:  # noqa: N802
        """True once nothing is left to read; bus time then runs on to the deadline."""
        if self._rx_at < len(self._rx):
            return False
        self.elapsed_s = max(self.elapsed_s, self._deadline)
        return True
