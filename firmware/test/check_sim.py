#!/usr/bin/env python3
"""Runs the real firmware ELF in the simavr harness and checks its frames.

Standard library only. Checks, against PROTOCOL.md: every byte belongs to a
well-formed frame, seq counts from 0 by one, the CRC is right, constant inputs
read exactly their ADC value, the trimmed-mean step response, a one-sample spike
never shows, the frame rate in simulated time, `rate=N#` (and garbage that must
be ignored), the layouts with and without the accelerometer (WITH_ACCEL), the
serial rate the firmware programs (BAUD), the pty link in real time, and a
clean exit on SIGTERM.
"""

import argparse
import binascii
import os
import re
import select
import signal
import subprocess
import sys
import tempfile
import termios
import time
import tty

SAMPLE_MS = 20  # board_config.h: SAMPLE_RATE_HZ 50
ACCEL_KEYS = ["accx", "accy", "accz"]
FSR_KEYS = [f"fsr{i}" for i in range(6)]
FRAME_RE = re.compile(rb"seq=(\d{1,5});((?:[a-z][a-z0-9]*=-?\d{1,5};)+)crc=([0-9A-F]{4})")

Frame = tuple[int, dict[str, int]]  # (seq, {key: value})

failures: list[str] = []


def check(cond: bool, msg: str) -> bool:
    if not cond:
        failures.append(msg)
        print("FAIL: " + msg, file=sys.stderr)
    return cond


def adc_counts(mv: int) -> int:
    """simavr 1.6's ADC: floor(mV * 1023 / Vref) clipped to 1023, Vref = AVCC = 5000 mV."""
    return min(1023, mv * 1023 // 5000)


def parse_frames(data: bytes, what: str) -> list[Frame]:
    """Splits the byte stream into frames; every byte must belong to a valid frame."""
    chunks = data.split(b"#")
    tail = chunks.pop()  # bytes after the last '#': a frame cut off by the end of the run
    check(
        tail == b"" or tail.startswith(b"seq=") or b"seq=".startswith(tail),
        f"{what}: unexpected trailing bytes {tail[:40]!r}",
    )
    frames: list[Frame] = []
    for raw in chunks:
        m = FRAME_RE.fullmatch(raw)
        if not check(m is not None, f"{what}: malformed frame {raw[:80]!r}"):
            continue
        body = raw[: raw.rindex(b"crc=")]
        crc = int(m.group(3), 16)
        check(binascii.crc_hqx(body, 0xFFFF) == crc, f"{what}: bad CRC in {raw!r}")
        fields: dict[str, int] = {}
        for item in m.group(2).decode().rstrip(";").split(";"):
            key, value = item.split("=")
            check(key not in fields, f"{what}: repeated key {key}")
            fields[key] = int(value)
        frames.append((int(m.group(1)), fields))
    return frames


def check_seq(frames: list[Frame], what: str) -> None:
    for i, (seq, _) in enumerate(frames):
        if not check(seq == i % 65536, f"{what}: frame {i} has seq={seq}"):
            break


def run_sim(
    args: argparse.Namespace,
    mv: dict[str, int],
    script_lines: list[str] | None = None,
    duration_ms: int = 2000,
    elf: str | None = None,
) -> tuple[bytes, float]:
    cmd = [
        args.sim,
        "--elf",
        elf or args.elf,
        "--stdout",
        "--quiet",
        "--duration-ms",
        str(duration_ms),
    ]
    for ch, v in mv.items():
        cmd += ["--mv", f"{ch}={v}"]
    with tempfile.NamedTemporaryFile("w", suffix=".script", delete=False) as f:
        f.write("\n".join(script_lines or []) + "\n")
        script = f.name
    try:
        cmd += ["--script", script]
        t0 = time.monotonic()
        proc = subprocess.run(cmd, capture_output=True, timeout=60)
        wall = time.monotonic() - t0
    finally:
        os.unlink(script)
    check(
        proc.returncode == 0,
        f"{cmd} exited with {proc.returncode}: {proc.stderr.decode()[-500:]}",
    )
    check(proc.stderr == b"", f"--quiet still wrote to stderr: {proc.stderr[:200]!r}")
    return proc.stdout, wall


def frame_times(
    period_ms: float, change_at_ms: float | None, new_period_ms: float | None, end_ms: int
) -> list[float]:
    """Frame times in ms: the first one period after start-up. A rate change
    applies after the frame already scheduled (PROTOCOL.md, Host to board)."""
    times, t = [], period_ms
    if change_at_ms is not None:
        while t <= change_at_ms:
            times.append(t)
            t += period_ms
        period_ms = new_period_ms
    while t < end_ms + 100:
        times.append(t)
        t += period_ms
    return times


def check_count(frames: list[Frame], times: list[float], end_ms: int, what: str) -> None:
    # The firmware starts a few µs after reset and wakes within ~1 ms of a
    # deadline; a ~90-byte frame then takes ~1 ms on the wire at 1 Mbps.
    sure = sum(1 for t in times if t < end_ms - 3)
    maybe = sum(1 for t in times if end_ms - 3 <= t < end_ms)
    check(
        sure <= len(frames) <= sure + maybe,
        f"{what}: {len(frames)} frames in {end_ms} ms of simulated time, expected {sure}"
        + (f" or {sure + maybe}" if maybe else ""),
    )


def test_main(args: argparse.Namespace) -> None:
    accel = args.accel == 1
    period = 1000.0 / args.rate
    mv = {
        "ir1": 1200,
        "ir2": 700,
        "fsr0": 2500,
        "fsr1": 0,
        "fsr2": 5000,
        "fsr3": 1,
        "fsr4": 4999,
        "fsr5": 3333,
        "accx": 1650,
        "accy": 1700,
        "accz": 2400,
    }
    step_to = 3000  # ir2 steps 700 -> 3000 mV between two samples
    step_at = 510
    spike = (710, 725)  # fsr0 at 5000 mV for exactly one sample (the one at ~720 ms)
    change_at = 1010  # rate=50#, split across two sends, after ignored garbage
    end = 2000
    script = [
        "# ir2 step between the samples at 500 and 520 ms",
        f"{step_at} ir2 {step_to}",
        f"{spike[0]} fsr0 5000",
        f"{spike[1]} fsr0 {mv['fsr0']}",
        "# all ignored: out of range, malformed, garbage",
        "600 send xx#rate=9#rate=51#rate=5O#rate=20\\x01#\\xff\\xfe#rate=",
        "650 send 30 oops#",
        "1005 send #\\r\\nra",
        f"{change_at} send te=50#\\r\\n",
    ]
    data, wall = run_sim(args, mv, script, end)
    what = f"main run ({args.rate} Hz, WITH_ACCEL={args.accel})"
    frames = parse_frames(data, what)
    check_seq(frames, what)

    keys = ["ir1", "ir2"] + (ACCEL_KEYS if accel else []) + FSR_KEYS
    for seq, fields in frames:
        if not check(
            list(fields) == keys,
            f"{what}: seq {seq} has keys {list(fields)}, expected {keys}",
        ):
            break
    # Constant inputs read exactly their ADC value in every frame (the spike never shows).
    for key in keys:
        if key == "ir2":
            continue
        want = adc_counts(mv[key])
        bad = [(seq, f[key]) for seq, f in frames if f[key] != want]
        check(
            not bad,
            f"{what}: {key} should always read {want} ({mv[key]} mV), got (seq, value) {bad[:5]}",
        )
    # ir2 step response: a, a, round((2a+b)/3), round((a+2b)/3), b by new samples.
    a, b = adc_counts(mv["ir2"]), adc_counts(step_to)
    expect_by_new = {0: a, 1: a, 2: (2 * a + b + 1) // 3, 3: (a + 2 * b + 1) // 3}
    seen = set()
    for seq, fields in frames:
        t = (seq + 1) * period
        if t > change_at:
            break
        new = max(0, int(t // SAMPLE_MS) - step_at // SAMPLE_MS)  # samples at 520, 540, ... ms
        want = expect_by_new.get(new, b)
        seen.add(min(new, 4))
        check(
            fields["ir2"] == want,
            f"{what}: ir2 at seq {seq} ({t:.0f} ms, {new} new samples) = {fields['ir2']}, "
            f"expected {want}",
        )
    check(len(seen) >= 3, f"{what}: step response not covered ({sorted(seen)})")

    times = frame_times(period, change_at + 1, 1000.0 / 50, end)
    check_count(frames, times, end, what)
    sim_s = end / 1000.0
    print(f"  {what}: {len(frames)} frames, {len(data)} bytes, {sim_s / wall:.0f}x real time")


def test_variant(args: argparse.Namespace) -> None:
    """The WITH_ACCEL=1 layout, built at 50 Hz and 2 Mbps (Makefile target accel)."""
    mv = {
        "ir1": 100,
        "ir2": 200,
        "fsr0": 300,
        "fsr1": 400,
        "fsr2": 500,
        "fsr3": 600,
        "fsr4": 700,
        "fsr5": 800,
        "accx": 2000,
        "accy": 1650,
        "accz": 1980,
    }
    end = 510
    data, _ = run_sim(args, mv, [], end, elf=args.accel_elf)
    what = "WITH_ACCEL=1, 50 Hz run"
    frames = parse_frames(data, what)
    check_seq(frames, what)
    keys = ["ir1", "ir2", *ACCEL_KEYS, *FSR_KEYS]
    for seq, fields in frames:
        check(list(fields) == keys, f"{what}: seq {seq} keys {list(fields)}")
        check(
            all(fields[k] == adc_counts(mv[k]) for k in keys),
            f"{what}: seq {seq} values {fields}",
        )
    check_count(frames, frame_times(20.0, None, None, end), end, what)
    print(f"  {what}: {len(frames)} frames")


def uart_bps(elf: str, args: argparse.Namespace) -> int | None:
    """The rate the firmware programmed into USART0, from the harness's summary."""
    proc = subprocess.run(
        [args.sim, "--elf", elf, "--stdout", "--duration-ms", "50"],
        capture_output=True,
        timeout=60,
    )
    m = re.search(rb"uart0: (\d+) bps", proc.stderr)
    return int(m.group(1)) if m else None


def test_baud(args: argparse.Namespace) -> None:
    """BAUD reaches the USART exactly as Serial.begin() sets it (serial_baud.h)."""
    for elf, want in ((args.elf, args.baud), (args.accel_elf, 2_000_000)):
        got = uart_bps(elf, args)
        check(got == want, f"baud: {elf} programs {got} bps, expected {want}")
    print(f"  baud: {args.baud} bps (main build), 2000000 bps (variant)")


def test_pty(args: argparse.Namespace) -> None:
    """--pty --realtime: read the pty in raw mode, send rate=50# through it."""
    duration = 1500
    proc = subprocess.Popen(
        [
            args.sim,
            "--elf",
            args.elf,
            "--pty",
            "--realtime",
            "--quiet",
            "--duration-ms",
            str(duration),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    what = "pty run"
    data = b""
    t0 = time.monotonic()
    try:
        line = proc.stdout.readline().decode()
        if not check(line.startswith("pty: /dev/"), f"{what}: first line {line!r}"):
            return
        fd = os.open(line.split(":", 1)[1].strip(), os.O_RDWR | os.O_NOCTTY)
        tty.setraw(fd)
        termios.tcflush(fd, termios.TCIFLUSH)
        os.write(fd, b"rate=50#")
        sent = time.monotonic() - t0
        while time.monotonic() - t0 < 10:
            r, _, _ = select.select([fd], [], [], 0.2)
            if r:
                try:
                    chunk = os.read(fd, 4096)
                except OSError:  # EIO: the harness closed the master
                    break
                if not chunk:
                    break
                data += chunk
            elif proc.poll() is not None:
                break
        os.close(fd)
    finally:
        proc.wait(timeout=10)
    wall = time.monotonic() - t0
    check(proc.returncode == 0, f"{what}: exit status {proc.returncode}")
    check(
        wall >= duration / 1000.0 * 0.95,
        f"{what}: --realtime ran {duration} ms in {wall:.2f} s",
    )
    # The flush may cut into a frame; resynchronise at the first "seq=".
    start = data.find(b"seq=")
    frames = parse_frames(data[start:], what) if start >= 0 else []
    seqs = [s for s, _ in frames]
    check(
        seqs == list(range(seqs[0], seqs[0] + len(seqs))) if seqs else False,
        f"{what}: seq not consecutive: {seqs[:10]}",
    )
    # 20 Hz would give <= 30 frames in 1.5 s; 50 Hz after the command ~ 70.
    check(
        len(frames) >= 1.5 * 50 * 0.75,
        f"{what}: {len(frames)} frames after rate=50# sent at {sent:.2f} s",
    )
    print(f"  {what}: {len(frames)} frames in {wall:.2f} s wall, rate=50# sent after {sent:.2f} s")


def test_sigterm(args: argparse.Namespace) -> None:
    proc = subprocess.Popen(
        [args.sim, "--elf", args.elf, "--stdout", "--realtime"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    time.sleep(0.4)
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=10)
    what = "SIGTERM run"
    check(proc.returncode == 0, f"{what}: exit status {proc.returncode}")
    check(b"frames" in err, f"{what}: no summary on stderr: {err[-300:]!r}")
    frames = parse_frames(out, what)
    check(len(frames) >= 4, f"{what}: only {len(frames)} frames in 0.4 s")
    print(f"  {what}: {len(frames)} frames, clean exit")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sim", required=True)
    ap.add_argument("--elf", required=True)
    ap.add_argument(
        "--accel-elf",
        required=True,
        help="built with WITH_ACCEL=1 FRAME_RATE_HZ=50 BAUD=2000000 (the other layout)",
    )
    ap.add_argument("--rate", type=int, default=20, help="FRAME_RATE_HZ of --elf")
    ap.add_argument("--accel", type=int, default=0, help="WITH_ACCEL of --elf")
    ap.add_argument("--baud", type=int, default=1_000_000, help="BAUD of --elf")
    args = ap.parse_args()
    print("simulation tests:")
    test_main(args)
    test_variant(args)
    test_baud(args)
    test_pty(args)
    test_sigterm(args)
    if failures:
        print(f"simulation tests: {len(failures)} FAILED", file=sys.stderr)
        return 1
    print("simulation tests: passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
