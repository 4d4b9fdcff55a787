"""The sensor board's serial rate: what the ATmega2560 at 16 MHz can send, as the firmware sets it.

Theory of operation
-------------------
The USART makes its bit clock by dividing the CPU clock: the rate is
``f_osc / (16 · (UBRR + 1))``, or ``f_osc / (8 · (UBRR + 1))`` with the
double-speed bit U2X set (ATmega640/1280/1281/2560/2561 datasheet, Atmel
2549Q, 22.3.1 and Table 22-1). With an integer UBRR most rates are only
approximated. The datasheet tabulates the error of the common rates,
``Error = (closest match / rate − 1) · 100 %`` (22.11, "Examples of Baud Rate
Setting"; the 16 MHz column is in Table 22-12), and recommends a receiver
error of at most ±2.0 % for frames of 8 data bits without parity in normal
speed and ±1.5 % in double speed ("Asynchronous Operational Range", p. 215,
Tables 22-2 and 22-3).

The firmware does not pick UBRR itself: ``Serial.begin()`` of the Arduino
core (``HardwareSerial::begin``) tries U2X first, with
``UBRR = (f / 4 / rate − 1) / 2`` in integer arithmetic, and falls back to
normal speed, ``UBRR = (f / 8 / rate − 1) / 2``, when that UBRR exceeds 4095
or — a hard-coded exception for old bootloaders — for 57600 bps at 16 MHz.
So a rate counts as supported when the setting *the firmware actually
programs* is within ±2 % of it. That rules out 115200 bps (U2X, UBRR = 16:
+2.1 %) and 57600 bps (forced to normal speed, UBRR = 16: +2.1 %, although
U2X with UBRR = 34 would give −0.8 %), as well as 230400 bps (−3.5 %); the
rates that pass all come out within 0.64 %, so the stricter ±1.5 % of double
speed selects the same set. The host's end of the Mega's USB link, an
ATmega16U2 at 16 MHz, rounds the same way, but nothing here counts on that.

The rate must also carry the frames: the longest frame the firmware sends
(:data:`LONGEST_FRAME_BYTES`, every value at four digits) at the highest
rate the host may ask for (``rate=50#``, :data:`MAX_FRAME_RATE_HZ`), 10 bits
per byte (8N1). Slower, the board's transmit buffer fills and
``Serial.write`` blocks its sampling loop. That rules out 38400 bps and below.

:func:`usart_setting` is the first rule, :func:`carries_frames` the second;
:data:`BOARD_BAUDRATES` are the datasheet's table rates (and its 2 Mbps
maximum at 16 MHz) that pass both. The firmware checks the same two rules at
compile time for its ``BAUD`` build option
(``firmware/whexar_sensors/serial_baud.h``), and ``sensor_board.baudrate`` in
the robot configuration must be one of :data:`BOARD_BAUDRATES`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

from whexar.sensors.frame import encode_frame

F_CPU_HZ: Final = 16_000_000
"""The Arduino Mega 2560's crystal (``F_CPU`` in ``firmware/Makefile``)."""
MAX_ERROR: Final = 0.02
"""Recommended receiver error for 8-bit frames, normal speed (datasheet Table 22-2)."""
TABLE_RATES: Final = (
    2400,
    4800,
    9600,
    14400,
    19200,
    28800,
    38400,
    57600,
    76800,
    115200,
    230400,
    250000,
    500000,
    1_000_000,
    2_000_000,
)
"""The rates of the datasheet's table (Table 22-12), with its 2 Mbps maximum at 16 MHz (U2X)."""
BITS_PER_BYTE: Final = 10
"""8N1: a start bit, 8 data bits, a stop bit."""
MAX_FRAME_RATE_HZ: Final = 50
"""The highest frame rate ``rate=N#`` may set (firmware/PROTOCOL.md "Host to board")."""
LONGEST_FRAME_BYTES: Final = len(
    encode_frame(seq=65535, ir=(1023,) * 2, acc=(1023,) * 3, fsr=(1023,) * 6)
)
"""The longest frame the firmware sends, with its accelerometer fields and ``#`` (127 bytes)."""
UBRR_MAX: Final = 4095
"""UBRRn (UBRRnH:UBRRnL) is 12 bits wide; the Arduino core checks the same bound."""


@dataclass(frozen=True, slots=True)
class UsartSetting:
    """The USART setting the Arduino core programs for ``rate``, and what it gives."""

    rate: int
    u2x: bool
    ubrr: int
    actual_bps: float
    error: float
    """(actual / rate − 1), as a fraction: +0.021 is the datasheet's "2.1 %"."""

    @property
    def ok(self) -> bool:
        """Within :data:`MAX_ERROR` of the rate asked for."""
        return abs(self.error) <= MAX_ERROR


def usart_setting(rate: int, f_cpu: int = F_CPU_HZ) -> UsartSetting:
    """The (U2X, UBRR) that ``Serial.begin(rate)`` programs, the rate it gives and its error.

    Integer arithmetic exactly as ``HardwareSerial::begin`` of the Arduino AVR
    core (1.8): see the module docstring.
    """
    if rate <= 0:
        raise ValueError(f"rate = {rate!r}: must be positive")
    ubrr = (f_cpu // 4 // rate - 1) // 2
    u2x = True
    if (f_cpu == 16_000_000 and rate == 57600) or ubrr > UBRR_MAX:
        u2x = False
        ubrr = (f_cpu // 8 // rate - 1) // 2
    ubrr = max(ubrr, 0)
    actual = f_cpu / ((8 if u2x else 16) * (ubrr + 1))
    return UsartSetting(rate, u2x, ubrr, actual, actual / rate - 1.0)


def carries_frames(rate: int) -> bool:
    """Whether ``rate`` carries the longest frame at the highest frame rate (8N1)."""
    return rate >= LONGEST_FRAME_BYTES * BITS_PER_BYTE * MAX_FRAME_RATE_HZ


BOARD_BAUDRATES: Final = tuple(r for r in TABLE_RATES if usart_setting(r).ok and carries_frames(r))
"""The sensor board's serial rates: 76800, 250000, 500000, 1000000 and 2000000 bps (module)."""


def baudrate_problem(rate: int) -> str | None:
    """``None`` if the board supports ``rate``; else why not and what it supports."""
    if rate in BOARD_BAUDRATES:
        return None
    allowed = ", ".join(str(r) for r in BOARD_BAUDRATES)
    if rate <= 0:
        why = "not a rate"
    elif not (s := usart_setting(rate)).ok:
        mode = "U2X" if s.u2x else "normal speed"
        why = (
            f"the firmware's USART setting ({mode}, UBRR = {s.ubrr}) gives "
            f"{s.actual_bps:.0f} bps, {100 * s.error:+.1f} %"
        )
    elif not carries_frames(rate):
        need = LONGEST_FRAME_BYTES * BITS_PER_BYTE * MAX_FRAME_RATE_HZ
        why = (
            f"too slow for {LONGEST_FRAME_BYTES}-byte frames at {MAX_FRAME_RATE_HZ} Hz ({need} bps)"
        )
    else:
        why = "not one of the datasheet's rates (Table 22-12)"
    return (
        f"a rate the ATmega2560 at 16 MHz reaches within ±2 % as the firmware sets it and "
        f"that carries its frames (datasheet Tables 22-2, 22-12): {allowed}; "
        f"{rate} bps: {why}"
    )


__all__ = [
    "BOARD_BAUDRATES",
    "F_CPU_HZ",
    "LONGEST_FRAME_BYTES",
    "MAX_ERROR",
    "MAX_FRAME_RATE_HZ",
    "TABLE_RATES",
    "UsartSetting",
    "baudrate_problem",
    "carries_frames",
    "usart_setting",
]
