"""The emulated sensor board behind a pseudo-terminal, in real time.

Theory of operation
-------------------
:class:`BoardPty` serves a :class:`~whexar.sensors.board_emulator.SensorBoardEmulator`
on the master side of a pty, so that any program that opens :attr:`BoardPty.path` as a
serial port — pyserial, the runtime's sensor reader, ``whexar sensors``, ``whexar
doctor`` — reads the frames of ``firmware/PROTOCOL.md`` over a real file descriptor,
as from the board's USB serial line. ``whexar emulate --board`` runs one beside the
servo emulator, in the emulator's process: a controller measured against it pays for
its own serial reading, not for the board's arithmetic.

One thread runs an event loop on real time: it asks the board's link for its next frame
(which arrives when its last byte would have crossed the wire at the board's baud rate)
and writes it to the master; what the host writes (``rate=N#``) goes to the board. A
pty does not pulse DTR when a program opens it, so the board does not reset then: like
a board that did not reset on opening, a client first reads what was on its way (the
reader drops a partial first frame; ``firmware/PROTOCOL.md``, "How the reader
resynchronises"). With no client reading, the pty's input queue fills and further
frames are lost, as a USB CDC device's are when no host polls it.
"""

from __future__ import annotations

import errno
import os
import threading
from dataclasses import dataclass
from types import TracebackType

import anyio

from whexar.runtime.clock import Clock
from whexar.runtime.clock import run as run_loop
from whexar.runtime.pty import ServedPty
from whexar.sensors.board_emulator import EmulatedBoardLink, SensorBoardEmulator

__all__ = ["BoardPty", "BoardPtyStats"]


@dataclass(slots=True)
class BoardPtyStats:
    """What the pty carried: frames written whole, frames lost to a full queue, bytes in."""

    frames: int = 0
    lost: int = 0
    received_bytes: int = 0


class BoardPty:
    """Serve ``board`` on a new pty until :meth:`close` (or the ``with`` block's end)."""

    def __init__(self, board: SensorBoardEmulator) -> None:
        self.board = board
        self.stats = BoardPtyStats()
        self._pty = ServedPty.open()  # raw, the slave held open, a wake-up pipe
        self.path: str = self._pty.path
        self._thread = threading.Thread(target=self._run, name="board-pty", daemon=True)
        self.error: BaseException | None = None
        """What stopped the serving thread early, if anything did."""
        self._thread.start()

    def __enter__(self) -> BoardPty:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def close(self) -> None:
        """Stop serving and close the pty."""
        if self._thread.is_alive():
            self._pty.wake()
            self._thread.join(timeout=5)
        self._pty.close()

    # ------------------------------------------------------------------ thread

    def _run(self) -> None:
        try:
            run_loop(self._serve)
        except BaseException as exc:  # kept for the owner: the thread ends
            self.error = exc

    async def _serve(self) -> None:
        link = self.board.open(Clock())
        async with anyio.create_task_group() as tg:
            tg.start_soon(self._send_frames, link)
            tg.start_soon(self._take_commands, link)
            await anyio.wait_readable(self._pty.wake_r)
            tg.cancel_scope.cancel()

    async def _send_frames(self, link: EmulatedBoardLink) -> None:
        while True:
            data = await link.receive()
            try:
                written = os.write(self._pty.master, data)
            except BlockingIOError:
                self.stats.lost += 1  # nobody reads: the queue is full
                continue
            if written == len(data):
                self.stats.frames += 1
            else:
                self.stats.lost += 1  # its head went out; the reader resynchronises

    async def _take_commands(self, link: EmulatedBoardLink) -> None:
        while True:
            await anyio.wait_readable(self._pty.master)
            try:
                data = os.read(self._pty.master, 4096)
            except BlockingIOError:
                continue
            except OSError as exc:
                if exc.errno == errno.EIO:  # cannot happen while we hold the slave
                    await anyio.sleep(0.01)
                    continue
                raise
            self.stats.received_bytes += len(data)
            await link.send(data)
