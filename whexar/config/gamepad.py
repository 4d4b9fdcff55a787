"""The gamepad's mapping: which sticks drive, which buttons do what, and the dead-man.

A **control** is a button by its input-event-codes.h name (``BTN_TL``,
``BTN_SOUTH``; the aliases ``BTN_A``… too), or one direction of an axis: an
``ABS_*`` name and ``+`` or ``-`` (``ABS_HAT0Y-`` is the d-pad's up,
``ABS_RZ+`` the right trigger pulled past three quarters). An **action** is
``stop``, ``flip``, ``gait:<tripod|tetrapod|ripple|wave>``,
``mode:<walk|ride|hybrid>``, ``stance:<a [stances] preset>`` or ``none`` (a
default button unmapped: the merge rule can change a key, not delete it).

The defaults suit the common pads under their Linux drivers — Xbox-style pads
and 8BitDo pads in X-input mode (``xpad``), DualShock 4 and DualSense
(``hid-playstation``) — which report the same codes by position
(Documentation/input/gamepad.rst): left stick ``ABS_X``/``ABS_Y``, right
stick ``ABS_RX``/``ABS_RY``, d-pad ``ABS_HAT0X``/``ABS_HAT0Y``, shoulders
``BTN_TL``/``BTN_TR``. The README's table lists them with the pads' labels.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Annotated, Final, Literal

from pydantic import AfterValidator, Field

from whexar.errors import Problem
from whexar.kinematics.gait import AUTO_GAIT, GAIT_RANKING
from whexar.runtime.schema import Positive, Section, format_path
from whexar.sensors.evdev import ABS_CODES, KEY_CODES

GAITS: Final = (*GAIT_RANKING[1:], AUTO_GAIT)
"""The walking gaits a button may choose."""
MODES: Final = ("walk", "ride", "hybrid")
"""The locomotion modes a button may choose (the coordinator's; a test keeps them equal)."""


def _axis(name: str) -> str:
    if name not in ABS_CODES:
        raise ValueError(f"an axis: one of {', '.join(ABS_CODES)}")
    return name


def _control(name: str) -> str:
    if name in KEY_CODES:
        return name
    if name[-1:] in ("+", "-") and name[:-1] in ABS_CODES:
        return name
    raise ValueError(
        "a button (BTN_SOUTH, BTN_TL…, any BTN_ name of input-event-codes.h a gamepad "
        "uses) or an axis and a direction (ABS_HAT0Y-, ABS_RZ+)"
    )


def _action(text: str) -> str:
    kind, _, value = text.partition(":")
    if text in ("stop", "flip", "none"):
        return text
    if kind == "gait" and value in GAITS:
        return text
    if kind == "mode" and value in MODES:
        return text
    if kind == "stance" and value:
        return text  # a preset of [stances]: checked across sections
    raise ValueError(
        "stop, flip, none, "
        + ", ".join(f"gait:{g}" for g in GAITS)
        + ", "
        + ", ".join(f"mode:{m}" for m in MODES)
        + " or stance:NAME (a [stances] preset)"
    )


AxisName = Annotated[str, AfterValidator(_axis)]
"""An ``EV_ABS`` code by name: ``ABS_X``, ``ABS_HAT0Y``…"""
ControlName = Annotated[str, AfterValidator(_control)]
"""A button (``BTN_*``) or an axis direction (``ABS_*+``, ``ABS_*-``)."""
ActionName = Annotated[str, AfterValidator(_action)]
"""What a control does: stop, flip, none, gait:…, mode:…, stance:…"""


class StickSpec(Section):
    """One stick axis and its sense: ``invert`` when pushing it the positive way (right,
    down: the kernel's sense) should mean a negative command."""

    axis: AxisName
    invert: bool = False


def default_ranges() -> dict[str, tuple[int, int]]:
    # xpad's ranges (the Xbox pads): sticks 16-bit signed, triggers 0..255 (the Xbox One's
    # are 0..1023), hats -1..1. hid-playstation's sticks are 0..255: the device's own
    # range (EVIOCGABS) is what counts unless axis_ranges = "config".
    stick = (-32768, 32767)
    return {
        "ABS_X": stick,
        "ABS_Y": stick,
        "ABS_RX": stick,
        "ABS_RY": stick,
        "ABS_Z": (0, 255),
        "ABS_RZ": (0, 255),
        "ABS_HAT0X": (-1, 1),
        "ABS_HAT0Y": (-1, 1),
    }


def default_buttons() -> dict[str, str]:
    return {
        "BTN_EAST": "stop",  # B (Xbox) / Circle (PlayStation)
        "BTN_SOUTH": "mode:walk",  # A / Cross
        "BTN_NORTH": "mode:ride",  # 0x133: X on xpad pads, Triangle on PlayStation pads
        "BTN_WEST": "mode:hybrid",  # 0x134: Y on xpad pads, Square on PlayStation pads
        "ABS_HAT0Y-": "gait:tripod",  # d-pad up
        "ABS_HAT0X+": "gait:tetrapod",  # d-pad right
        "ABS_HAT0Y+": "gait:ripple",  # d-pad down
        "ABS_HAT0X-": "gait:wave",  # d-pad left
        "BTN_DPAD_UP": "gait:tripod",  # the same d-pad on pads that report it as buttons
        "BTN_DPAD_RIGHT": "gait:tetrapod",
        "BTN_DPAD_DOWN": "gait:ripple",
        "BTN_DPAD_LEFT": "gait:wave",
        "BTN_START": "stance:default",  # Menu / Options
        "BTN_TR": "stance:high",  # RB / R1
        "ABS_RZ+": "stance:low",  # RT / R2 pulled
        "BTN_SELECT": "flip",  # View, Back / Share, Create
    }


AxisRange = tuple[int, int]


class GamepadSpec(Section):
    """The gamepad as a command source: its device, its mapping, its safety timings."""

    device: str = Field(default="/dev/input/event0", min_length=1)
    """The event device ``source = "gamepad"`` opens; a ``/dev/input/by-id/…-event-joystick``
    link names one pad whatever the order it was plugged in."""
    record_bytes: Literal["native", 16, 24] = "native"
    """Size of one ``struct input_event``: ``native`` is this Python's (24 on a 64-bit OS, 16
    on 32-bit Raspberry Pi OS); 16 or 24 to decode the other's bytes."""
    axis_ranges: Literal["device", "config"] = "device"
    """``device``: each axis's range as the device reports it (EVIOCGABS), ``ranges`` where
    it cannot tell (a pipe); ``config``: ``ranges`` always."""
    dead_man: ControlName = "BTN_TL"
    """Held: the pad drives; let go: the robot is commanded to stop, and no button but
    ``stop`` does anything. Default: LB / L1."""
    forward: StickSpec = StickSpec(axis="ABS_Y", invert=True)
    """Forward speed: the left stick up (the kernel's up is negative)."""
    sideways: StickSpec = StickSpec(axis="ABS_X", invert=True)
    """Sideways speed, positive to the left: the left stick left."""
    turn: StickSpec = StickSpec(axis="ABS_RX", invert=True)
    """Turn rate, positive counter-clockwise: the right stick left."""
    dead_zone: float = Field(default=0.2, ge=0, lt=0.9, allow_inf_nan=False)
    """Fraction of a stick's half-travel about its centre read as zero (XInput suggests about
    24 % for worn sticks); beyond it the speed rises from zero to full."""
    resolution: float = Field(default=0.05, gt=0, le=0.5, allow_inf_nan=False)
    """A stick's travel is read in steps of this fraction, with a quarter step of hysteresis:
    a stick's jitter sends no new command."""
    max_forward_m_s: Positive = 0.2
    """Forward speed at full travel (the riding maximum, 6.5.1; walking gaits clamp lower)."""
    max_sideways_m_s: Positive = 0.1
    max_yaw_rate_deg_s: Positive = 30.0
    silent_after_s: Positive = 2.0
    """No event for this long while the dead-man is held and the pad asks for motion: the
    robot is commanded to stop. A stick held still sends nothing (the kernel reports
    changes only), so this is not much shorter than a person keeps a stick at its stop."""
    reopen_period_s: Positive = 1.0
    """How often a pad that is not there (unplugged, not yet paired) is looked for."""
    ranges: dict[AxisName, AxisRange] = Field(default_factory=default_ranges)
    """Each axis's ``[minimum, maximum]`` raw value, where the device does not say."""
    buttons: dict[ControlName, ActionName] = Field(default_factory=default_buttons)
    """Control → action, for every control but the dead-man."""

    @property
    def max_yaw_rate_rad_s(self) -> float:
        return math.radians(self.max_yaw_rate_deg_s)

    def problems(self, at: str) -> list[Problem]:
        found: list[Problem] = []
        for name, (low, high) in self.ranges.items():
            if low >= high:
                found.append(
                    Problem(
                        format_path((at, "ranges", name)),
                        [low, high],
                        "[minimum, maximum], the minimum below the maximum",
                    )
                )
        sticks = {role: getattr(self, role).axis for role in ("forward", "sideways", "turn")}
        seen: dict[str, str] = {}
        for role, axis in sticks.items():
            if axis in seen:
                found.append(
                    Problem(
                        f"{at}.{role}.axis", axis, f"an axis no other stick uses ({seen[axis]})"
                    )
                )
            seen.setdefault(axis, role)
        axes_needed = [(f"{at}.{role}.axis", axis) for role, axis in sticks.items()]
        controls = [(f"{at}.dead_man", self.dead_man)]
        controls += [(format_path((at, "buttons", name)), name) for name in self.buttons]
        used: dict[tuple[str, int], str] = {}
        for path, control in controls:
            if control in KEY_CODES:
                key = ("key", KEY_CODES[control])
            else:
                axis = control[:-1]
                key = (control[-1], ABS_CODES[axis])
                axes_needed.append((path, axis))
                if axis in sticks.values():
                    role = next(r for r, a in sticks.items() if a == axis)
                    found.append(
                        Problem(path, control, f"an axis no stick drives ({role} uses {axis})")
                    )
            if key in used:
                found.append(
                    Problem(path, control, f"a control mapped once: the same code as {used[key]}")
                )
            used.setdefault(key, path)
        for path, axis in axes_needed:
            if axis not in self.ranges:
                found.append(
                    Problem(path, axis, f"an axis with a range under {at}.ranges (add {axis})")
                )
        return found


def stance_problems(
    spec: GamepadSpec, stances: Iterable[str], at: str = "gamepad"
) -> list[Problem]:
    """Every ``stance:NAME`` action whose NAME is not a stance preset."""
    known = sorted(stances)
    return [
        Problem(
            format_path((at, "buttons", control)),
            action,
            f"stance:NAME of a preset: {', '.join(known)}",
        )
        for control, action in spec.buttons.items()
        if action.startswith("stance:") and action.removeprefix("stance:") not in known
    ]
