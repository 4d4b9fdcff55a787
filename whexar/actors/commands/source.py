"""The command source actor: motion commands from a script, stdin or the keyboard.

The front ends are told in :mod:`whexar.actors.commands`; the script
parser is :mod:`.script`, the keyboard's keys and status line
:mod:`.keyboard`, the terminal and stdin :mod:`.terminal`. This actor only
chooses the front end, waits on it and sends what it makes.
"""

from __future__ import annotations

import codecs
import math
import os
from typing import Final

import anyio

from whexar.actors.commands.keyboard import (
    HELP,
    STATUS_PERIOD_S,
    KeyboardState,
    key_command,
    split_keys,
)
from whexar.actors.commands.script import SourceName, load_script, parse_command, shown
from whexar.actors.commands.terminal import LineReader, Terminal, stdin_fd, write
from whexar.actors.messages import CommandRefused, LocomotionState, MotionCommand
from whexar.errors import ConfigError, UsageError
from whexar.runtime.actor import Actor, ActorParams, Input, Output
from whexar.runtime.schema import Positive

STDIN_ON_VIRTUAL_TIME: Final = "stdin is not read on virtual time; give --commands FILE"
"""The reason of the one ``CommandRefused`` a stdin source gives on virtual time."""


class CommandSource(Actor):
    """Sends motion commands from a script, stdin or the keyboard (see the module docstring)."""

    class Params(ActorParams):
        source: SourceName = "stdin"
        """``stdin``, ``keyboard``, ``none``, or the path of a command script (JSON lines)."""
        step_height_m: Positive = 0.06
        """The step height the keyboard's ``+`` and ``-`` start from (the default
        configuration's ``locomotion.step_height_mm``)."""

    params: Params
    commands = Output(MotionCommand)
    state = Input(LocomotionState, optional=True)
    """The coordinator's state, for the keyboard's status line."""

    _terminal: Terminal | None = None
    """The keyboard's terminal in cbreak mode, while its settings need restoring."""

    async def run(self) -> None:
        source = self.params.source
        if source == "none":
            self.ready()
            await anyio.sleep_forever()
        elif source == "stdin":
            await self._stdin()
        elif source == "keyboard":
            await self._keyboard()
        else:
            await self._script(source)

    async def safe_stop(self, reason: str) -> None:
        """Give the terminal its settings back: a second Ctrl-C ends the process without cleanup."""
        self._restore_terminal()

    # ----------------------------------------------------------------- script

    async def _script(self, path: str) -> None:
        # Checked again here: the file may have changed since the wiring was.
        script = load_script(path, source=self.name)
        self.ready()
        for command in script:
            await self.clock.sleep_until(command.t)
            await self.commands.send(command)
        await anyio.sleep_forever()

    # ----------------------------------------------------------------- stdin

    def _refuse(self, command: str, reason: str) -> None:
        self.emit(CommandRefused(t=self.now(), source=self.name, command=command, reason=reason))

    async def _stdin(self) -> None:
        if self.clock.virtual and not self.clock.real_io:
            # Not an error: a graph with the default source still runs on virtual time.
            self.ready()
            self._refuse("stdin", STDIN_ON_VIRTUAL_TIME)
            await anyio.sleep_forever()
            return
        self.clock.uses_real_io("stdin")
        fd = stdin_fd()
        if fd is None:
            self.ready()
            self._refuse("stdin", "this process has no stdin to read")
            await anyio.sleep_forever()
            return
        reader = LineReader(fd)
        self.ready()
        number = 0
        while (raw := await reader.readline()) is not None:
            number += 1
            where = f"stdin line {number}"
            text = raw.decode("utf-8", errors="replace").strip()
            if len(raw) > reader.limit:
                self._refuse(shown(text), f"{where}: a line of at most {reader.limit} bytes")
                continue
            if not text or text.startswith("#"):
                continue
            try:
                command = parse_command(text, t=self.now(), source=self.name, where=where)
            except ConfigError as exc:
                self._refuse(shown(text), "; ".join(str(p) for p in exc.problems))
                continue
            await self.commands.send(command)
        await anyio.sleep_forever()

    # ----------------------------------------------------------------- keyboard

    async def _keyboard(self) -> None:
        self.clock.uses_real_io("keyboard (the terminal on stdin)")
        fd = stdin_fd()
        if fd is None or not os.isatty(fd):
            raise UsageError(
                "source = 'keyboard' needs a terminal on stdin; give a command script "
                "or 'stdin' to read commands from a pipe"
            )
        self._keys = KeyboardState(step_height_m=self.params.step_height_m)
        self._state: LocomotionState | None = None
        self._drawn_at = -math.inf
        try:
            self._terminal = Terminal(fd)
            write(HELP + "\n")
            self._draw()
            self.ready()
            async with anyio.create_task_group() as tg:
                if self.state.connected:
                    tg.start_soon(self._follow_state)
                await self._read_keys(fd)
                await anyio.sleep_forever()
        finally:
            self._restore_terminal()  # synchronous: no cancellation can cut it short

    async def _read_keys(self, fd: int) -> None:
        decoder = codecs.getincrementaldecoder("utf-8")(errors="replace")
        tail = ""
        while True:
            await anyio.wait_readable(fd)
            try:
                data = os.read(fd, 1024)
            except BlockingIOError:
                continue
            except OSError:  # EIO: the terminal hung up
                data = b""
            if not data:
                # Nobody can steer any more: do not leave the robot moving.
                self._keys, stop = key_command(" ", self._keys, t=self.now(), source=self.name)
                if stop is not None:
                    await self.commands.send(stop)
                return
            keys, tail = split_keys(tail + decoder.decode(data))
            for key in keys:
                self._keys, command = key_command(key, self._keys, t=self.now(), source=self.name)
                if command is not None:
                    await self.commands.send(command)
                if self._keys.quit:
                    self.request_stop("x pressed on the keyboard")
            self._draw()

    async def _follow_state(self) -> None:
        async for state in self.state:
            self._state = state
            # A state arrives every control cycle; the line is redrawn at a pace a
            # person can read, and a key redraws it at once anyway.
            if self.now() - self._drawn_at >= STATUS_PERIOD_S:
                self._draw()

    def _draw(self) -> None:
        if self._terminal is not None:
            self._terminal.draw(self._keys, self._state)
        self._drawn_at = self.now()

    def _restore_terminal(self) -> None:
        terminal, self._terminal = self._terminal, None
        if terminal is not None:
            terminal.restore()
