"""An in-process sensor board: the firmware's behaviour in Python, on the runtime clock.

Theory of operation
-------------------
The real board (``firmware/``) samples every analog input at 50 Hz, keeps a
5-sample trimmed mean per input and sends a checked frame every
1/frame-rate seconds (``firmware/PROTOCOL.md``). :class:`SensorBoardEmulator`
does the same arithmetic, frame for frame, and hands the bytes to the reader
through :class:`EmulatedBoardLink`, a :class:`~whexar.sensors.serial_link.ByteLink`
whose frames arrive when their last byte would have crossed the wire at the
board's baud rate. So the sensor reader runs unchanged on virtual time, in
tests and in the simulator; the firmware itself runs under simavr in the
end-to-end tests, which check it against the same protocol.

Opening a link resets the board, as opening an Arduino Mega's USB port
pulses DTR: sequence numbers start from 0 again, the filters refill and the
frame rate is the build's default again (a ``rate=N#`` is forgotten). The
sketch starts ``boot_s`` after the reset — a real Mega's bootloader waits
about a second first; the default, 0, keeps frames on the frame clock — and
sends its first frame one frame period later. Like the firmware's default
build (``WITH_ACCEL=0``), the board has no analog accelerometer unless
``accelerometer=True``.

Faults are methods (``unplug``, ``silence``, ``corrupt``, ``drop``,
``inject``, ``reset``) that a test or a scenario calls at the time it wants
them.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Final

import anyio

from whexar.errors import DeviceGoneError, UsageError
from whexar.kinematics.sensing import ADC_MAX
from whexar.runtime.clock import Clock
from whexar.runtime.devices import DeviceKind
from whexar.sensors.frame import ACC_KEYS, FSR_KEYS, IR_KEYS, encode_frame

SAMPLE_RATE_HZ: Final = 50.0
"""ADC sampling of every input (Žák 2023, 6.1.2, 6.1.5)."""
FILTER_WINDOW: Final = 5
"""Samples in each input's trimmed mean (firmware/PROTOCOL.md "Timing")."""
BITS_PER_BYTE: Final = 10
"""8N1: start bit, 8 data bits, stop bit."""
CHANNELS: Final = (*IR_KEYS, *ACC_KEYS, *FSR_KEYS)
"""Every analog input of the board, by its frame key."""
RATE_MIN_HZ: Final = 10
RATE_MAX_HZ: Final = 50
"""The ``rate=N#`` command's range (firmware/PROTOCOL.md "Host to board")."""

Script = Callable[[float], Mapping[str, int]]
"""Board time (s since reset) → ADC counts of the inputs that change."""


class TrimmedMean:
    """One input's filter: the mean of the middle 3 of the last 5 samples, rounded."""

    __slots__ = ("_window",)

    def __init__(self, first: int) -> None:
        # The firmware fills its window with the first sample, so the very
        # first frame is already a valid reading.
        self._window: deque[int] = deque([first] * FILTER_WINDOW, maxlen=FILTER_WINDOW)

    def push(self, sample: int) -> None:
        self._window.append(sample)

    @property
    def value(self) -> int:
        ordered = sorted(self._window)
        total = sum(ordered[1:-1])
        return (total + 1) // 3  # round half up, as the firmware's integer code does


def counts_for_distance(distance_m: float, k_cm: float, exponent: float) -> int:
    """The IR reading that eq. 5.5 maps back to ``distance_m`` (its inverse, rounded)."""
    if distance_m <= 0:
        raise UsageError(f"distance_m = {distance_m!r}: must be positive")
    counts = float((100.0 * distance_m / k_cm) ** (1.0 / exponent))
    return max(1, min(ADC_MAX, round(counts)))


def counts_for_acceleration(
    accel_g: tuple[float, float, float],
    zero_g_counts: tuple[float, float, float],
    counts_per_g: tuple[float, float, float],
) -> tuple[int, int, int]:
    """The analog accelerometer's readings for ``accel_g`` (each axis linear, clipped)."""
    x, y, z = (
        max(0, min(ADC_MAX, round(zero + a * per)))
        for a, zero, per in zip(accel_g, zero_g_counts, counts_per_g, strict=True)
    )
    return x, y, z


@dataclass
class BoardFaults:
    """What is wrong with the board right now; the emulator's methods set these."""

    unplugged: bool = False
    silent_until: float = -math.inf
    corrupt: int = 0
    drop: int = 0


class SensorBoardEmulator:
    """The sensor board's firmware in Python (see the module docstring).

    ``counts`` holds the present ADC reading of each input by frame key;
    :meth:`set` changes them, or ``script`` gives them as a function of the
    board's time. ``accelerometer=True`` adds ``accx/accy/accz`` to the
    frames (a ``WITH_ACCEL=1`` build); ``boot_s`` is the silence after every
    reset before the sketch starts. ``frame_rate_hz`` is the build's default
    rate (``FRAME_RATE_HZ``); :attr:`rate_hz` is the rate in force now.
    """

    def __init__(
        self,
        *,
        frame_rate_hz: float = 20.0,
        baudrate: int = 1_000_000,
        accelerometer: bool = False,
        boot_s: float = 0.0,
        counts: Mapping[str, int] | None = None,
        script: Script | None = None,
    ) -> None:
        if not RATE_MIN_HZ <= frame_rate_hz <= RATE_MAX_HZ:
            raise UsageError(
                f"frame_rate_hz = {frame_rate_hz!r}: must lie in {RATE_MIN_HZ}…{RATE_MAX_HZ}"
            )
        if not (math.isfinite(boot_s) and boot_s >= 0):
            raise UsageError(f"boot_s = {boot_s!r}: must be a finite time >= 0")
        self.frame_rate_hz = frame_rate_hz
        self.baudrate = baudrate
        self.accelerometer = accelerometer
        self.boot_s = boot_s
        self.script = script
        # Level and unloaded, nothing in range: acc z reads +1 g on the
        # default ADXL335 calibration; 80 counts is beyond 2 m by eq. 5.5.
        self.counts: dict[str, int] = {"ir1": 80, "ir2": 80, "accx": 338, "accy": 338}
        self.counts.update({"accz": 405, **dict.fromkeys(FSR_KEYS, 0)})
        if counts:
            self.set(**counts)
        self.faults = BoardFaults()
        self.frames_sent = 0
        self.resets = 0
        self.commands: list[bytes] = []
        self._link: EmulatedBoardLink | None = None

    @property
    def rate_hz(self) -> float:
        """The frame rate in force: the build's default, or what ``rate=N#`` set since reset."""
        return self._link.rate_hz if self._link is not None else self.frame_rate_hz

    def set(self, **counts: int) -> None:
        """Set inputs by frame key (``ir1=300, fsr2=512``); values are ADC counts."""
        for key, value in counts.items():
            if key not in CHANNELS:
                raise UsageError(f"{key!r}: not an input (known: {', '.join(CHANNELS)})")
            if not 0 <= value <= ADC_MAX:
                raise UsageError(f"{key} = {value!r}: ADC counts lie in 0…{ADC_MAX}")
            self.counts[key] = int(value)

    def inputs_at(self, board_t: float) -> dict[str, int]:
        """Every input's reading at board time ``board_t``."""
        if self.script is None:
            return self.counts
        return {**self.counts, **self.script(board_t)}

    # ------------------------------------------------------------------ faults

    def unplug(self) -> None:
        """The USB cable is pulled: the open link ends and no new one opens."""
        self.faults.unplugged = True
        if self._link is not None:
            self._link.wake()

    def replug(self) -> None:
        """The cable is back: the next open succeeds (and resets the board)."""
        self.faults.unplugged = False

    def silence(self, until_board_s: float) -> None:
        """The board sends nothing until board time ``until_board_s`` (frames are lost)."""
        self.faults.silent_until = until_board_s

    def corrupt(self, frames: int = 1) -> None:
        """Flip one bit in each of the next ``frames`` frames."""
        self.faults.corrupt += frames

    def drop(self, frames: int = 1) -> None:
        """Lose the next ``frames`` frames on the wire (their sequence numbers are skipped)."""
        self.faults.drop += frames

    def reset(self) -> None:
        """The board restarts with its link still open (a brown-out, the watchdog, the reset
        button): the frame on its way is lost, and after ``boot_s`` the sketch starts over —
        ``seq`` from 0, filters refilled, the build's default frame rate."""
        self.resets += 1
        if self._link is not None:
            self._link.restart_pending = True
            self._link.wake()

    def inject(self, data: bytes) -> None:
        """Put ``data`` on the wire now, between frames (noise, a stray reset message)."""
        if self._link is not None:
            self._link.pending.append(data)
            self._link.wake()

    # ------------------------------------------------------------------ link

    def open(self, clock: Clock) -> EmulatedBoardLink:
        """Connect, as opening the port would: the board resets; raises when unplugged."""
        if self.faults.unplugged:
            raise DeviceGoneError("emulated sensor board: unplugged")
        if self._link is not None:
            self._link.closed = True
            self._link.wake()
        self.resets += 1
        self._link = EmulatedBoardLink(self, clock)
        return self._link


SENSOR_BOARD: Final = DeviceKind[SensorBoardEmulator]("emulated sensor board", "emulator")
"""Emulated boards in :data:`~whexar.runtime.devices.DEVICES`: ``port = "emulator:NAME"`` of
:class:`~whexar.actors.sensing.SensorReader` opens the one registered as NAME."""


class EmulatedBoardLink:
    """A :class:`~whexar.sensors.serial_link.ByteLink` to an emulated board (runtime clock)."""

    def __init__(self, board: SensorBoardEmulator, clock: Clock) -> None:
        self.board = board
        self.name = "emulator"
        self.closed = False
        self.pending: list[bytes] = []
        self.restart_pending = False
        self._clock = clock
        self._command = bytearray()
        self._woken = anyio.Event()
        self._start()

    def _start(self) -> None:
        """The sketch's ``setup()``, ``boot_s`` from now: board time 0 is when it runs."""
        self._t0 = self._clock.now() + self.board.boot_s
        self.rate_hz: float = self.board.frame_rate_hz
        self._period = 1.0 / self.rate_hz
        self._next_frame = self._period
        self._next_sample = 0.0
        self._seq = 0
        self._filters: dict[str, TrimmedMean] | None = None

    def wake(self) -> None:
        self._woken.set()

    def _sample_until(self, board_t: float) -> None:
        # Every 50 Hz sample up to and including board_t, as the firmware takes them.
        step = 1.0 / SAMPLE_RATE_HZ
        while self._next_sample <= board_t + 1e-12:
            inputs = self.board.inputs_at(self._next_sample)
            if self._filters is None:
                self._filters = {key: TrimmedMean(inputs[key]) for key in CHANNELS}
            else:
                for key, flt in self._filters.items():
                    flt.push(inputs[key])
            self._next_sample += step

    def _frame(self) -> bytes:
        filters = self._filters
        assert filters is not None
        values = {key: flt.value for key, flt in filters.items()}
        data = encode_frame(
            seq=self._seq,
            ir=[values[k] for k in IR_KEYS],
            acc=[values[k] for k in ACC_KEYS] if self.board.accelerometer else None,
            fsr=[values[k] for k in FSR_KEYS],
        )
        self._seq = (self._seq + 1) % 65536
        return data

    def _gone(self) -> bool:
        return self.closed or self.board.faults.unplugged

    async def receive(self) -> bytes:
        board, faults = self.board, self.board.faults
        while True:
            if self._gone():
                raise DeviceGoneError("emulated sensor board: unplugged")
            if self.restart_pending:
                self.restart_pending = False
                self._start()
            if self.pending:
                data = b"".join(self.pending)
                self.pending.clear()
                return data
            frame_t = self._next_frame
            self._sample_until(frame_t)
            data = self._frame()
            arrival = self._t0 + frame_t + len(data) * BITS_PER_BYTE / board.baudrate
            with anyio.move_on_after(max(0.0, arrival - self._clock.now())):
                await self._woken.wait()
            if self._woken.is_set():
                # Woken early (a fault, injected bytes, a reset): this frame is
                # not sent yet; undo its sequence number and look again.
                self._woken = anyio.Event()
                self._seq = (self._seq - 1) % 65536
                continue
            self._next_frame = frame_t + self._period
            if frame_t < faults.silent_until:
                continue
            if faults.drop:
                faults.drop -= 1
                continue
            if faults.corrupt:
                faults.corrupt -= 1
                data = _flip_bit(data, self._seq)
            board.frames_sent += 1
            return data

    async def send(self, data: bytes) -> None:
        if self._gone():
            raise DeviceGoneError("emulated sensor board: unplugged")
        for byte in data:
            if byte != ord("#"):
                self._command.append(byte)
                del self._command[:-16]
                continue
            command, self._command = bytes(self._command), bytearray()
            self.board.commands.append(command + b"#")
            rate = rate_command(command)
            if rate is not None:
                self._period = 1.0 / rate
                self.rate_hz = rate

    async def aclose(self) -> None:
        self.closed = True


def rate_command(command: bytes) -> int | None:
    """The rate a host-to-board command (its bytes before ``#``) asks for, ``None`` when
    the firmware ignores it. As the firmware's parser (frame.cpp): blanks before it are
    skipped, N has 1 to 3 digits and lies in 10 … 50 (firmware/PROTOCOL.md)."""
    command = command.lstrip(b" \t\r\n\x00")
    digits = command.removeprefix(b"rate=")
    if not (command.startswith(b"rate=") and digits.isdigit() and len(digits) <= 3):
        return None
    rate = int(digits)
    return rate if RATE_MIN_HZ <= rate <= RATE_MAX_HZ else None


def _flip_bit(data: bytes, salt: int) -> bytes:
    """``data`` with one bit flipped, at a position that depends on ``salt`` (deterministic)."""
    index = (salt * 7919) % (len(data) - 1)  # never the terminating '#' itself
    flipped = bytearray(data)
    flipped[index] ^= 1 << (salt % 7)
    return bytes(flipped)


__all__ = [
    "CHANNELS",
    "FILTER_WINDOW",
    "SAMPLE_RATE_HZ",
    "SENSOR_BOARD",
    "EmulatedBoardLink",
    "SensorBoardEmulator",
    "TrimmedMean",
    "counts_for_acceleration",
    "counts_for_distance",
    "rate_command",
]
