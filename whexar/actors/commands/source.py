"""The command source actor: motion commands from a script, stdin, the keyboard or a gamepad.

The front ends are told in :mod:`whexar.actors.commands`; the script
parser is :mod:`.script`, the keyboard's keys and status line
:mod:`.keyboard`, the terminal and stdin :mod:`.terminal`, the gamepad's
mapping :mod:`.gamepad` (its device :mod:`whexar.sensors.evdev_link`, its
records :mod:`whexar.sensors.evdev`). This actor only chooses the front end,
waits on it and sends what it makes.
"""

from __future__ import annotations

import codecs
import math
import os
from collections.abc import Callable
from typing import Final

import anyio

from whexar.actors.commands.gamepad import (
    AxisRange,
    GamepadMapping,
    GamepadPolicy,
    choose_mapping,
)
from whexar.actors.commands.keyboard import (
    HELP,
    STATUS_PERIOD_S,
    KeyboardState,
    key_command,
    split_keys,
)
from whexar.actors.commands.script import (
    GAMEPAD_PREFIX,
    SourceName,
    load_script,
    parse_command,
    shown,
)
from whexar.actors.commands.terminal import LineReader, Terminal, stdin_fd, write
from whexar.actors.messages import (
    CommandRefused,
    GamepadEventsDropped,
    GamepadLayoutUnknown,
    GamepadLinkDown,
    GamepadLinkHeard,
    GamepadLinkSilent,
    GamepadLinkUp,
    LocomotionState,
    MotionCommand,
)
from whexar.config import ConfigFile, GamepadSpec, RobotConfig, load_config
from whexar.errors import ConfigError, DeviceGoneError, UsageError
from whexar.runtime.actor import Actor, ActorParams, Input, Output
from whexar.runtime.devices import DEVICES
from whexar.runtime.schema import Positive
from whexar.sensors.evdev import Dropped, EventDecoder
from whexar.sensors.evdev_link import EVENT_PIPE, EventDevice

STDIN_ON_VIRTUAL_TIME: Final = "stdin is not read on virtual time; give --commands FILE"
"""The reason of the one ``CommandRefused`` a stdin source gives on virtual time."""

PAD_READ_RECORDS: Final = 64
"""Records read from the gamepad at most per read (a report is a few)."""


class CommandSource(Actor):
    """Sends motion commands from a script, stdin, the keyboard or a gamepad (see the module
    docstring)."""

    class Params(ActorParams):
        source: SourceName = "stdin"
        """``stdin``, ``keyboard``, ``gamepad`` (the device of ``[gamepad]``),
        ``gamepad:DEVICE`` (``/dev/input/eventN``, or ``pipe:NAME``: an in-process
        :class:`~whexar.sensors.evdev_link.EventPipe`), ``none``, or the path of a command
        script (JSON lines)."""
        config: ConfigFile | None = None
        """Robot configuration file, for its ``[gamepad]`` mapping; absent: the built-in
        defaults (``RobotConfig().gamepad``)."""
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
        elif source == "gamepad" or source.startswith(GAMEPAD_PREFIX):
            await self._gamepad(source.removeprefix("gamepad").removeprefix(":") or None)
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

    # ----------------------------------------------------------------- gamepad

    async def _gamepad(self, device: str | None) -> None:
        cfg = load_config(self.params.config) if self.params.config else RobotConfig()
        spec = cfg.gamepad
        link = device or spec.device
        opener = self._pad_opener(link)
        self.clock.uses_real_io(f"gamepad {link}")  # refused on virtual time, unless allowed
        configured = GamepadMapping.from_config(spec)
        fallback = GamepadMapping.from_config(GamepadSpec())  # for a pad of another layout
        policy = GamepadPolicy(configured, source=self.name)
        decoder = EventDecoder(policy.mapping.record_bytes)
        told: str | None = None  # the reason last said down: a cause is said once
        first = True
        while True:
            pad: EventDevice | None = None
            try:
                pad = opener()
            except DeviceGoneError as exc:
                if str(exc) != told:
                    told = str(exc)
                    self.emit(
                        GamepadLinkDown(t=self.now(), source=self.name, link=link, reason=told)
                    )
            if pad is not None:
                self._connect_pad(pad, policy, spec, (configured, fallback))
            if first:
                # Ready once the first open is tried and told: a pad not there is an event.
                self.ready()
                first = False
            if pad is not None:
                try:
                    told = await self._read_pad(pad, policy, decoder)
                finally:
                    pad.close()
                self.emit(GamepadLinkDown(t=self.now(), source=self.name, link=link, reason=told))
                for command in policy.lost(self.now()):
                    await self.commands.send(command)
            await self.clock.sleep(spec.reopen_period_s)

    def _pad_opener(self, link: str) -> Callable[[], EventDevice]:
        scheme, _, name = link.partition(":")
        if scheme == EVENT_PIPE.scheme and name:
            pipe = DEVICES.get(EVENT_PIPE, name, setting=f"source = {self.params.source!r}")
            return lambda: EventDevice.from_pipe(pipe, link)
        return lambda: EventDevice.open(link)

    def _connect_pad(
        self,
        pad: EventDevice,
        policy: GamepadPolicy,
        spec: GamepadSpec,
        mappings: tuple[GamepadMapping, GamepadMapping],
    ) -> None:
        """A pad was opened: of ``mappings`` (the configured one, the default) the one that
        fits its layout (EVIOCGBIT), and its axes as it describes them (EVIOCGABS), if it
        can tell."""
        mapping, missing, using = choose_mapping(*mappings, pad.capabilities())
        policy.mapping = mapping
        name = pad.name() or ""
        if using is not None:
            self.emit(
                GamepadLayoutUnknown(
                    t=self.now(),
                    source=self.name,
                    link=pad.link,
                    name=name,
                    missing=missing,
                    using=using,
                )
            )
        infos = {a: info for a in policy.mapping.axes if (info := pad.abs_info(a)) is not None}
        ranges = {
            axis: AxisRange(info.minimum, info.maximum)
            for axis, info in infos.items()
            if spec.axis_ranges == "device" and info.minimum < info.maximum
        }
        values = {axis: info.value for axis, info in infos.items()}
        policy.connected(self.now(), ranges=ranges, values=values)
        self.emit(GamepadLinkUp(t=self.now(), source=self.name, link=pad.link, name=name))

    async def _read_pad(
        self, pad: EventDevice, policy: GamepadPolicy, decoder: EventDecoder
    ) -> str:
        """Read the pad until it goes away; why it did."""
        axes = policy.mapping.axes
        decoder.clear()
        while True:
            deadline = policy.silence_deadline()
            readable = False
            with anyio.CancelScope(
                deadline=math.inf if deadline is None else self.clock.loop_time(deadline)
            ):
                await anyio.wait_readable(pad.fd)
                readable = True
            t = self.now()
            if not readable:  # the deadline passed: nothing came while it drove
                silent_s = t - (t if policy.last_heard is None else policy.last_heard)
                commands = policy.silence(t)
                self.emit(
                    GamepadLinkSilent(t=t, source=self.name, link=pad.link, silent_s=silent_s)
                )
                await self._send_all(commands)
                continue
            try:
                data = pad.read(decoder.record_bytes * PAD_READ_RECORDS)
            except DeviceGoneError as exc:
                return str(exc)
            if data is None:
                continue
            if not data:
                return f"{pad.link}: end of file (the pad went away)"
            for item in decoder.feed(data):
                t = self.now()
                if policy.silent and policy.last_heard is not None:
                    self.emit(
                        GamepadLinkHeard(
                            t=t, source=self.name, link=pad.link, silent_s=t - policy.last_heard
                        )
                    )
                if isinstance(item, Dropped):
                    keys = pad.keys()
                    values = {
                        axis: info.value
                        for axis in axes
                        if (info := pad.abs_info(axis)) is not None
                    }
                    commands = policy.dropped(t, keys=keys, values=values)
                    self.emit(
                        GamepadEventsDropped(
                            t=t,
                            source=self.name,
                            link=pad.link,
                            discarded=item.discarded,
                            resynced=keys is not None,
                        )
                    )
                else:
                    commands = policy.report(t, item.events)
                await self._send_all(commands)

    async def _send_all(self, commands: list[MotionCommand]) -> None:
        for command in commands:
            await self.commands.send(command)
