"""End to end: the real firmware image on a simulated ATmega2560, read by the real reader.

``make -C firmware all sim accel`` builds the sketch for the Mega 2560 with avr-gcc
(the default build, and ``build/accel/``: ``WITH_ACCEL=1`` at 50 Hz and 2 Mbps) and the
simavr harness (``firmware/sim/whexar_sim.c``); the harness runs the very ELF a user
flashes, injects analog voltages from a script and hands the UART bytes over (stdout,
or a pseudo-terminal). The tests check the frames against the injected voltages,
within simavr's ADC quantisation and the filter of ``firmware/PROTOCOL.md``, and then
read them through pyserial-asyncio with the real :class:`SensorReader` and ``whexar
sensors``.
"""

from __future__ import annotations

import json
import math
import selectors
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from whexar.actors.messages import (
    AccelImplausible,
    BodyTilt,
    LegLoads,
    ObstacleRanges,
    SensorFrame,
    SensorFrameGap,
    SensorFrameRejected,
)
from whexar.config import RobotConfig, parse_config
from whexar.doctor import Environment, Findings, Status
from whexar.doctor.board import check_sensor_board
from whexar.kinematics.sensing import ir_distance, tilt_from_acceleration
from whexar.sensors.board_emulator import SensorBoardEmulator
from whexar.sensors.frame import Frame, FrameDecoder, Rejected
from whexar.testing import run_actors
from whexar.testing.sensors import sensor_graph

# Builds the firmware and runs it in simavr: seconds per test. One at a time: the build is
# not run twice at once, and the harness on a pty runs in real time.
pytestmark = [pytest.mark.slow, pytest.mark.serial]

ROOT = Path(__file__).resolve().parents[2]
FIRMWARE = ROOT / "firmware"
SIM = FIRMWARE / "build" / "whexar-sim"
ACCEL_ELF = FIRMWARE / "build" / "accel" / "whexar_sensors.elf"
CFG = RobotConfig()
VREF_MV = 5000

VOLTAGES = {
    "ir1": 1500,  # about 0.28 m by eq. 5.5
    "ir2": 250,  # 51 counts: nothing within 150 cm
    # Pitched 30° on the ADXL335 calibration: 1.65 V at 0 g, 330 mV/g.
    "accx": 1650,
    "accy": 1815,
    "accz": 1936,
    "fsr0": 0,
    "fsr1": 400,
    "fsr2": 980,  # 200 counts: exactly contact_on_counts
    "fsr3": 2500,
    "fsr4": 4990,
    "fsr5": 5000,
}


def simavr_counts(millivolts: int) -> int:
    """simavr 1.6's ADC result: ⌊mV·1023/Vref⌋ (the chip's datasheet has 1024; ≤ 1 count)."""
    return min(1023, millivolts * 1023 // VREF_MV)


EXPECTED = {key: simavr_counts(mv) for key, mv in VOLTAGES.items()}


@pytest.fixture(scope="module")
def firmware() -> Path:
    """Build the firmware, its accelerometer variant and the harness (no-ops when up to date)."""
    done = subprocess.run(
        ["make", "-C", str(FIRMWARE), "all", "sim", "accel"],
        capture_output=True,
        text=True,
        check=False,
    )
    if done.returncode != 0:
        pytest.fail(f"make -C firmware all sim accel failed:\n{done.stdout}\n{done.stderr}")
    assert SIM.exists()
    assert ACCEL_ELF.exists()
    return SIM


def mv_args(voltages: dict[str, int]) -> list[str]:
    return [arg for key, mv in voltages.items() for arg in ("--mv", f"{key}={mv}")]


def simulate(*args: str, timeout: float = 60.0) -> bytes:
    done = subprocess.run(
        [str(SIM), "--stdout", "--quiet", *args], capture_output=True, timeout=timeout, check=True
    )
    return done.stdout


def decode(data: bytes) -> list[Frame]:
    items = FrameDecoder().feed(data)
    bad = [i for i in items if isinstance(i, Rejected)]
    assert not bad, bad
    return [i for i in items if isinstance(i, Frame)]


def test_firmware_frames_carry_exactly_the_injected_voltages(firmware: Path) -> None:
    frames = decode(simulate(*mv_args(VOLTAGES), "--duration-ms", "2010"))
    # 20 Hz from one period after reset: 0.05 … 2.0 s.
    assert len(frames) == 40
    assert [f.seq for f in frames] == list(range(40))
    assert all(f.checked for f in frames)
    for f in frames:
        assert f.ir == (EXPECTED["ir1"], EXPECTED["ir2"])
        assert f.acc is None  # the default build has no accelerometer (WITH_ACCEL=0)
        assert f.fsr == tuple(EXPECTED[f"fsr{i}"] for i in range(6))


def test_accelerometer_build_carries_its_channels(firmware: Path) -> None:
    data = simulate("--elf", str(ACCEL_ELF), *mv_args(VOLTAGES), "--duration-ms", "1010")
    frames = decode(data)
    assert len(frames) == 50  # 50 Hz: 0.02 … 1.0 s
    for f in frames:
        assert f.acc == (EXPECTED["accx"], EXPECTED["accy"], EXPECTED["accz"])
        assert f.ir == (EXPECTED["ir1"], EXPECTED["ir2"])


def test_default_build_agrees_with_the_default_configuration() -> None:
    # One statement of "is there an analog accelerometer, at what rates":
    # the firmware's build defaults and RobotConfig() must say the same.
    makefile = (FIRMWARE / "Makefile").read_text()
    header = (FIRMWARE / "whexar_sensors" / "board_config.h").read_text()

    def make_default(name: str) -> int:
        (line,) = [ln for ln in makefile.splitlines() if ln.split("?=")[0].strip() == name]
        return int(line.split("?=")[1].split("#")[0])

    def header_default(name: str) -> int:
        (line,) = [ln for ln in header.splitlines() if ln.startswith(f"#define {name} ")]
        return int(line.split()[2].rstrip("UL"))

    board = CFG.sensor_board
    emulator = SensorBoardEmulator()  # the firmware's arithmetic in Python, default build
    fitted = board.accelerometer.fitted
    assert make_default("WITH_ACCEL") == header_default("WITH_ACCEL") == fitted
    assert emulator.accelerometer == fitted
    assert make_default("BAUD") == header_default("SERIAL_BAUD") == board.baudrate
    assert emulator.baudrate == board.baudrate
    assert make_default("FRAME_RATE_HZ") == header_default("FRAME_RATE_HZ") == board.frame_rate_hz
    assert emulator.frame_rate_hz == board.frame_rate_hz


def test_firmware_filter_follows_a_step_as_documented(firmware: Path, tmp_path: Path) -> None:
    # fsr3 steps from 1000 mV to 4000 mV between the samples at 1000 and 1020 ms
    # (samples every 20 ms from reset); a one-sample spike on ir1 at 1510 ms.
    script = tmp_path / "step.txt"
    script.write_text("0 fsr3 1000\n1010 fsr3 4000\n1505 ir1 4500\n1515 ir1 1500\n")
    frames = decode(simulate("--mv", "ir1=1500", "--script", str(script), "--duration-ms", "2000"))
    a, b = simavr_counts(1000), simavr_counts(4000)
    allowed = {a, (2 * a + b + 1) // 3, (a + 2 * b + 1) // 3, b}
    fsr3: dict[float, int] = {}
    ir1: set[int] = set()
    for f in frames:
        assert f.seq is not None
        assert f.fsr is not None
        assert f.ir is not None
        fsr3[round(0.05 * (f.seq + 1), 2)] = f.fsr[3]
        ir1.add(f.ir[0])
    assert fsr3[1.0] == a  # nothing new yet
    assert fsr3[1.05] == (2 * a + b + 1) // 3  # 2 of 5 samples new (1020, 1040)
    assert fsr3[1.1] == b  # 4 or 5 new samples: the step is fully seen
    assert set(fsr3.values()) <= allowed  # never anything else, never overshoot
    # The trimmed mean never lets one outlier through.
    assert ir1 == {simavr_counts(1500)}


def test_firmware_obeys_the_rate_command(firmware: Path, tmp_path: Path) -> None:
    script = tmp_path / "rate.txt"
    script.write_text("500 send rate=50#\n")
    frames = decode(simulate("--script", str(script), "--duration-ms", "1500"))
    # 0.05 … 0.5 s at 20 Hz (10 frames), then 50 Hz up to 1.5 s (about 50 more).
    assert [f.seq for f in frames] == list(range(len(frames)))
    assert 58 <= len(frames) <= 61


@contextmanager
def sim_on_pty(sim: Path, voltages: dict[str, int], *args: str) -> Iterator[str]:
    """The firmware on a pty in real time; yields the pty's path."""
    proc = subprocess.Popen(
        [str(sim), "--pty", "--realtime", "--quiet", *mv_args(voltages), *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        with selectors.DefaultSelector() as sel:
            sel.register(proc.stdout, selectors.EVENT_READ)
            if not sel.select(10.0):
                pytest.fail("whexar-sim printed no pty within 10 s")
        line = proc.stdout.readline()
        assert line.startswith("pty: "), line
        yield line.split(":", 1)[1].strip()
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


@pytest.fixture
def pty_sim(firmware: Path) -> Iterator[str]:
    """The default firmware on a pty in real time; yields the pty's path."""
    with sim_on_pty(firmware, VOLTAGES) as path:
        yield path


def test_reader_publishes_what_the_firmware_measured(pty_sim: str, tmp_path: Path) -> None:
    config = tmp_path / "robot.toml"
    config.write_text("[sensor_board]\nframe_rate_hz = 50.0\n")
    result = run_actors(sensor_graph(pty_sim, {"config": str(config)}), duration=1.5, virtual=False)
    frames = result.messages("frames", of=SensorFrame)
    assert len(frames) >= 20
    assert not result.events(of=SensorFrameRejected)
    assert not result.events(of=SensorFrameGap)
    seqs = [f.seq for f in frames]
    first = seqs[0]
    assert first is not None
    assert seqs == list(range(first, first + len(seqs)))
    # The reader asked for 50 Hz after the first frame; the firmware obeyed.
    late = [f.t for f in frames if f.t > frames[0].t + 0.3]
    rate = (len(late) - 1) / (late[-1] - late[0])
    assert 40 <= rate <= 60
    ranges = result.messages("ranges", of=ObstacleRanges)[-1]
    ir1, ir2 = EXPECTED["ir1"], EXPECTED["ir2"]
    assert ranges.counts == (ir1, ir2)
    assert ranges.distances_m[0] == pytest.approx(ir_distance(ir1), rel=1e-12)
    assert ranges.distances_m[1] == math.inf
    loads = result.messages("loads", of=LegLoads)[-1]
    assert loads.counts == tuple(EXPECTED[f"fsr{i}"] for i in range(6))
    on = CFG.fsr.contact_on_counts
    assert loads.contacts == tuple(c >= on for c in loads.counts)
    assert not result.messages("tilt")  # no accelerometer on the default board
    assert all(f.acc_counts is None and f.roll_rad is None for f in frames)


def test_reader_tilt_and_a_missing_rangefinder_on_the_accelerometer_build(
    firmware: Path, tmp_path: Path
) -> None:
    config = tmp_path / "robot.toml"
    config.write_text(
        "[sensor_board]\nbaudrate = 2000000\n[sensor_board.accelerometer]\nfitted = true\n"
    )
    voltages = {**VOLTAGES, "ir2": 0}  # the left rangefinder unplugged: 0 V
    with sim_on_pty(firmware, voltages, "--elf", str(ACCEL_ELF)) as path:
        result = run_actors(
            sensor_graph(path, {"config": str(config)}), duration=1.0, virtual=False
        )
    assert not result.events(of=SensorFrameRejected)
    assert not result.events(of=AccelImplausible)
    ranges = result.messages("ranges", of=ObstacleRanges)[-1]
    assert ranges.counts == (EXPECTED["ir1"], 0)
    assert ranges.distances_m[0] == pytest.approx(ir_distance(EXPECTED["ir1"]), rel=1e-12)
    assert ranges.distances_m[1] is None  # no reading: not free space
    tilt = result.messages("tilt", of=BodyTilt)[-1]
    acc = CFG.sensor_board.accelerometer
    accel = [
        (EXPECTED[k] - zero) / per
        for k, zero, per in zip(
            ("accx", "accy", "accz"), acc.zero_g_counts, acc.counts_per_g, strict=True
        )
    ]
    roll, pitch = tilt_from_acceleration(*accel)
    assert tilt.roll_rad == pytest.approx(roll, rel=1e-12)
    assert tilt.pitch_rad == pytest.approx(pitch, rel=1e-12)
    assert math.degrees(tilt.pitch_rad) == pytest.approx(30.0, abs=1.0)


def test_monitor_prints_the_firmwares_frames(pty_sim: str) -> None:
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "whexar.cli",
            "sensors",
            "--port",
            pty_sim,
            "--json",
            "--duration",
            "0.6",
        ],
        capture_output=True,
        text=True,
        timeout=30,
        cwd=ROOT,
        check=True,
    )
    records = [json.loads(line) for line in done.stdout.splitlines()]
    frames = [r for r in records if r["kind"] == "frame"]
    assert len(frames) >= 8
    raw = {k: v for k, v in EXPECTED.items() if not k.startswith("acc")}
    assert frames[-1]["raw"] == raw
    assert frames[-1]["loads"] == [EXPECTED[f"fsr{i}"] for i in range(6)]
    assert frames[-1]["ir_status"] == ["range", "clear"]
    assert frames[-1]["ir_distance_m"][1] is None
    assert frames[-1]["roll_deg"] is None
    assert {r["event"] for r in records if r["kind"] == "event"} == {"SensorLinkUp"}


def test_doctor_finds_the_firmware_ready_at_the_rate_it_asks(pty_sim: str) -> None:
    # The doctor's check on the very firmware a user flashes: checked frames, every
    # group, and rate=50# obeyed (the build's default is 20 Hz).
    env = Environment(
        config=parse_config({"sensor_board": {"frame_rate_hz": 50}}), board_port=pty_sim
    )
    found = Findings()
    try:
        got = check_sensor_board(env, found)
    finally:
        for close in found.closers:
            close()
    assert got.status is Status.OK, got
    assert got.summary.startswith(f"checked frames on {pty_sim} at ")
    assert "(asked 50), IR and force sensors, no accelerometer" in got.summary
    fsr = ",".join(str(EXPECTED[f"fsr{i}"]) for i in range(6))
    assert got.details[0] == f"last frame: ir1={EXPECTED['ir1']} ir2={EXPECTED['ir2']}, fsr {fsr}"
