"""``whexar sensors``: watch a sensor board's frames while bringing it up.

The monitor runs the real :class:`~whexar.actors.sensing.SensorReader` on
real time and prints each decoded frame as it arrives, plus one line for
every link event (up, down, stale, fresh), sequence gap, rejected frame and
change of the accelerometer's plausibility.

Each IR rangefinder reads one of three ways: a distance; nothing within
range (``--`` in a line, ``"clear"``); or no reading, its input at 0 V — an
unplugged or unpowered sensor, whose view is unknown (``n/c`` in a line,
``"no_reading"``). With ``--json`` every line is one strict JSON object (no
``NaN`` or ``Infinity``) whose ``kind`` is ``frame`` or ``event`` (then ``event``
is its class name); ``ir_distance_m`` holds a distance or ``null`` per sensor and
``ir_status`` says which of the three it is (``"range"``, ``"clear"``,
``"no_reading"``); ``loads`` are the FSR counts; ``roll_deg`` and
``pitch_deg`` are ``null`` when there is no tilt (no accelerometer fitted, or
its reading is not gravity).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from whexar import _json
from whexar.actors.messages import (
    AccelImplausible,
    AccelPlausible,
    SensorFrame,
    SensorFrameGap,
    SensorFrameRejected,
    SensorLinkDown,
    SensorLinkFresh,
    SensorLinkStale,
    SensorLinkUp,
)
from whexar.cli.common import Commands, seconds
from whexar.runtime.messages import Message
from whexar.runtime.wiring import EVENTS_CHANNEL
from whexar.sensors.frame import ACC_KEYS, FSR_KEYS, IR_KEYS

SENSOR_EVENTS = (
    SensorLinkUp,
    SensorLinkDown,
    SensorLinkStale,
    SensorLinkFresh,
    SensorFrameGap,
    SensorFrameRejected,
    AccelImplausible,
    AccelPlausible,
)
"""The events the monitor prints."""


def _deg(rad: float | None) -> float | None:
    return None if rad is None else round(math.degrees(rad), 2)


def ir_status(distance: float | None) -> str:
    """``"range"`` (a distance), ``"clear"`` (nothing within range) or ``"no_reading"``."""
    if distance is None:
        return "no_reading"
    return "clear" if math.isinf(distance) else "range"


def _ir_text(distance: float | None) -> str:
    if distance is None:
        return " n/c "
    return "  -- " if math.isinf(distance) else f"{distance:.3f}"


def frame_record(frame: SensorFrame) -> dict[str, Any]:
    """A frame as a JSON-ready dict: raw counts by key, then the converted values."""
    raw: dict[str, int] = {}
    for keys, values in (
        (IR_KEYS, frame.ir_counts),
        (ACC_KEYS, frame.acc_counts),
        (FSR_KEYS, frame.fsr_counts),
    ):
        if values is not None:
            raw.update(zip(keys, values, strict=True))
    distances = frame.ir_distances_m
    return {
        "kind": "frame",
        "t": round(frame.t, 6),
        "seq": frame.seq,
        "raw": raw,
        "ir_distance_m": None
        if distances is None
        else [None if d is None or math.isinf(d) else round(d, 4) for d in distances],
        "ir_status": None if distances is None else [ir_status(d) for d in distances],
        "loads": None if frame.fsr_counts is None else list(frame.fsr_counts),
        "contacts": None if frame.contacts is None else list(frame.contacts),
        "roll_deg": _deg(frame.roll_rad),
        "pitch_deg": _deg(frame.pitch_rad),
        "missed": frame.missed,
    }


def frame_line(frame: SensorFrame) -> str:
    """A frame as one human-readable line."""
    seq = "-" if frame.seq is None else str(frame.seq)
    parts = [f"{frame.t:10.3f}  seq {seq:>5}"]
    if frame.ir_counts is not None and frame.ir_distances_m is not None:
        shown = ", ".join(_ir_text(d) for d in frame.ir_distances_m)
        parts.append(f"ir {frame.ir_counts[0]:4d} {frame.ir_counts[1]:4d} ({shown} m)")
    if frame.fsr_counts is not None and frame.contacts is not None:
        marks = "".join("#" if c else "." for c in frame.contacts)
        parts.append(f"fsr {' '.join(f'{c:4d}' for c in frame.fsr_counts)} [{marks}]")
    if frame.roll_rad is not None and frame.pitch_rad is not None:
        parts.append(f"roll {_deg(frame.roll_rad):+6.1f}° pitch {_deg(frame.pitch_rad):+6.1f}°")
    elif frame.acc_counts is not None:
        parts.append("acc " + " ".join(f"{c:4d}" for c in frame.acc_counts) + " (no tilt)")
    return "  ".join(parts)


def event_record(event: Message) -> dict[str, Any]:
    """A sensor event as a JSON-ready dict."""
    fields = {
        name: getattr(event, name)
        for name in event.__dataclass_fields__
        if name not in ("t", "source")
    }
    return {"kind": "event", "t": round(event.t, 6), "event": type(event).__name__, **fields}


def event_line(event: Message) -> str:
    """A sensor event as one human-readable line."""
    t = f"{event.t:10.3f}  "
    match event:
        case SensorLinkUp():
            return f"{t}link up: {event.link}"
        case SensorLinkDown():
            return f"{t}link DOWN: {event.reason}"
        case SensorLinkStale():
            return (
                f"{t}STALE: no valid frame for {event.silent_s:.3f} s (last seq {event.last_seq})"
            )
        case SensorLinkFresh():
            return f"{t}fresh again after {event.silent_s:.3f} s"
        case SensorFrameGap(restarted=True):
            return f"{t}board RESTARTED: seq {event.seq} where {event.expected} was due"
        case SensorFrameGap():
            return f"{t}GAP: {event.missed} frame(s) lost before seq {event.seq}"
        case SensorFrameRejected():
            return f"{t}REJECTED ({event.size} bytes): {event.reason}: {event.excerpt}"
        case AccelImplausible():
            return (
                f"{t}{event.sensor} accelerometer NOT GRAVITY: |a| = {event.magnitude_g:.2f} g "
                f"(1 ± {event.tolerance_g:g} g expected): no tilt"
            )
        case AccelPlausible():
            return (
                f"{t}{event.sensor} accelerometer reads gravity again "
                f"(|a| = {event.magnitude_g:.2f} g) after {event.withheld} reading(s)"
            )
    return f"{t}{type(event).__name__}"


def observer(as_json: bool, write: Callable[[str], None]) -> Callable[[str, Message], None]:
    """A runtime observer that writes frames and sensor events, one line each."""

    def observe(channel: str, msg: Message) -> None:
        if channel == "frames" and isinstance(msg, SensorFrame):
            write(_json.dumps(frame_record(msg)) if as_json else frame_line(msg))
        elif channel == EVENTS_CHANNEL and isinstance(msg, SENSOR_EVENTS):
            write(_json.dumps(event_record(msg)) if as_json else event_line(msg))

    return observe


def _sensors(args: argparse.Namespace) -> int:
    from whexar.actors.sensing.monitor import sensor_graph
    from whexar.runtime.clock import run as run_loop
    from whexar.runtime.supervisor import Runtime
    from whexar.runtime.wiring import build_graph

    params: dict[str, object] = {}
    if args.baud is not None:
        params["baudrate"] = args.baud
    if args.config is not None:
        params["config"] = str(args.config)
    if args.protocol is not None:
        params["protocol"] = args.protocol
    graph = build_graph(sensor_graph(args.port, params, outputs=("frames",)))

    def write(line: str) -> None:
        print(line, flush=True)

    runtime = Runtime(graph, handle_signals=True, observer=observer(args.json, write))
    if not args.json:
        print(f"reading {args.port}; stop with Ctrl-C", flush=True)

    async def main() -> int:
        return await runtime.run(duration=args.duration)

    return run_loop(main)


def add_commands(commands: Commands) -> None:
    """Add this group's commands to the ``whexar`` command table."""
    sensors = commands.add_parser(
        "sensors",
        help="print the sensor board's frames as they arrive",
        description="Read the sensor board (firmware/PROTOCOL.md) through the real sensor "
        "reader and print each decoded frame: raw counts, IR distances (eq. 5.5), FSR "
        "counts and contact flags, roll and pitch, sequence number; and a line for every "
        "link event, sequence gap, rejected frame and implausible accelerometer. An IR "
        "sensor reads a distance, '--' (nothing within range) or 'n/c' (no reading: its "
        "input is at 0 V, unplugged). Runs until SIGINT/SIGTERM or "
        "--duration. Exit status 0 after a clean stop.",
    )
    sensors.add_argument(
        "--port", required=True, help="e.g. /dev/ttyACM0, the pty of whexar-sim, or 'emulator'"
    )
    sensors.add_argument(
        "--baud", type=int, default=None, help="default: sensor_board.baudrate (1000000)"
    )
    sensors.add_argument(
        "--config", type=Path, default=None, help="robot configuration (calibrations, thresholds)"
    )
    sensors.add_argument(
        "--protocol",
        choices=("checked", "thesis"),
        default=None,
        help="checked: frames need seq and crc (default); thesis: plain frames too",
    )
    sensors.add_argument("--json", action="store_true", help="one JSON object per line")
    sensors.add_argument(
        "--duration", type=seconds, default=None, help="stop after this many seconds"
    )
    sensors.set_defaults(handler=_sensors)
