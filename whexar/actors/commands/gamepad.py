"""The gamepad as a command source: what the pad reports in, motion commands out.

Theory of operation
-------------------
:class:`GamepadPolicy` keeps what the pad holds — keys down, axis positions —
from the :class:`~whexar.sensors.evdev.Report`\\ s of the event device, and
turns it into :class:`~whexar.actors.messages.MotionCommand`\\ s by the
:class:`GamepadMapping` (the ``[gamepad]`` section). A plain class: its
methods take the time and what happened and return the commands to send; the
actor (:mod:`.source`) reads the device and sends them.

* **Sticks → velocity.** Each stick axis is normalised by its range (the
  device's, EVIOCGABS, or the configuration's) to −1…1 about the centre; a
  dead zone about the centre reads as 0 and the rest is stretched back to
  0…1, so the speed rises from zero at the dead zone's edge; the result is
  held in steps of ``resolution`` with a quarter step of hysteresis (0 and
  full travel exactly), then scaled to ``max_forward_m_s``,
  ``max_sideways_m_s`` and the turn rate. A command goes out only when that
  velocity changes — a stick's jitter sends nothing — and always carries all
  three components (the pad owns the whole velocity, as the keyboard does).
* **The dead-man.** Only while it is held does the pad drive: letting it go
  sends one stop (velocity zero, ``stop``), and while it is up the sticks and
  every button but ``stop`` do nothing. A dead-man held while the pad was
  plugged in (or opened) does not count until it is let go and pressed again.
* **Buttons → actions**, on the press (not the release, not the kernel's
  auto-repeat): gait, mode, stance, flip (``upside_down`` toggled, as the
  keyboard does it) and stop. An axis direction (a d-pad's hat, a trigger)
  presses past half its travel and lets go below a quarter. A stop while the
  sticks are off centre holds until they come back to the centre (or the
  dead-man is let go): pressing stop means stop, not stop until the next
  jitter.
* **The link.** :meth:`~GamepadPolicy.lost` (unplugged): the state is
  forgotten and a stop is sent unless the robot is stopped already.
  :meth:`~GamepadPolicy.dropped` (``SYN_DROPPED``): with the device's present
  keys and axes the state is taken from them; without (a pipe, an ioctl
  refused) it is forgotten as on a loss — the dead-man reads as let go and
  must be pressed again. **Silence**: while the dead-man is held and the pad
  asks for motion, :meth:`~GamepadPolicy.silence_deadline` is
  ``silent_after_s`` after the last report; past it :meth:`~GamepadPolicy.silence`
  stops the robot. The next report counts as the pad's word again: if it still
  asks for motion, the velocity goes out. Silence while standing still is no
  danger, and a pad with its sticks centred is silent by nature (the kernel
  reports changes only), so it is not watched then.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from typing import Final

from whexar.actors.messages import MotionCommand
from whexar.config import GamepadSpec, StickSpec
from whexar.sensors.evdev import (
    ABS_CODES,
    EV_ABS,
    EV_KEY,
    KEY_CODES,
    NATIVE_RECORD_BYTES,
    InputEvent,
)

PRESS: Final = 0.5
"""An axis direction counts as pressed past this fraction of its half-travel…"""
RELEASE: Final = 0.25
"""…and as let go below this one."""
HYSTERESIS_STEPS: Final = 0.75
"""A stick's level moves only once its reading is this many steps away from it."""

Velocity = tuple[float, float, float]
ZERO: Final[Velocity] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class AxisRange:
    """An axis's raw range; :meth:`normalised` maps it onto −1…1 about its centre."""

    minimum: int
    maximum: int

    def normalised(self, value: int) -> float:
        centre = (self.minimum + self.maximum) / 2
        half = (self.maximum - self.minimum) / 2
        return max(-1.0, min(1.0, (value - centre) / half))


@dataclass(frozen=True)
class Control:
    """A button (``direction`` 0, ``code`` an EV_KEY code) or one direction of an axis
    (``direction`` ±1, ``code`` an EV_ABS code)."""

    name: str
    code: int
    direction: int = 0

    @classmethod
    def parse(cls, name: str) -> Control:
        """``BTN_TL``, ``ABS_HAT0Y-``… (names checked by the configuration)."""
        if name in KEY_CODES:
            return cls(name, KEY_CODES[name])
        return cls(name, ABS_CODES[name[:-1]], 1 if name[-1] == "+" else -1)

    @property
    def is_axis(self) -> bool:
        return self.direction != 0


@dataclass(frozen=True)
class Action:
    """What a control does: ``kind`` stop, flip, gait, mode or stance; ``value`` for the last
    three."""

    kind: str
    value: str | None = None

    @classmethod
    def parse(cls, text: str) -> Action | None:
        """``stop``, ``gait:ripple``…; ``none`` is ``None`` (checked by the configuration)."""
        if text == "none":
            return None
        kind, _, value = text.partition(":")
        return cls(kind, value or None)


@dataclass(frozen=True)
class Stick:
    """One velocity component: its axis, its sign and its value at full travel."""

    axis: int
    sign: float
    full: float

    @classmethod
    def of(cls, spec: StickSpec, full: float) -> Stick:
        return cls(ABS_CODES[spec.axis], -1.0 if spec.invert else 1.0, full)


@dataclass(frozen=True)
class GamepadMapping:
    """The ``[gamepad]`` section as the policy uses it: codes, not names; SI units."""

    dead_man: Control
    forward: Stick
    sideways: Stick
    turn: Stick
    buttons: tuple[tuple[Control, Action | None], ...]
    ranges: Mapping[int, AxisRange]
    dead_zone: float = 0.2
    resolution: float = 0.05
    silent_after_s: float = 2.0
    record_bytes: int = NATIVE_RECORD_BYTES

    @classmethod
    def from_config(cls, spec: GamepadSpec) -> GamepadMapping:
        return cls(
            dead_man=Control.parse(spec.dead_man),
            forward=Stick.of(spec.forward, spec.max_forward_m_s),
            sideways=Stick.of(spec.sideways, spec.max_sideways_m_s),
            turn=Stick.of(spec.turn, spec.max_yaw_rate_rad_s),
            buttons=tuple((Control.parse(c), Action.parse(a)) for c, a in spec.buttons.items()),
            ranges={ABS_CODES[name]: AxisRange(*pair) for name, pair in spec.ranges.items()},
            dead_zone=spec.dead_zone,
            resolution=spec.resolution,
            silent_after_s=spec.silent_after_s,
            record_bytes=(
                NATIVE_RECORD_BYTES if spec.record_bytes == "native" else spec.record_bytes
            ),
        )

    def with_controls_of(self, other: GamepadMapping) -> GamepadMapping:
        """``other``'s controls — the dead-man, each stick's axis and sense, the buttons —
        with this mapping's tunables: full-travel speeds, dead zone, resolution, silence,
        record size, and its axis ranges where it gives one (they describe the pad)."""
        return replace(
            self,
            dead_man=other.dead_man,
            forward=replace(other.forward, full=self.forward.full),
            sideways=replace(other.sideways, full=self.sideways.full),
            turn=replace(other.turn, full=self.turn.full),
            buttons=other.buttons,
            ranges={**other.ranges, **self.ranges},
        )

    @property
    def sticks(self) -> tuple[Stick, Stick, Stick]:
        return (self.forward, self.sideways, self.turn)

    @property
    def axes(self) -> frozenset[int]:
        """Every axis the mapping reads: the sticks' and the axis directions'."""
        controls = [self.dead_man, *(c for c, _ in self.buttons)]
        return frozenset([*(s.axis for s in self.sticks), *(c.code for c in controls if c.is_axis)])

    def with_ranges(self, ranges: Mapping[int, AxisRange]) -> GamepadMapping:
        """This mapping with the ranges a device reported in place of the configured ones."""
        return dataclasses.replace(self, ranges={**self.ranges, **ranges})


def missing_controls(
    mapping: GamepadMapping, keys: frozenset[int], axes: frozenset[int]
) -> tuple[str, ...]:
    """What a pad with buttons ``keys`` and axes ``axes`` (EVIOCGBIT) lacks of ``mapping``
    to drive: its dead-man and its sticks' axes (a missing action button only loses that
    action)."""
    dead_man = mapping.dead_man
    lost = [] if (dead_man.code in (axes if dead_man.is_axis else keys)) else [dead_man.name]
    names = {code: name for name, code in ABS_CODES.items()}
    for stick in mapping.sticks:
        if stick.axis not in axes:
            lost.append(names.get(stick.axis, str(stick.axis)))
    return tuple(dict.fromkeys(lost))


def choose_mapping(
    configured: GamepadMapping,
    default: GamepadMapping,
    capabilities: tuple[frozenset[int], frozenset[int]] | None,
) -> tuple[GamepadMapping, tuple[str, ...], str | None]:
    """The mapping to drive a pad with ``capabilities`` (``None``: it cannot tell, so the
    configured one): (mapping, what the configured one lacks, ``"default"`` or
    ``"configured"`` when it lacks something, else ``None``). ``"default"`` takes the
    default's controls and keeps the configured speeds and tunables
    (:meth:`GamepadMapping.with_controls_of`)."""
    if capabilities is None:
        return configured, (), None
    keys, axes = capabilities
    lost = missing_controls(configured, keys, axes)
    if not lost:
        return configured, (), None
    if not missing_controls(default, keys, axes):
        return configured.with_controls_of(default), lost, "default"
    return configured, lost, "configured"


class GamepadPolicy:
    """The pad's state and the commands it asks for (see the module docstring).

    ``source`` stamps every command. :attr:`last_heard` is the time of the
    last report (``None`` while no pad is connected); :attr:`silent` says
    :meth:`silence` stopped the robot and no report came since.
    """

    def __init__(self, mapping: GamepadMapping, *, source: str = "gamepad") -> None:
        self.mapping = mapping
        self.source = source
        self.last_heard: float | None = None
        self.silent = False
        self.upside_down = False
        """What the flip button last asked for (the keyboard's rule: the pad's own belief)."""
        self.keys: set[int] = set()
        """The key codes held."""
        self.values: dict[int, int] = {}
        """The last raw value of each axis reported."""
        self.sent: Velocity = ZERO
        """The velocity last sent (zero after a stop)."""
        self.stopped = True
        """The last velocity command was a stop, or none was sent yet."""
        self._held_axes: set[Control] = set()
        self._levels = [0.0, 0.0, 0.0]
        self._armed = False
        self._latched = False  # a stop pressed with the sticks off centre holds
        self._dead_man_stale = False  # held when the pad was opened: let go first
        self._actions: dict[tuple[int, int], Action | None] = {
            (c.code, c.direction): a for c, a in mapping.buttons
        }
        self._axis_controls = [
            c for c in (mapping.dead_man, *(c for c, _ in mapping.buttons)) if c.is_axis
        ]

    # ----------------------------------------------------------------- the link

    def connected(
        self,
        t: float,
        *,
        ranges: Mapping[int, AxisRange] | None = None,
        values: Mapping[int, int] | None = None,
    ) -> None:
        """A pad was opened: forget the old one; ``ranges`` and ``values`` are what the device
        says of its axes (EVIOCGABS), where it can tell."""
        self._forget()
        if ranges:
            self.mapping = self.mapping.with_ranges(ranges)
        if values:
            self.values.update(values)
        self._axis_presses()
        self._dead_man_stale = self._holds(self.mapping.dead_man)
        self.last_heard = t
        self.silent = False

    def lost(self, t: float) -> list[MotionCommand]:
        """The pad went away: its state is forgotten; a stop unless stopped already."""
        self._forget()
        self.last_heard = None
        self.silent = False
        return [] if self.stopped else [self._stop(t)]

    def dropped(
        self,
        t: float,
        *,
        keys: Iterable[int] | None = None,
        values: Mapping[int, int] | None = None,
    ) -> list[MotionCommand]:
        """The kernel dropped events. With ``keys`` (EVIOCGKEY) and ``values`` (EVIOCGABS) the
        state is the device's; without, it is forgotten (the dead-man reads as let go)."""
        self._heard(t)
        if keys is None:
            self._forget()
            return [] if self.stopped else [self._stop(t)]
        self.keys = set(keys)
        self.values.update(values or {})
        self._axis_presses()  # a press lost in the drop does not act
        return self._commands(t, [])

    def silence_deadline(self) -> float | None:
        """When the pad's silence stops the robot: ``silent_after_s`` after the last report,
        while the dead-man is held and motion asked for; ``None`` otherwise."""
        if self.silent or self.last_heard is None or not self._armed:
            return None
        if self.stopped or self.sent == ZERO:
            return None
        return self.last_heard + self.mapping.silent_after_s

    def silence(self, t: float) -> list[MotionCommand]:
        """The pad said nothing past :meth:`silence_deadline`: stop."""
        self.silent = True
        return [] if self.stopped else [self._stop(t)]

    # ----------------------------------------------------------------- reports

    def report(self, t: float, events: Iterable[InputEvent]) -> list[MotionCommand]:
        """Apply one report (the events of one SYN_REPORT); the commands it asks for."""
        self._heard(t)
        pressed: list[Control] = []
        for event in events:
            if event.type == EV_KEY:
                if event.value == 1 and event.code not in self.keys:
                    self.keys.add(event.code)
                    pressed.append(Control("", event.code))
                elif event.value == 0:
                    self.keys.discard(event.code)
                # value 2 is the kernel's auto-repeat of a held key: nothing new
            elif event.type == EV_ABS:
                self.values[event.code] = event.value
        pressed += self._axis_presses()
        return self._commands(t, pressed)

    @property
    def armed(self) -> bool:
        """The dead-man is held (and was pressed since the pad was opened)."""
        return self._armed

    # ----------------------------------------------------------------- inside

    def _heard(self, t: float) -> None:
        self.last_heard = t
        self.silent = False

    def _forget(self) -> None:
        self.keys.clear()
        self.values.clear()
        self._held_axes.clear()
        self._levels = [0.0, 0.0, 0.0]
        self._armed = False
        self._latched = False
        self._dead_man_stale = False

    def _normalised(self, axis: int) -> float:
        raw = self.values.get(axis)
        if raw is None:
            return 0.0  # never reported: at rest
        span = self.mapping.ranges.get(axis)
        return 0.0 if span is None else span.normalised(raw)

    def _holds(self, control: Control) -> bool:
        if control.is_axis:
            return control in self._held_axes
        return control.code in self.keys

    def _axis_presses(self) -> list[Control]:
        """Update which axis directions are held; the ones newly pressed."""
        pressed = []
        for control in self._axis_controls:
            reading = self._normalised(control.code) * control.direction
            if control in self._held_axes:
                if reading < RELEASE:
                    self._held_axes.discard(control)
            elif reading >= PRESS:
                self._held_axes.add(control)
                pressed.append(control)
        return pressed

    def _deflection(self, stick: Stick) -> float:
        n = self._normalised(stick.axis)
        zone = self.mapping.dead_zone
        if abs(n) <= zone:
            return 0.0
        return math.copysign((abs(n) - zone) / (1.0 - zone), n)

    def _velocity(self) -> Velocity:
        step = self.mapping.resolution
        out = []
        for i, stick in enumerate(self.mapping.sticks):
            x = self._deflection(stick)
            level = self._levels[i]
            if x in (0.0, 1.0, -1.0):
                level = x
            elif abs(x - level) > HYSTERESIS_STEPS * step:
                level = max(-1.0, min(1.0, round(x / step) * step))
            self._levels[i] = level
            out.append(round(level * stick.sign * stick.full, 6) + 0.0)  # no -0.0
        return (out[0], out[1], out[2])

    def _stop(self, t: float) -> MotionCommand:
        self.sent = ZERO
        self.stopped = True
        return MotionCommand(
            t=t, source=self.source, vx_m_s=0.0, vy_m_s=0.0, yaw_rate_rad_s=0.0, stop=True
        )

    def _commands(self, t: float, pressed: list[Control]) -> list[MotionCommand]:
        held = self._holds(self.mapping.dead_man)
        if not held:
            self._dead_man_stale = False
        armed = held and not self._dead_man_stale
        if self._armed and not armed:
            self._latched = False
        self._armed = armed
        asked = self._velocity()
        if asked == ZERO:
            self._latched = False
        out: list[MotionCommand] = []
        if armed and not self._latched:
            if asked != self.sent:
                vx, vy, yaw = asked
                out.append(
                    MotionCommand(t=t, source=self.source, vx_m_s=vx, vy_m_s=vy, yaw_rate_rad_s=yaw)
                )
                self.sent = asked
                self.stopped = False
        elif not self.stopped:
            out.append(self._stop(t))
        for control in pressed:
            action = self._actions.get((control.code, control.direction))
            if action is None:
                continue
            if action.kind == "stop":
                out.append(self._stop(t))
                self._latched = armed and asked != ZERO
            elif armed:
                out.append(self._act(t, action))
        return out

    def _act(self, t: float, action: Action) -> MotionCommand:
        if action.kind == "flip":
            self.upside_down = not self.upside_down
            return MotionCommand(t=t, source=self.source, upside_down=self.upside_down)
        if action.kind == "gait":
            return MotionCommand(t=t, source=self.source, gait=action.value)
        if action.kind == "mode":
            return MotionCommand(t=t, source=self.source, mode=action.value)
        return MotionCommand(t=t, source=self.source, stance=action.value)
