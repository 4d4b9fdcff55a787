"""Linux input events (evdev): the kernel's ``struct input_event`` records, a sans-IO codec.

Theory of operation
-------------------
A gamepad, like every Linux input device, appears as ``/dev/input/eventN``;
reading it yields fixed-size binary records, ``struct input_event`` of
``linux/input.h`` (include/uapi/linux/input.h)::

    struct input_event {
        struct timeval time;        /* two native longs: seconds, microseconds */
        __u16 type;                 /* EV_SYN, EV_KEY, EV_ABS, ... */
        __u16 code;                 /* BTN_SOUTH, ABS_X, ... */
        __s32 value;                /* 1/0 pressed/released; an axis position */
    };

The time is two C ``long``\\ s of the *reading process* (since Linux 5.0 a
32-bit process gets ``__kernel_ulong_t __sec, __usec``, the same size), so a
record is **24 bytes for a 64-bit process** (aarch64, x86-64: Raspberry Pi OS
64-bit) and **16 bytes for a 32-bit one** (armhf: Raspberry Pi OS 32-bit, even
on a 64-bit kernel, which gives 32-bit readers the compat layout).
:data:`NATIVE_RECORD_BYTES` is this interpreter's size; :class:`EventDecoder`
takes either, so a recording from one Pi decodes on another. Byte order is
the machine's (little-endian on every Pi).

Events come in **reports**: the driver sends what changed in one device
packet, then ``EV_SYN``/``SYN_REPORT`` ("these belong together"). A reader
applies a report whole. ``SYN_DROPPED`` says the kernel's buffer for this
reader overflowed and events were lost: the reader must ignore every event up
to and including the next ``SYN_REPORT`` and then ask the device for its
present state with the ``EVIOCG*`` ioctls (Documentation/input/event-codes.rst,
"EV_SYN event codes"). :class:`EventDecoder` does the cutting: bytes in
(any split: a pipe may deliver half a record), :class:`Report` and
:class:`Dropped` out, no I/O and no clock. The ioctl request numbers
(:func:`eviocgabs`, :func:`eviocgkey`, :func:`eviocgname`) are computed here
too; the calls themselves are :mod:`whexar.sensors.evdev_link`'s.

The constants cite include/uapi/linux/input-event-codes.h (event types and
codes) and include/uapi/linux/input.h (the records, ``struct input_absinfo``
and the ioctls); the gamepad layout is Documentation/input/gamepad.rst.
Only the codes a gamepad or joystick uses are named (:data:`KEY_CODES`,
:data:`ABS_CODES`).
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Mapping
from typing import Final, NamedTuple

# --------------------------------------------------------------------------- event types
# input-event-codes.h, "Event types".

EV_SYN: Final = 0x00
EV_KEY: Final = 0x01
EV_REL: Final = 0x02
EV_ABS: Final = 0x03
EV_MSC: Final = 0x04

# input-event-codes.h, "Synchronization events".
SYN_REPORT: Final = 0
SYN_CONFIG: Final = 1
SYN_MT_REPORT: Final = 2
SYN_DROPPED: Final = 3

# --------------------------------------------------------------------------- codes
# input-event-codes.h. Gamepad buttons are named by position (gamepad.rst): BTN_A is
# an alias of BTN_SOUTH, BTN_B of BTN_EAST, BTN_X of BTN_NORTH (0x133), BTN_Y of
# BTN_WEST (0x134). Drivers differ on the last two: xpad reports the Xbox pad's X
# button (the west one) as BTN_X = 0x133 and Y (north) as BTN_Y = 0x134, while
# hid-playstation reports Triangle (north) as 0x133 and Square (west) as 0x134.

BTN_TRIGGER: Final = 0x120
BTN_SOUTH: Final = 0x130
BTN_EAST: Final = 0x131
BTN_C: Final = 0x132
BTN_NORTH: Final = 0x133
BTN_WEST: Final = 0x134
BTN_Z: Final = 0x135
BTN_TL: Final = 0x136
BTN_TR: Final = 0x137
BTN_TL2: Final = 0x138
BTN_TR2: Final = 0x139
BTN_SELECT: Final = 0x13A
BTN_START: Final = 0x13B
BTN_MODE: Final = 0x13C
BTN_THUMBL: Final = 0x13D
BTN_THUMBR: Final = 0x13E
BTN_DPAD_UP: Final = 0x220
BTN_DPAD_DOWN: Final = 0x221
BTN_DPAD_LEFT: Final = 0x222
BTN_DPAD_RIGHT: Final = 0x223
BTN_TRIGGER_HAPPY1: Final = 0x2C0
KEY_MAX: Final = 0x2FF

ABS_X: Final = 0x00
ABS_Y: Final = 0x01
ABS_Z: Final = 0x02
ABS_RX: Final = 0x03
ABS_RY: Final = 0x04
ABS_RZ: Final = 0x05
ABS_THROTTLE: Final = 0x06
ABS_RUDDER: Final = 0x07
ABS_WHEEL: Final = 0x08
ABS_GAS: Final = 0x09
ABS_BRAKE: Final = 0x0A
ABS_HAT0X: Final = 0x10
ABS_HAT0Y: Final = 0x11
ABS_MAX: Final = 0x3F

_JOYSTICK_BUTTONS: Final = (
    *("BTN_TRIGGER", "BTN_THUMB", "BTN_THUMB2", "BTN_TOP", "BTN_TOP2", "BTN_PINKIE"),
    *("BTN_BASE", "BTN_BASE2", "BTN_BASE3", "BTN_BASE4", "BTN_BASE5", "BTN_BASE6"),
)

KEY_CODES: Final[Mapping[str, int]] = {
    **{name: BTN_TRIGGER + i for i, name in enumerate(_JOYSTICK_BUTTONS)},
    "BTN_DEAD": 0x12F,
    "BTN_SOUTH": BTN_SOUTH,
    "BTN_A": BTN_SOUTH,
    "BTN_EAST": BTN_EAST,
    "BTN_B": BTN_EAST,
    "BTN_C": BTN_C,
    "BTN_NORTH": BTN_NORTH,
    "BTN_X": BTN_NORTH,
    "BTN_WEST": BTN_WEST,
    "BTN_Y": BTN_WEST,
    "BTN_Z": BTN_Z,
    "BTN_TL": BTN_TL,
    "BTN_TR": BTN_TR,
    "BTN_TL2": BTN_TL2,
    "BTN_TR2": BTN_TR2,
    "BTN_SELECT": BTN_SELECT,
    "BTN_START": BTN_START,
    "BTN_MODE": BTN_MODE,
    "BTN_THUMBL": BTN_THUMBL,
    "BTN_THUMBR": BTN_THUMBR,
    "BTN_DPAD_UP": BTN_DPAD_UP,
    "BTN_DPAD_DOWN": BTN_DPAD_DOWN,
    "BTN_DPAD_LEFT": BTN_DPAD_LEFT,
    "BTN_DPAD_RIGHT": BTN_DPAD_RIGHT,
    # 0x2c0-0x2e7: spare buttons (xpad's d-pad with dpad_to_buttons, paddles).
    **{f"BTN_TRIGGER_HAPPY{n}": BTN_TRIGGER_HAPPY1 + n - 1 for n in range(1, 41)},
}
"""The ``EV_KEY`` codes of gamepads and joysticks, by their input-event-codes.h names
(aliases included: ``BTN_A`` is ``BTN_SOUTH``)."""

ABS_CODES: Final[Mapping[str, int]] = {
    "ABS_X": ABS_X,
    "ABS_Y": ABS_Y,
    "ABS_Z": ABS_Z,
    "ABS_RX": ABS_RX,
    "ABS_RY": ABS_RY,
    "ABS_RZ": ABS_RZ,
    "ABS_THROTTLE": ABS_THROTTLE,
    "ABS_RUDDER": ABS_RUDDER,
    "ABS_WHEEL": ABS_WHEEL,
    "ABS_GAS": ABS_GAS,
    "ABS_BRAKE": ABS_BRAKE,
    **{f"ABS_HAT{n}{xy}": ABS_HAT0X + 2 * n + i for n in range(4) for i, xy in enumerate("XY")},
}
"""The ``EV_ABS`` codes of gamepads and joysticks: sticks, analog triggers, hats (d-pads).
On a gamepad (gamepad.rst) negative is left or up, positive right or down."""


def key_name(code: int) -> str:
    """The name of an ``EV_KEY`` code, position names first (``BTN_SOUTH``, not ``BTN_A``)."""
    for name, value in KEY_CODES.items():
        if value == code:
            return name
    return f"key 0x{code:03x}"


def abs_name(code: int) -> str:
    """The name of an ``EV_ABS`` code (``ABS_HAT0Y``)."""
    for name, value in ABS_CODES.items():
        if value == code:
            return name
    return f"abs 0x{code:02x}"


# --------------------------------------------------------------------------- records

RECORD_64: Final = 24
"""Bytes of a record read by a 64-bit process: ``long`` seconds and microseconds, 8 each."""
RECORD_32: Final = 16
"""Bytes of a record read by a 32-bit process (armhf): 4-byte seconds and microseconds."""
RECORD_SIZES: Final = (RECORD_32, RECORD_64)

NATIVE_RECORD_BYTES: Final = struct.calcsize("@llHHi")
"""The record this interpreter reads: two native ``long``\\ s, two ``__u16``, one ``__s32``."""

_FORMATS: Final = {
    # "=": the machine's byte order, standard sizes, no padding.
    RECORD_64: struct.Struct("=qqHHi"),  # struct timeval of a 64-bit process
    RECORD_32: struct.Struct("=LLHHi"),  # __kernel_ulong_t __sec, __usec (Linux >= 5.0)
}


def record_struct(record_bytes: int) -> struct.Struct:
    """The layout of one record of ``record_bytes`` (16 or 24); a ValueError otherwise."""
    try:
        return _FORMATS[record_bytes]
    except KeyError:
        raise ValueError(
            f"an input_event record is {RECORD_32} or {RECORD_64} bytes, not {record_bytes}"
        ) from None


class InputEvent(NamedTuple):
    """One ``struct input_event``: the kernel's timestamp, type, code and value."""

    type: int
    code: int
    value: int
    sec: int = 0
    usec: int = 0

    @property
    def time_s(self) -> float:
        """The kernel's timestamp in seconds (CLOCK_REALTIME unless EVIOCSCLOCKID changed it)."""
        return self.sec + self.usec * 1e-6


class Report(NamedTuple):
    """The events of one ``SYN_REPORT``: what changed together, in order (the SYN left out)."""

    events: tuple[InputEvent, ...]


class Dropped(NamedTuple):
    """The kernel dropped events (``SYN_DROPPED``): the state is unknown until the device is
    asked again. Given at the ``SYN_REPORT`` that ends the dropped stretch; ``discarded``
    events read in between were thrown away, as the kernel's documentation asks."""

    discarded: int


def encode(events: Iterable[InputEvent], record_bytes: int = NATIVE_RECORD_BYTES) -> bytes:
    """``events`` as the kernel writes them, in records of ``record_bytes`` (for tests,
    fixtures and the in-process pad of :mod:`whexar.sensors.evdev_link`)."""
    layout = record_struct(record_bytes)
    return b"".join(layout.pack(e.sec, e.usec, e.type, e.code, e.value) for e in events)


def syn_report(sec: int = 0, usec: int = 0) -> InputEvent:
    """The ``EV_SYN``/``SYN_REPORT`` that closes a report."""
    return InputEvent(EV_SYN, SYN_REPORT, 0, sec, usec)


class EventDecoder:
    """Bytes read from an event device in, :class:`Report`\\ s and :class:`Dropped` out.

    ``record_bytes`` is the record size (:data:`NATIVE_RECORD_BYTES` by default;
    16 or 24). Bytes may arrive in any split: an unfinished record waits for
    the rest. Events after the last ``SYN_REPORT`` wait for theirs; after a
    ``SYN_DROPPED`` everything up to and including the next ``SYN_REPORT`` is
    discarded, and that ``SYN_REPORT`` yields one :class:`Dropped`.
    """

    def __init__(self, record_bytes: int = NATIVE_RECORD_BYTES) -> None:
        self._layout = record_struct(record_bytes)
        self.record_bytes = record_bytes
        self._tail = b""
        self._pending: list[InputEvent] = []
        self._dropping: int | None = None  # events discarded since SYN_DROPPED

    def clear(self) -> None:
        """Forget everything half-read (a device opened again starts afresh)."""
        self._tail = b""
        self._pending = []
        self._dropping = None

    def feed(self, data: bytes) -> list[Report | Dropped]:
        """Decode ``data``; the reports (and drops) it completes, in order."""
        buffer = self._tail + data
        whole = len(buffer) - len(buffer) % self.record_bytes
        self._tail = buffer[whole:]
        out: list[Report | Dropped] = []
        for sec, usec, kind, code, value in self._layout.iter_unpack(buffer[:whole]):
            event = InputEvent(kind, code, value, sec, usec)
            if kind == EV_SYN and code == SYN_DROPPED:
                self._dropping = (self._dropping or 0) + len(self._pending)
                self._pending = []
            elif kind == EV_SYN and code == SYN_REPORT:
                if self._dropping is not None:
                    out.append(Dropped(self._dropping))
                    self._dropping = None
                else:
                    out.append(Report(tuple(self._pending)))
                self._pending = []
            elif self._dropping is not None:
                self._dropping += 1
            else:
                self._pending.append(event)
        return out


# --------------------------------------------------------------------------- ioctls
# asm-generic/ioctl.h: _IOC(dir, type, nr, size) = dir << 30 | size << 16 | type << 8 | nr,
# _IOC_READ = 2. ARM (32- and 64-bit) and x86 use this generic layout; Alpha, MIPS,
# PowerPC and SPARC do not (their direction bits start at 29), and are not handled.

_IOC_READ: Final = 2


def _ioc_read(nr: int, size: int) -> int:
    return _IOC_READ << 30 | size << 16 | ord("E") << 8 | nr


ABSINFO: Final = struct.Struct("=6i")
"""``struct input_absinfo`` (input.h): value, minimum, maximum, fuzz, flat, resolution."""

KEY_BITMASK_BYTES: Final = KEY_MAX // 8 + 1
"""Bytes of the key bitmask EVIOCGKEY fills: one bit per code up to KEY_MAX."""


class AbsInfo(NamedTuple):
    """An axis as the device describes it (EVIOCGABS): its present value and its range."""

    value: int
    minimum: int
    maximum: int
    fuzz: int = 0
    flat: int = 0
    resolution: int = 0


def eviocgabs(axis: int) -> int:
    """EVIOCGABS(abs) = _IOR('E', 0x40 + abs, struct input_absinfo): one axis's value and range."""
    if not 0 <= axis <= ABS_MAX:
        raise ValueError(f"an ABS code is 0..{ABS_MAX}, not {axis}")
    return _ioc_read(0x40 + axis, ABSINFO.size)


def eviocgkey(length: int = KEY_BITMASK_BYTES) -> int:
    """EVIOCGKEY(len) = _IOC(_IOC_READ, 'E', 0x18, len): the bitmask of keys held now."""
    return _ioc_read(0x18, length)


def eviocgname(length: int = 256) -> int:
    """EVIOCGNAME(len) = _IOC(_IOC_READ, 'E', 0x06, len): the device's name."""
    return _ioc_read(0x06, length)


def eviocgbit(ev_type: int, length: int) -> int:
    """EVIOCGBIT(ev, len) = _IOC(_IOC_READ, 'E', 0x20 + ev, len): the codes of event type
    ``ev`` the device can send (its capabilities: which buttons and axes it has)."""
    return _ioc_read(0x20 + ev_type, length)


def keys_held(bitmask: bytes) -> frozenset[int]:
    """The codes set in an EVIOCGKEY bitmask (bit ``code % 8`` of byte ``code // 8``)."""
    return frozenset(
        index * 8 + bit for index, byte in enumerate(bitmask) for bit in range(8) if byte >> bit & 1
    )
