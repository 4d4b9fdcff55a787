"""The sensor board: its port, its frames (``firmware/PROTOCOL.md``) and their rate.

The check opens ``[sensor_board] port`` at ``[sensor_board] baudrate`` and listens
for the first frame (a real Mega resets when its port opens and its bootloader waits
about a second first, ``firmware/README.md``). It then asks for the configured rate
with ``rate=N#`` as the runtime's reader does, and measures the rate the frames arrive
at. What it reports, each with its fix:

* no byte at all: the firmware is not running (not flashed, held in reset, wrong port);
* bytes but no frame: another baud rate (the rate the frames decode at is looked for),
  or not whexar's firmware;
* plain thesis frames (no ``seq``, no ``crc``) where ``protocol = "checked"``;
* a group missing (IR or force sensors), or an accelerometer where none is configured
  (and the reverse);
* a rate that is not the one asked for (a firmware without ``rate=N#``);
* frames lost or rejected while measuring, and rangefinders that read 0 (unplugged).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final

from whexar.doctor import host
from whexar.doctor.environment import BoardPort, Environment
from whexar.doctor.report import CheckResult, Findings, Status, fail, warn
from whexar.sensors.frame import Frame, FrameDecoder, Rejected
from whexar.sensors.usart import BOARD_BAUDRATES

NAME: Final = "sensor board"
FIRST_FRAME_S: Final = 3.0
"""Longest wait for the first frame: the Mega's bootloader runs about 1 s after the reset
that opening its port causes (``firmware/README.md``), then one frame period (0.1 s at the
slowest 10 Hz); three times that covers a slow USB enumeration."""
MEASURE_S: Final = 1.5
"""How long the frame rate is measured: 30 frames at the default 20 Hz, so one frame
more or less is 3 %, within :data:`RATE_TOLERANCE`."""
RATE_TOLERANCE: Final = 0.1
"""Largest relative difference between the measured and the asked frame rate."""
FLASH: Final = (
    "flash whexar's firmware (firmware/README.md: make -C firmware, then avrdude … "
    "-U flash:w:build/whexar_sensors.hex:i)"
)
IR_SIDES: Final = ("right front", "left front")
"""``ir1`` and ``ir2``'s legs (firmware/PROTOCOL.md, Fields)."""


@dataclass(slots=True)
class Heard:
    """What one listen read: bytes, frames with their arrival times, rejections."""

    size: int = 0
    frames: list[tuple[float, Frame]] = field(default_factory=list)
    rejected: list[Rejected] = field(default_factory=list)


def listen(
    port: BoardPort,
    now: Callable[[], float],
    decoder: FrameDecoder,
    seconds: float,
    *,
    frames: int | None = None,
) -> Heard:
    """Read ``port`` for ``seconds`` (or until ``frames`` frames have arrived)."""
    heard = Heard()
    end = now() + seconds
    while now() < end:
        data = port.read(4096)
        if not data:
            continue
        heard.size += len(data)
        t = now()
        for item in decoder.feed(data):
            if isinstance(item, Frame):
                heard.frames.append((t, item))
            else:
                heard.rejected.append(item)
        if frames is not None and len(heard.frames) >= frames:
            break
    return heard


def check_sensor_board(env: Environment, found: Findings) -> CheckResult:
    """The board answers on its port with whexar's frames, at the configured rate."""
    spec = env.config.sensor_board
    path = Path(env.board_port_name)
    absent = host.device(
        env,
        path,
        NAME,
        "the sensor board is not plugged in, or is another device",
        "plug the Mega's USB cable in and find its port with: ls /dev/serial/by-id/; "
        "then pass --board-port DEVICE or set [sensor_board] port",
    )
    if absent is not None:
        return absent
    port = _open(env, str(path), spec.baudrate)
    if isinstance(port, CheckResult):
        return port
    found.closers.append(port.close)
    decoder = FrameDecoder(mode="thesis")  # hears plain frames too, to say so
    decoder.clear(tail_expected=True)
    first = listen(port, env.now, decoder, FIRST_FRAME_S, frames=2)
    if not first.frames:
        return _silent(env, port, first, str(path), spec.baudrate)
    frame = first.frames[-1][1]
    if spec.protocol == "checked" and not frame.checked:
        return fail(
            NAME,
            f"{path} sends the thesis's plain frames (no seq, no crc); "
            '[sensor_board] protocol is "checked"',
            f'{FLASH}; or set [sensor_board] protocol = "thesis"',
        )
    missing = [what for what, got in (("ir1, ir2", frame.ir), ("fsr0…fsr5", frame.fsr)) if not got]
    if missing:
        return fail(
            NAME,
            f"{path}'s frames carry no {' and no '.join(missing)}: not whexar's firmware",
            FLASH,
        )
    asked = round(spec.frame_rate_hz)
    port.write(f"rate={asked}#".encode())
    # The rate holds from the board's next frame on: measure from the one after it.
    listen(port, env.now, decoder, FIRST_FRAME_S, frames=1)
    measured = listen(port, env.now, decoder, MEASURE_S)
    return _judge(env, str(path), first, measured, asked)


def _open(env: Environment, path: str, baudrate: int) -> BoardPort | CheckResult:
    try:
        port = env.open_board_port(path, baudrate)
    except OSError as exc:
        return fail(NAME, f"cannot open {path}: {host.reason(exc)}", None)
    # Bytes queued before this open (a pty, a board that did not reset) are not news.
    with contextlib.suppress(OSError):
        port.reset_input_buffer()
    return port


def _silent(
    env: Environment, port: BoardPort, heard: Heard, path: str, baudrate: int
) -> CheckResult:
    """No frame at ``baudrate``: say whether anything came, and at which rate frames do."""
    if heard.size == 0:
        return fail(
            NAME,
            f"{path} sent nothing in {FIRST_FRAME_S:g} s: the board's firmware is not running",
            f"{FLASH}; check that {path} is the board (ls /dev/serial/by-id/)",
        )
    port.close()
    for rate in (r for r in BOARD_BAUDRATES if r != baudrate):
        other = _open(env, path, rate)
        if isinstance(other, CheckResult):
            break
        try:
            decoder = FrameDecoder(mode="thesis")
            decoder.clear(tail_expected=True)
            if listen(other, env.now, decoder, FIRST_FRAME_S, frames=2).frames:
                return fail(
                    NAME,
                    f"{path} sent {heard.size} bytes but no frame at {baudrate} bps; "
                    f"its frames decode at {rate} bps",
                    f"set [sensor_board] baudrate = {rate} (or build the firmware with "
                    f"BAUD={baudrate})",
                )
        finally:
            other.close()
    rates = ", ".join(str(r) for r in BOARD_BAUDRATES)
    return fail(
        NAME,
        f"{path} sent {heard.size} bytes but no frame at any of {rates} bps: not whexar's firmware",
        FLASH,
    )


def _judge(env: Environment, path: str, first: Heard, measured: Heard, asked: int) -> CheckResult:
    spec = env.config.sensor_board
    frames = measured.frames
    last = (frames or first.frames)[-1][1]
    ir = last.ir or (0, 0)
    groups = "IR and force sensors" + (", accelerometer" if last.acc else ", no accelerometer")
    details = [
        f"last frame: ir1={ir[0]} ir2={ir[1]}, fsr {','.join(str(v) for v in last.fsr or ())}"
        + (f", acc {','.join(str(v) for v in last.acc)}" if last.acc else ""),
    ]
    if len(frames) < 2:
        return fail(
            NAME,
            f"{path} stopped sending after rate={asked}#: {len(frames)} frames in {MEASURE_S:g} s",
            f"{FLASH} (rate=N# takes 10 … 50)",
            tuple(details),
        )
    (t0, f0), (t1, f1) = frames[0], frames[-1]
    lost = sum(f.missed for _, f in frames[1:])
    rate = (len(frames) - 1 + lost) / (t1 - t0) if t1 > t0 else float("inf")
    details.append(
        f"{len(frames)} frames in {t1 - t0:.2f} s (seq {f0.seq} … {f1.seq}), {lost} lost, "
        f"{len(measured.rejected)} rejected"
    )
    summary = (
        f"{'checked' if last.checked else 'plain'} frames on {path} at {rate:.1f} Hz "
        f"(asked {asked}), {groups}"
    )
    if abs(rate - asked) > RATE_TOLERANCE * asked:
        return fail(
            NAME,
            f"{path} sends {rate:.1f} frames/s after rate={asked}#: a firmware without the "
            "rate command, or a busy board",
            FLASH,
            tuple(details),
        )
    warnings: list[tuple[str, str]] = []
    if lost or measured.rejected:
        warnings.append(
            (
                f"{lost} frames lost and {len(measured.rejected)} rejected in {MEASURE_S:g} s",
                "a noisy or long USB cable, or a busy host: try another cable or port",
            )
        )
    for key, side, value in zip(("ir1", "ir2"), IR_SIDES, ir, strict=True):
        if value == 0:
            warnings.append(
                (
                    f"{key} (rangefinder on the {side} leg) reads 0 counts: unplugged or unpowered",
                    f"check the {side} rangefinder's cable (firmware/PROTOCOL.md: 0 is no reading)",
                )
            )
    fitted = spec.accelerometer.fitted
    if fitted and last.acc is None:
        warnings.append(
            (
                "[sensor_board.accelerometer] fitted = true, but the frames carry no acc*",
                "build the firmware with WITH_ACCEL=1, or set fitted = false",
            )
        )
    elif last.acc is not None and not fitted:
        warnings.append(
            (
                "the frames carry acc*, but [sensor_board.accelerometer] fitted = false: "
                "the reader makes no tilt of them",
                "set [sensor_board.accelerometer] fitted = true if one is fitted",
            )
        )
    if warnings:
        said = "; ".join(w for w, _ in warnings)
        return warn(NAME, f"{summary}; {said}", "; ".join(f for _, f in warnings), tuple(details))
    return CheckResult(NAME, Status.OK, summary, None, tuple(details))


__all__ = ["FIRST_FRAME_S", "MEASURE_S", "NAME", "RATE_TOLERANCE", "check_sensor_board", "listen"]
