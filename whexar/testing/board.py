"""A sensor board behind a serial port, on a fake clock: for ``whexar doctor``'s tests.

:class:`FakeBoard` sends the bytes of ``firmware/PROTOCOL.md`` (through
:func:`~whexar.sensors.frame.encode_frame`) as the firmware does: it resets when its
port opens, starts ``boot_s`` later, sends a frame every period and obeys ``rate=N#``
from its next frame on. Each way the real board goes wrong is an argument: silent, at
another baud rate (what the host then reads is the frames' bytes garbled, as a UART
sampling at the wrong rate gives), plain thesis frames, a group missing, deaf to
``rate=N#``, corrupted frames, a rangefinder unplugged. A port's :meth:`read` waits on
the fake clock (up to its timeout, or until the next frame has arrived), so a check
that times the frames runs in no real time.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from whexar.doctor.environment import BOARD_READ_TIMEOUT_S as READ_TIMEOUT_S
from whexar.sensors.board_emulator import rate_command
from whexar.sensors.frame import encode_frame


@dataclass(slots=True)
class FakeClock:
    """Seconds that pass only when a fake device waits."""

    t: float = 0.0

    def now(self) -> float:
        return self.t


@dataclass
class FakeBoard:
    """The sensor board's firmware as a host sees it through its port."""

    clock: FakeClock = field(default_factory=FakeClock)
    baudrate: int = 1_000_000
    rate_hz: int = 20
    """The build's frame rate (``FRAME_RATE_HZ``), in force after every reset."""
    boot_s: float = 1.0
    """From the reset that opening the port causes to the sketch's start (the bootloader)."""
    silent: bool = False
    plain: bool = False
    """Send the thesis's frames: no ``seq``, no ``crc``."""
    obeys_rate: bool = True
    accelerometer: bool = False
    fsr: bool = True
    ir: tuple[int, int] = (80, 80)
    corrupt_every: int = 0
    """Flip a bit in every n-th frame (0: never)."""
    opened: list[int] = field(default_factory=list)
    """The baud rate of every open, in order."""
    commands: list[bytes] = field(default_factory=list)

    def open(self, name: str, baudrate: int) -> FakeBoardPort:
        """Open the port at ``baudrate``: the board resets, as a Mega's does (DTR)."""
        self.opened.append(baudrate)
        return FakeBoardPort(self, baudrate)


class FakeBoardPort:
    """One open of :class:`FakeBoard`'s port."""

    def __init__(self, board: FakeBoard, baudrate: int) -> None:
        self.board = board
        self.baudrate = baudrate
        self.closed = False
        clock = board.clock
        self._period = 1.0 / board.rate_hz
        self._next = clock.t + board.boot_s + self._period
        self._seq = 0
        self._command = bytearray()

    def read(self, size: int) -> bytes:
        assert not self.closed, "read after close"
        clock, board = self.board.clock, self.board
        if board.silent or clock.t + READ_TIMEOUT_S < self._next:
            clock.t += READ_TIMEOUT_S
            return b""
        clock.t = max(clock.t, self._next)
        data = self._frame()
        self._next += self._period
        if self.baudrate != board.baudrate:
            # Sampled at the wrong rate: the bits land in other places, no frame survives.
            return bytes((b * 7 + 0x55) & 0xFF for b in data)
        return data[:size]

    def _frame(self) -> bytes:
        board = self.board
        seq = self._seq
        self._seq = (seq + 1) % 65536
        data = encode_frame(
            seq=None if board.plain else seq,
            ir=board.ir,
            acc=(338, 338, 405) if board.accelerometer else None,
            fsr=(0, 12, 230, 251, 0, 198) if board.fsr else None,
            checksum=not board.plain,
        )
        if board.corrupt_every and seq % board.corrupt_every == board.corrupt_every - 1:
            at = len(data) // 2
            data = data[:at] + bytes([data[at] ^ 0x01]) + data[at + 1 :]
        return data

    def write(self, data: bytes) -> int:
        for byte in data:
            if byte != ord("#"):
                self._command.append(byte)
                continue
            command, self._command = bytes(self._command), bytearray()
            self.board.commands.append(command + b"#")
            rate = rate_command(command)
            if self.board.obeys_rate and rate is not None:
                # From the next frame on, one new period after it (firmware/PROTOCOL.md).
                self._period = 1.0 / rate
        return len(data)

    def reset_input_buffer(self) -> None:
        pass

    def close(self) -> None:
        self.closed = True


__all__ = ["READ_TIMEOUT_S", "FakeBoard", "FakeBoardPort", "FakeClock"]
