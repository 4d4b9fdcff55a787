"""An evdev input device as a link: open, read without blocking, ask its state; and a pad in
this process over a pipe.

:class:`EventDevice` owns one descriptor: ``/dev/input/eventN`` opened
read-only and non-blocking (the event loop waits on it; the reader never
blocks), or the read end of an :class:`EventPipe`. Its ioctls (EVIOCGNAME,
EVIOCGABS, EVIOCGKEY; numbers from :mod:`whexar.sensors.evdev`) answer
``None`` where the descriptor is no event device (a pipe answers ENOTTY), so
the caller falls back to its configuration. Errors are translated at this
edge: a node that cannot be opened or has vanished (ENODEV, what a read of an
unplugged device returns) is :class:`~whexar.errors.DeviceGoneError`, whose
text says why — with the fix for a permission refused (the ``input`` group).

:class:`EventPipe` is a gamepad in this process: events written into an
``os.pipe()``, the read end handed to whoever opens it, ``unplug()`` closing
the write end (the reader sees end of file, as it sees ENODEV from a real
pad). Register it in :data:`~whexar.runtime.devices.DEVICES` under
:data:`EVENT_PIPE` and name it ``pipe:NAME`` where a device path goes.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
from typing import Final

from whexar.errors import DeviceGoneError
from whexar.runtime.devices import DeviceKind
from whexar.sensors.evdev import (
    ABS_MAX,
    ABSINFO,
    EV_ABS,
    EV_KEY,
    KEY_BITMASK_BYTES,
    KEY_MAX,
    NATIVE_RECORD_BYTES,
    AbsInfo,
    InputEvent,
    encode,
    eviocgabs,
    eviocgbit,
    eviocgkey,
    eviocgname,
    keys_held,
    syn_report,
)

PERMISSION_HINT: Final = (
    "the user needs read access to the event device: add it to the 'input' group "
    "(README, 'Driving with a gamepad')"
)


def _reason(action: str, where: str, exc: OSError) -> str:
    text = f"{action} {where}: {exc.strerror or exc}"
    if exc.errno in (errno.EACCES, errno.EPERM):
        text += f"; {PERMISSION_HINT}"
    return text


class EventDevice:
    """One open event device (or any descriptor carrying its records), read without blocking.

    ``fd`` becomes this object's: :meth:`close` closes it. ``link`` names it in errors.
    """

    def __init__(self, fd: int, link: str) -> None:
        os.set_blocking(fd, False)
        self.fd = fd
        self.link = link

    @classmethod
    def open(cls, path: str) -> EventDevice:
        """Open ``path`` (``/dev/input/eventN``) read-only; DeviceGoneError says why not."""
        try:
            fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
        except OSError as exc:
            raise DeviceGoneError(_reason("cannot open", path, exc)) from exc
        return cls(fd, path)

    @classmethod
    def from_pipe(cls, pipe: EventPipe, link: str) -> EventDevice:
        """Open an in-process pad (its ``link`` is ``pipe:NAME``); DeviceGoneError while it is
        unplugged."""
        try:
            return cls(pipe.open(), link)
        except OSError as exc:
            raise DeviceGoneError(_reason("cannot open", link, exc)) from exc

    def read(self, size: int) -> bytes | None:
        """Up to ``size`` bytes; ``b""`` at end of file; ``None`` when nothing is there yet.

        A device that went away (ENODEV, EIO) is :class:`DeviceGoneError`.
        """
        try:
            return os.read(self.fd, size)
        except (BlockingIOError, InterruptedError):
            return None
        except OSError as exc:
            raise DeviceGoneError(_reason("cannot read", self.link, exc)) from exc

    def _ioctl(self, request: int, size: int) -> bytes | None:
        buffer = bytearray(size)
        try:
            fcntl.ioctl(self.fd, request, buffer)
        except OSError:  # ENOTTY: not an event device (a pipe); ENODEV: gone (a read says so)
            return None
        return bytes(buffer)

    def name(self) -> str | None:
        """The device's name (EVIOCGNAME, "Microsoft X-Box 360 pad"), ``None`` if it has none."""
        raw = self._ioctl(eviocgname(256), 256)
        if raw is None:
            return None
        return raw.split(b"\0", 1)[0].decode("utf-8", errors="replace")

    def abs_info(self, axis: int) -> AbsInfo | None:
        """Axis ``axis``'s present value and range (EVIOCGABS), ``None`` if it cannot tell."""
        raw = self._ioctl(eviocgabs(axis), ABSINFO.size)
        if raw is None:
            return None
        return AbsInfo(*ABSINFO.unpack(raw))

    def keys(self) -> frozenset[int] | None:
        """The key codes held now (EVIOCGKEY), ``None`` if it cannot tell."""
        raw = self._ioctl(eviocgkey(KEY_BITMASK_BYTES), KEY_BITMASK_BYTES)
        return None if raw is None else keys_held(raw)

    def capabilities(self) -> tuple[frozenset[int], frozenset[int]] | None:
        """The button (EV_KEY) and axis (EV_ABS) codes the device has (EVIOCGBIT), ``None``
        if it cannot tell (a pipe)."""
        key_bytes, abs_bytes = KEY_MAX // 8 + 1, ABS_MAX // 8 + 1
        keys = self._ioctl(eviocgbit(EV_KEY, key_bytes), key_bytes)
        axes = self._ioctl(eviocgbit(EV_ABS, abs_bytes), abs_bytes)
        if keys is None or axes is None:
            return None
        return keys_held(keys), keys_held(axes)  # the same bitmask layout as EVIOCGKEY

    def close(self) -> None:
        """Close the descriptor (once; later calls do nothing)."""
        fd, self.fd = self.fd, -1
        if fd >= 0:
            with contextlib.suppress(OSError):
                os.close(fd)


class EventPipe:
    """A gamepad in this process: records written into a pipe that an :class:`EventDevice`
    reads (tests, demos). Plugged in when made.

    :meth:`open` hands out a new descriptor of the read end (an OSError, as for a
    node that is not there, while unplugged); :meth:`send` writes events as the
    kernel would, each call one report; :meth:`unplug` closes the write end, so
    the reader sees end of file; :meth:`plug` makes a new pipe.
    """

    def __init__(self, record_bytes: int = NATIVE_RECORD_BYTES) -> None:
        self.record_bytes = record_bytes
        self._read: int | None = None
        self._write: int | None = None
        self.plug()

    @property
    def plugged(self) -> bool:
        return self._write is not None

    def plug(self) -> None:
        """Plug a fresh pad in (a new pipe); one plugged in stays as it is."""
        if self._write is None:
            self._read, self._write = os.pipe()

    def open(self) -> int:
        """A new descriptor of the pipe's read end; the caller owns it."""
        if self._read is None:
            raise OSError(errno.ENOENT, os.strerror(errno.ENOENT))
        return os.dup(self._read)

    def write(self, data: bytes) -> None:
        """Raw bytes into the pipe (a record cut in two, a recording)."""
        if self._write is None:
            raise DeviceGoneError("the pipe's pad is unplugged")
        os.write(self._write, data)

    def send(self, *events: InputEvent | tuple[int, int, int], report: bool = True) -> None:
        """``events`` (``(type, code, value)`` or :class:`InputEvent`), then a SYN_REPORT."""
        found = [e if isinstance(e, InputEvent) else InputEvent(*e) for e in events]
        self.write(encode([*found, *([syn_report()] if report else [])], self.record_bytes))

    def unplug(self) -> None:
        """Pull the pad out: the reader reads what is left, then end of file."""
        for fd in (self._write, self._read):
            if fd is not None:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._read = self._write = None

    close = unplug


EVENT_PIPE: Final = DeviceKind[EventPipe]("gamepad pipe", "pipe")
"""In-process pads in :data:`~whexar.runtime.devices.DEVICES`: ``pipe:NAME`` as the device."""
