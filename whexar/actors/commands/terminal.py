"""The terminal and stdin, for the command sources that read a person or a pipe.

:class:`LineReader` reads lines from a descriptor through the event loop;
:class:`Terminal` puts a terminal in cbreak mode, draws the status line on
stderr and always gives the terminal its settings back.
"""

from __future__ import annotations

import contextlib
import os
import stat
import sys
import termios
import tty
from typing import Any, Final

import anyio
import anyio.lowlevel

from whexar.actors.commands.keyboard import CLEAR_LINE, KeyboardState, status_line
from whexar.actors.messages import LocomotionState

MAX_LINE_BYTES: Final = 65_536
"""Longest line read from stdin; a longer one is refused (input without newlines
must not grow the buffer without bound)."""


class LineReader:
    """Reads lines from a file descriptor through the event loop, without a thread.

    A pipe, a socket or a terminal is waited on as the loop's watched
    descriptor; a regular file (``< script.jsonl``) or a device such as
    ``/dev/null`` cannot be watched (epoll refuses them) and never blocks, so
    it is read directly, with a checkpoint between reads so others still run.
    """

    def __init__(self, fd: int, *, limit: int = MAX_LINE_BYTES) -> None:
        self.fd = fd
        self.limit = limit
        mode = os.fstat(fd).st_mode
        self._watched = stat.S_ISFIFO(mode) or stat.S_ISSOCK(mode) or os.isatty(fd)
        self._buffer = bytearray()
        self._eof = False
        self._skipping = False  # inside a line that was too long: drop it up to its end

    async def readline(self) -> bytes | None:
        """The next line without its newline, or ``None`` at end of input.

        A line longer than ``limit`` bytes comes back as its first
        ``limit + 1`` bytes (tell it by its length); the rest of it is dropped.
        """
        while True:
            end = self._buffer.find(b"\n")
            if end >= 0:
                line = bytes(self._buffer[: min(end, self.limit + 1)])
                del self._buffer[: end + 1]
                if self._skipping:
                    self._skipping = False
                    continue
                return line
            if len(self._buffer) > self.limit:
                head = bytes(self._buffer[: self.limit + 1])
                self._buffer.clear()
                if not self._skipping:
                    self._skipping = True
                    return head
            if self._eof:
                line = bytes(self._buffer)
                self._buffer.clear()
                return line if line and not self._skipping else None
            chunk = await self._read()
            if chunk is None:
                continue
            if chunk:
                self._buffer += chunk
            else:
                self._eof = True

    async def _read(self) -> bytes | None:
        """Bytes read, ``b""`` at end of input, ``None`` when nothing was there after all."""
        if self._watched:
            await anyio.wait_readable(self.fd)
        else:
            await anyio.lowlevel.checkpoint()
        try:
            return os.read(self.fd, 65_536)
        except BlockingIOError:  # someone made the descriptor non-blocking: wait again
            return None
        except OSError:  # EIO: the terminal hung up; as good as the end of input
            return b""


def stdin_fd() -> int | None:
    """The descriptor of stdin, or ``None`` when there is none (closed, or replaced by a test)."""
    stream = sys.stdin
    if stream is None:
        return None
    try:
        return stream.fileno()
    except (AttributeError, OSError, ValueError):
        return None


class Terminal:
    """A terminal in cbreak mode: keys arrive one by one, unechoed, while Ctrl-C is still
    SIGINT (raw mode would take that from the runtime). :meth:`restore` gives the
    terminal its settings back; it is synchronous, so no cancellation can cut it short."""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self._saved: list[Any] | None = termios.tcgetattr(fd)
        tty.setcbreak(fd)

    def draw(self, keys: KeyboardState, state: LocomotionState | None) -> None:
        """Redraw the status line in place, cut to the terminal's width."""
        try:
            width: int | None = os.get_terminal_size(sys.stderr.fileno()).columns
        except (AttributeError, OSError, ValueError):
            width = None
        # A terminal that does not know its size says 0 columns: then do not cut.
        write(CLEAR_LINE + status_line(keys, state, width=width or None))

    def restore(self) -> None:
        """The terminal's settings as they were; then the status line erased."""
        saved, self._saved = self._saved, None
        if saved is None:
            return
        with contextlib.suppress(termios.error, OSError):
            termios.tcsetattr(self.fd, termios.TCSADRAIN, saved)
        write(CLEAR_LINE)


def write(text: str) -> None:
    """``text`` on stderr; a closed stderr is no reason to stop the robot."""
    with contextlib.suppress(OSError, ValueError):
        sys.stderr.write(text)
        sys.stderr.flush()
