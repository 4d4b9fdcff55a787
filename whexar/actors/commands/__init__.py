"""Where motion commands come from: a script, stdin, or a person at the keyboard or a gamepad.

Theory of operation
-------------------
:class:`CommandSource` turns what someone wants into
:class:`~whexar.actors.messages.MotionCommand` messages on its ``commands``
port, for the coordinator. Its ``source`` parameter chooses the front end:

* **a command script** (any value but the three words below: a file) — JSON
  lines, each one command with its time ``t`` in seconds since the start of
  the run::

      # forward in the tripod gait, turn left after 4.5 s, stop at 8 s
      {"t": 0, "vx_m_s": 0.1, "gait": "tripod"}
      {"t": 4.5, "yaw_rate_rad_s": 0.2}
      {"t": 8, "stop": true}

  The other keys are the fields of ``MotionCommand`` (not ``t`` or
  ``source``); blank lines and lines starting with ``#`` are skipped. The
  file is checked whole — with the wiring, and again when the actor starts,
  before it reports ready — and every problem is listed at once with its
  line, key, value and what is allowed (:func:`load_script`). The actor then
  sleeps on the runtime clock until each line's time and sends the command
  stamped with that time, so a script on virtual time gives the same run
  every time. After the last line it idles.
* ``stdin`` — the same JSON lines, read as they arrive; a ``t`` may be given
  but is ignored: a command applies when it is read. A bad line is one
  :class:`~whexar.actors.messages.CommandRefused` event and is skipped; the
  actor never fails on what it reads. End of input leaves it idle (a piped
  one-liner must not stop the robot). On virtual time stdin is not read at
  all — waiting on it would let virtual time run away — and one
  ``CommandRefused`` says so, unless the graph allows real I/O.
* ``keyboard`` — a person drives (:func:`key_command` has the keys). The
  terminal goes into cbreak mode, not raw: keys arrive one by one without
  echo, but Ctrl-C still raises SIGINT, which the runtime owns (its first
  SIGINT stops the run in order, a second one stops it safely at once). One
  status line on stderr (:func:`status_line`) shows the command and, when the
  ``state`` input is wired, the coordinator's
  :class:`~whexar.actors.messages.LocomotionState`. The terminal's settings
  are restored however the actor ends, and by its :meth:`~CommandSource.safe_stop`
  too, which a second Ctrl-C runs before the process exits without cleanup.
  Keys are read through the event loop (a watched descriptor), not a thread.
* ``gamepad`` or ``gamepad:DEVICE`` — a person drives with a Linux gamepad
  (``/dev/input/eventN``; without DEVICE the ``[gamepad]`` section's
  ``device``). The sticks give forward, sideways and turn speeds, buttons the
  gait, mode, stance, a flip and a stop, as the ``[gamepad]`` section of the
  robot configuration maps them (the ``config`` parameter; :mod:`.gamepad` has
  the policy: dead zone, steps, the dead-man). The pad drives only while its
  dead-man button is held. The device's records (:mod:`whexar.sensors.evdev`)
  are read through the event loop from a non-blocking descriptor
  (:mod:`whexar.sensors.evdev_link`), each report applied whole. A pad that is
  not there, or goes away (ENODEV, end of file), is
  :class:`~whexar.actors.messages.GamepadLinkDown` — and a stop if the robot
  moved — and is looked for again every ``reopen_period_s``
  (:class:`~whexar.actors.messages.GamepadLinkUp`); a pad silent for
  ``silent_after_s`` while it drives is a stop and
  :class:`~whexar.actors.messages.GamepadLinkSilent`; events the kernel dropped
  are :class:`~whexar.actors.messages.GamepadEventsDropped`. ``pipe:NAME`` as
  the device reads an in-process :class:`~whexar.sensors.evdev_link.EventPipe`
  instead (tests). Real time only, unless the graph allows real I/O.
* ``none`` — nothing is sent (a graph driven by a scenario).

Every front end makes the same typed command, so the coordinator has one
path for all of them. The actor (:mod:`.source`) only chooses the front end
and sends what it makes: the script parser (:mod:`.script`: :func:`load_script`,
:func:`parse_command`), the keyboard's keys and status line (:mod:`.keyboard`:
:func:`key_command`, :func:`split_keys`, :func:`status_line`) are pure
functions, and the gamepad's mapping is a plain class (:mod:`.gamepad`:
:class:`GamepadPolicy`, :class:`GamepadMapping`), all tested without a
terminal, a device or a loop; the terminal and stdin are :mod:`.terminal`'s.

May import: :mod:`whexar.actors.messages`, :mod:`whexar.config` and the layers below;
never another actor subsystem.
"""

from whexar.actors.commands.gamepad import AxisRange, GamepadMapping, GamepadPolicy
from whexar.actors.commands.keyboard import KeyboardState, key_command, split_keys, status_line
from whexar.actors.commands.script import (
    GAITS,
    GAMEPAD_PREFIX,
    KEYWORDS,
    MODES,
    MOTION_FIELDS,
    load_script,
    motion_fields,
    parse_command,
)
from whexar.actors.commands.source import STDIN_ON_VIRTUAL_TIME, CommandSource
from whexar.actors.commands.terminal import LineReader

__all__ = [
    "GAITS",
    "GAMEPAD_PREFIX",
    "KEYWORDS",
    "MODES",
    "MOTION_FIELDS",
    "STDIN_ON_VIRTUAL_TIME",
    "AxisRange",
    "CommandSource",
    "GamepadMapping",
    "GamepadPolicy",
    "KeyboardState",
    "LineReader",
    "key_command",
    "load_script",
    "motion_fields",
    "parse_command",
    "split_keys",
    "status_line",
]
