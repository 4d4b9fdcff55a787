"""The keyboard as a command source: keys in, commands and a status line out.

:func:`split_keys` cuts terminal input into keys (arrows are escape
sequences), :func:`key_command` turns one key into the next
:class:`KeyboardState` and, when it changes what is asked for, a
:class:`MotionCommand`; :func:`status_line` draws the command and the
coordinator's :class:`LocomotionState` on one line. Pure functions: the
terminal itself is :mod:`.terminal`'s.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Final

from whexar.actors.commands.script import GAITS
from whexar.actors.messages import LocomotionState, MotionCommand

SPEED_STEP_M_S: Final = 0.02
"""Forward, backward and sideways speed change per key press."""
YAW_STEP_RAD_S: Final = 0.1
"""Turn rate change per key press."""
STEP_HEIGHT_STEP_M: Final = 0.01
"""Step height change per ``+`` or ``-``."""
MAX_SPEED_M_S: Final = 0.5
MAX_YAW_RATE_RAD_S: Final = 2.0
STEP_HEIGHT_RANGE_M: Final = (0.01, 0.2)
# The coordinator clamps a command to what the robot can do (and says so with an
# event); these limits only keep a held key from winding the keyboard's own
# numbers far past that, so that a few presses always bring it back.

STATUS_PERIOD_S: Final = 0.1
"""Shortest time between two redraws of the status line for a new state (keys redraw at once)."""

HELP: Final = (
    "keys: arrows/WASD speed and turn, Q/E sideways, 1-4 tripod/tetrapod/ripple/wave, 0 auto, "
    "k walk, r ride, h hybrid, +/- step height, f flip, space stop, x quit, Ctrl-C stop the run"
)

CLEAR_LINE: Final = "\r\x1b[K"
"""Carriage return and erase to the end of the line: where the status line is redrawn."""

_ARROWS: Final = {"A": "up", "B": "down", "C": "right", "D": "left"}


@dataclass(frozen=True)
class KeyboardState:
    """What the keyboard has asked for so far (the robot's actual state is the coordinator's)."""

    vx_m_s: float = 0.0
    vy_m_s: float = 0.0
    yaw_rate_rad_s: float = 0.0
    gait: str | None = None
    """``None`` until a gait key is pressed: the coordinator's choice stands."""
    mode: str | None = None
    step_height_m: float = 0.06
    upside_down: bool = False
    quit: bool = False
    """``x`` was pressed: the run should end."""


def _stepped(value: float, step: float, limit: float) -> float:
    # Rounded so that n presses up and n down give exactly 0 again.
    return round(min(limit, max(-limit, value + step)), 6)


def _velocity(state: KeyboardState, *, t: float, source: str) -> MotionCommand:
    # Each velocity key sends all three: the keyboard owns the whole velocity.
    return MotionCommand(
        t=t,
        source=source,
        vx_m_s=state.vx_m_s,
        vy_m_s=state.vy_m_s,
        yaw_rate_rad_s=state.yaw_rate_rad_s,
    )


_MOVES: Final = {
    "up": (SPEED_STEP_M_S, 0.0, 0.0),
    "w": (SPEED_STEP_M_S, 0.0, 0.0),
    "down": (-SPEED_STEP_M_S, 0.0, 0.0),
    "s": (-SPEED_STEP_M_S, 0.0, 0.0),
    "q": (0.0, SPEED_STEP_M_S, 0.0),
    "e": (0.0, -SPEED_STEP_M_S, 0.0),
    "left": (0.0, 0.0, YAW_STEP_RAD_S),
    "a": (0.0, 0.0, YAW_STEP_RAD_S),
    "right": (0.0, 0.0, -YAW_STEP_RAD_S),
    "d": (0.0, 0.0, -YAW_STEP_RAD_S),
}
"""Velocity keys: the change of (vx, vy, yaw rate) they make; y and yaw are positive to the left."""

_MODE_KEYS: Final = {"k": "walk", "r": "ride", "h": "hybrid"}


def key_command(
    key: str, current: KeyboardState, *, t: float = 0.0, source: str = "keyboard"
) -> tuple[KeyboardState, MotionCommand | None]:
    """What pressing ``key`` asks for: the keyboard's new state and the command to send, if any.

    ``key`` is a character or an arrow's name (``up``, ``down``, ``left``,
    ``right``; see :func:`split_keys`); letters count in either case.

    * ↑/``w``, ↓/``s``: forward speed ±0.02 m/s; ←/``a``, →/``d``: turn rate
      ±0.1 rad/s (left is positive); ``q``, ``e``: sideways ±0.02 m/s (left,
      right). Each sends the whole velocity.
    * ``1``–``4``: gait tripod, tetrapod, ripple, wave, ``0``: the gait selector's;
      ``k`` walk, ``r`` ride, ``h`` hybrid.
    * ``+`` (or ``=``), ``-``: step height ±0.01 m; ``f``: turn over (upside_down).
    * space: stop — velocity zero and ``stop``; ``x``: the same, and ``quit``.

    Any other key changes nothing and sends nothing. The command is stamped
    ``t`` and ``source``.
    """
    name = key if len(key) > 1 else key.lower()
    move = _MOVES.get(name)
    if move is not None:
        dvx, dvy, dyaw = move
        state = dataclasses.replace(
            current,
            vx_m_s=_stepped(current.vx_m_s, dvx, MAX_SPEED_M_S),
            vy_m_s=_stepped(current.vy_m_s, dvy, MAX_SPEED_M_S),
            yaw_rate_rad_s=_stepped(current.yaw_rate_rad_s, dyaw, MAX_YAW_RATE_RAD_S),
        )
        return state, _velocity(state, t=t, source=source)
    if name in (" ", "x"):
        state = dataclasses.replace(
            current, vx_m_s=0.0, vy_m_s=0.0, yaw_rate_rad_s=0.0, quit=name == "x"
        )
        command = MotionCommand(
            t=t, source=source, vx_m_s=0.0, vy_m_s=0.0, yaw_rate_rad_s=0.0, stop=True
        )
        return state, command
    if name in ("1", "2", "3", "4", "0"):
        gait = GAITS[int(name) - 1]  # "0": the last, auto
        return dataclasses.replace(current, gait=gait), MotionCommand(t=t, source=source, gait=gait)
    if name in _MODE_KEYS:
        mode = _MODE_KEYS[name]
        return dataclasses.replace(current, mode=mode), MotionCommand(t=t, source=source, mode=mode)
    if name in ("+", "=", "-"):
        step = STEP_HEIGHT_STEP_M if name != "-" else -STEP_HEIGHT_STEP_M
        low, high = STEP_HEIGHT_RANGE_M
        height = round(min(high, max(low, current.step_height_m + step)), 6)
        return dataclasses.replace(current, step_height_m=height), MotionCommand(
            t=t, source=source, step_height_m=height
        )
    if name == "f":
        flipped = not current.upside_down
        return dataclasses.replace(current, upside_down=flipped), MotionCommand(
            t=t, source=source, upside_down=flipped
        )
    return current, None


def split_keys(text: str) -> tuple[list[str], str]:
    """Split what the terminal sent into keys; returns the keys and an unfinished tail.

    An arrow's escape sequence (``ESC [ A`` and its modified and application-mode
    forms ``ESC [ 1 ; 5 A``, ``ESC O A``) becomes ``up``, ``down``, ``right`` or
    ``left``; any other escape sequence becomes ``"\\x1b"`` (no key of ours). An
    escape sequence cut off at the end of ``text`` is the tail: prepend it to
    what comes next.
    """
    keys: list[str] = []
    i = 0
    n = len(text)
    while i < n:
        char = text[i]
        if char != "\x1b":
            keys.append(char)
            i += 1
            continue
        if i + 1 >= n:
            return keys, text[i:]
        kind = text[i + 1]
        if kind == "O":  # SS3: one final character
            if i + 2 >= n:
                return keys, text[i:]
            keys.append(_ARROWS.get(text[i + 2], "\x1b"))
            i += 3
        elif kind == "[":  # CSI: parameters and intermediates, then a final byte
            j = i + 2
            while j < n and 0x20 <= ord(text[j]) <= 0x3F:
                j += 1
            if j >= n:
                return keys, text[i:]
            keys.append(_ARROWS.get(text[j], "\x1b"))
            i = j + 1
        else:  # Alt+key or a lone Esc: no key of ours; the next character counts alone
            keys.append("\x1b")
            i += 1
    return keys, ""


def status_line(
    current: KeyboardState, state: LocomotionState | None = None, *, width: int | None = None
) -> str:
    """The keyboard's one status line: the command asked for, and the robot's state if known.

    ``width`` (the terminal's columns) cuts the line one short of it, so that
    it never wraps: a wrapped line could not be redrawn in place.
    """
    flipped = " flipped" if current.upside_down else ""
    parts = [
        f"cmd vx {current.vx_m_s:+.2f} vy {current.vy_m_s:+.2f} yaw {current.yaw_rate_rad_s:+.2f}",
        f"{current.gait or 'gait -'} {current.mode or 'mode -'} "
        f"step {current.step_height_m * 100:.0f} cm{flipped}",
    ]
    if state is None:
        parts.append("no locomotion state")
    else:
        vx, vy, yaw = state.twist
        swing = ",".join(str(leg) for leg in state.swing_legs) or "-"
        parts.append(
            f"{state.activity} {state.gait} {state.mode} "
            f"twist {vx:+.2f} {vy:+.2f} {yaw:+.2f} "
            f"margin {state.margin_m * 1000:.0f} mm swing {swing}"
        )
    line = " | ".join(parts)
    if width is not None and len(line) >= width:
        line = line[: max(0, width - 1)]
    return line
