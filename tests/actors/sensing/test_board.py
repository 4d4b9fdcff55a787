"""The sensor reader actor on virtual time, against the in-process sensor board.

Each test registers a :class:`SensorBoardEmulator` (the firmware's arithmetic, frame for
frame, each frame arriving when its last byte would) and runs the real
:class:`~whexar.actors.sensing.SensorReader`, then checks what it published and reported.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from pathlib import Path

import pytest

from whexar.actors.messages import (
    AccelImplausible,
    AccelPlausible,
    BodyTilt,
    LegLoads,
    ObstacleRanges,
    SensorFrame,
    SensorFrameGap,
    SensorFrameRejected,
    SensorLinkDown,
    SensorLinkFresh,
    SensorLinkStale,
    SensorLinkUp,
    SensorStats,
)
from whexar.cli import main
from whexar.config import RobotConfig
from whexar.kinematics.sensing import ir_distance, tilt_from_acceleration
from whexar.runtime.devices import DEVICES
from whexar.runtime.messages import ActorFailed
from whexar.sensors.board_emulator import (
    SENSOR_BOARD,
    SensorBoardEmulator,
    counts_for_acceleration,
    counts_for_distance,
)
from whexar.sensors.frame import encode_frame
from whexar.testing import Harness, RunResult, run_actors
from whexar.testing.sensors import sensor_graph

CFG = RobotConfig()
PERIOD = 1.0 / CFG.sensor_board.frame_rate_hz
WIRE_S_PER_BYTE = 10 / 1_000_000


@pytest.fixture(autouse=True)
def _clean_registry() -> Iterator[None]:
    yield
    DEVICES.clear(SENSOR_BOARD)


def board(name: str = "b", **kw: object) -> SensorBoardEmulator:
    emulator = SensorBoardEmulator(**kw)  # type: ignore[arg-type]
    DEVICES.register(SENSOR_BOARD, name, emulator)
    return emulator


def run(duration: float | None = None, scenario: object = None, **params: object) -> RunResult:
    return run_actors(
        sensor_graph("emulator:b", params),
        duration=duration,
        scenario=scenario,  # type: ignore[arg-type]
    )


def robot_file(tmp_path: Path, text: str) -> str:
    """A robot configuration file with only the keys ``text`` changes."""
    path = tmp_path / "robot.toml"
    path.write_text(text)
    return str(path)


FITTED = "[sensor_board.accelerometer]\nfitted = true\n"


def test_frames_arrive_at_the_frame_rate_with_consecutive_seq() -> None:
    board()
    result = run(duration=2.0)
    frames = result.messages("frames", of=SensorFrame)
    assert [f.seq for f in frames] == list(range(len(frames)))
    assert len(frames) == 39  # frames at 0.05 … 1.95 s: the one due at 2.0 s lands after
    # Stamped when the last byte arrived: the frame time plus its wire time.
    first = frames[0]
    size = len(encode_frame(seq=0, ir=first.ir_counts, acc=first.acc_counts, fsr=first.fsr_counts))
    assert first.t == pytest.approx(PERIOD + size * WIRE_S_PER_BYTE, abs=1e-9)
    gaps = [b.t - a.t for a, b in itertools.pairwise(frames)]
    assert max(gaps) == pytest.approx(PERIOD, abs=1e-4)
    assert result.events(of=SensorLinkUp)
    assert not result.events(of=SensorFrameRejected)
    assert not result.events(of=SensorLinkStale)


def test_ir_distances_follow_eq_5_5_and_the_range_limits() -> None:
    near = counts_for_distance(0.40, CFG.ir.k_cm, CFG.ir.exponent)
    board(counts={"ir1": near, "ir2": 1000})  # 1000 counts: nearer than 10 cm
    result = run(duration=0.5)
    last = result.messages("ranges", of=ObstacleRanges)[-1]
    assert last.counts == (near, 1000)
    assert last.distances_m[0] == pytest.approx(ir_distance(near), rel=1e-12)
    assert last.distances_m[0] == pytest.approx(0.40, abs=0.005)  # one count's quantisation
    assert last.distances_m[1] == CFG.ir.min_distance_mm / 1000

    DEVICES.clear(SENSOR_BOARD)
    board(counts={"ir1": 60, "ir2": 1})  # beyond 150 cm, both
    far = run(duration=0.5).messages("ranges", of=ObstacleRanges)[-1]
    assert far.distances_m == (math.inf, math.inf)


def test_an_unplugged_rangefinder_is_no_reading_not_free_space() -> None:
    # The left sensor is unplugged at 0.5 s (its input falls to 0 V) and back at 1.0 s.
    def script(t: float) -> dict[str, int]:
        return {"ir2": 0 if 0.5 <= t < 1.0 else 300}

    board(counts={"ir1": 60}, script=script)
    result = run(duration=1.5)
    ranges = result.messages("ranges", of=ObstacleRanges)
    frames = result.messages("frames", of=SensorFrame)
    unplugged = [r for r in ranges if r.counts[1] == 0]
    assert len(unplugged) >= 8  # the filter takes 80 ms to reach 0
    for r in unplugged:
        assert r.distances_m == (math.inf, None)  # the right one sees nothing: clear
    for r in ranges:
        if r.counts[1] > 0:  # on the way down and up, the filter passes far readings: inf
            assert r.distances_m[1] is not None
    assert {f.ir_distances_m for f in frames if f.ir_counts == (60, 0)} == {(math.inf, None)}
    assert ranges[-1].distances_m[1] == pytest.approx(ir_distance(300))


def test_contact_flags_have_hysteresis() -> None:
    on, off = CFG.fsr.contact_on_counts, CFG.fsr.contact_off_counts
    mid = (on + off) // 2
    # Leg 2's load rises through both thresholds, then falls through them,
    # each level held 0.5 s; the flag expected at the end of each level:
    ramp = [(0, False), (off, False), (mid, False), (on, True), (mid, True), (off, True)]
    ramp += [(off - 1, False), (0, False)]

    def script(t: float) -> dict[str, int]:
        return {"fsr2": ramp[min(int(t / 0.5), len(ramp) - 1)][0]}

    board(script=script)
    loads = run(duration=4.1).messages("loads", of=LegLoads)
    for i, (counts, flag) in enumerate(ramp):
        (at_end,) = [m for m in loads if abs(m.t - 0.5 * (i + 1)) < 0.01]
        assert at_end.counts[2] == counts
        assert at_end.contacts[2] is flag, (i, counts)
    # Every message obeys the rule on the counts it carries.
    state = False
    for msg in loads:
        c = msg.counts[2]
        state = True if c >= on else False if c < off else state
        assert msg.contacts == (False, False, state, False, False, False)


def test_tilt_from_the_board_accelerometer(tmp_path: Path) -> None:
    acc = CFG.sensor_board.accelerometer
    gravity = (math.sin(0.2), math.sin(-0.1), math.cos(0.2) * math.cos(0.1))
    counts = counts_for_acceleration(gravity, acc.zero_g_counts, acc.counts_per_g)
    board(accelerometer=True, counts=dict(zip(("accx", "accy", "accz"), counts, strict=True)))
    result = run(duration=0.5, config=robot_file(tmp_path, FITTED))
    assert not result.events(of=AccelImplausible)
    tilt = result.messages("tilt", of=BodyTilt)[-1]
    assert tilt.sensor == "board"
    want = tilt_from_acceleration(*gravity)
    # One ADC count is 1/67.5 g: about 0.015 rad at worst near level.
    assert tilt.roll_rad == pytest.approx(want[0], abs=0.02)
    assert tilt.pitch_rad == pytest.approx(want[1], abs=0.02)
    assert tilt.roll_rad == pytest.approx(math.atan2(*tilt.accel_g[::2]))


def test_board_without_accelerometer_publishes_no_tilt() -> None:
    board()  # like the firmware's default build: no acc fields
    result = run(duration=0.5)
    assert result.messages("frames", of=SensorFrame)[-1].acc_counts is None
    assert result.messages("tilt") == []


def test_accelerometer_counts_make_no_tilt_unless_one_is_fitted() -> None:
    # A WITH_ACCEL=1 build on a board without the sensor: its open inputs at 0 V
    # once gave -135° of roll and pitch. The default configuration says none is fitted.
    assert CFG.sensor_board.accelerometer.fitted is False
    board(accelerometer=True, counts={"accx": 0, "accy": 0, "accz": 0})
    result = run(duration=0.5)
    frames = result.messages("frames", of=SensorFrame)
    assert frames[-1].acc_counts == (0, 0, 0)  # shown as they came…
    assert all(f.roll_rad is None and f.pitch_rad is None for f in frames)  # …but no tilt
    assert result.messages("tilt") == []
    assert not result.events(of=AccelImplausible)


def test_implausible_acceleration_gives_no_tilt_and_one_event_each_way(tmp_path: Path) -> None:
    acc = CFG.sensor_board.accelerometer
    level = counts_for_acceleration((0.0, 0.0, 1.0), acc.zero_g_counts, acc.counts_per_g)
    heavy = counts_for_acceleration((0.0, 0.0, 1.25), acc.zero_g_counts, acc.counts_per_g)
    keys = ("accx", "accy", "accz")

    # Level; at 0.5 s the sensor loses its supply (0 V on every axis, what the
    # default ADXL335 calibration turns into (-5, -5, -5) g); at 1.0 s a 1.25 g
    # bump; from 1.5 s level again.
    def script(t: float) -> dict[str, int]:
        if 0.5 <= t < 1.0:
            return dict.fromkeys(keys, 0)
        return dict(zip(keys, heavy if 1.0 <= t < 1.5 else level, strict=True))

    board(accelerometer=True, script=script)
    result = run(duration=2.0, config=robot_file(tmp_path, FITTED))
    frames = result.messages("frames", of=SensorFrame)
    tilts = result.messages("tilt", of=BodyTilt)
    (bad,) = result.events(of=AccelImplausible)
    (good,) = result.events(of=AccelPlausible)
    assert bad.sensor == "board"
    assert bad.tolerance_g == acc.gravity_tolerance_g == 0.2
    withheld = [f for f in frames if f.roll_rad is None]
    # Said at the first withheld frame once they have lasted the hold-off (0.25 s).
    hold = acc.implausible_hold_s
    said = next(f for f in withheld if f.t - withheld[0].t >= hold)
    assert (bad.seq, bad.t) == (said.seq, said.t)
    assert hold <= bad.t - withheld[0].t < hold + 0.06  # within a frame (20 Hz) of it
    assert bad.magnitude_g > 1.2
    assert good.withheld == len(withheld)
    last_withheld = withheld[-1].seq
    assert last_withheld is not None
    assert good.seq == last_withheld + 1
    assert 1.5 < good.t < 1.65  # 80 ms of filter after the bump ends
    # Never a tilt from a reading that is not gravity, and none of -135°.
    assert {t.seq for t in tilts}.isdisjoint(f.seq for f in withheld)
    for t in tilts:
        assert abs(math.hypot(*t.accel_g) - 1.0) <= 0.2
        assert abs(t.roll_rad) < 0.05
        assert abs(t.pitch_rad) < 0.05
    assert tilts[-1].t > good.t - 1e-9


def test_corrupt_frames_are_rejected_and_never_published() -> None:
    emulator = board(counts={"ir1": 300})

    async def scenario(h: Harness) -> None:
        await h.sleep(0.5)
        emulator.corrupt(5)
        await h.sleep(1.0)

    result = run(scenario=scenario)
    rejected = result.events(of=SensorFrameRejected)
    assert len(rejected) == 5
    frames = result.messages("frames", of=SensorFrame)
    seqs = [f.seq for f in frames]
    assert len(seqs) == len(set(seqs))
    assert all(f.ir_counts == (300, 80) for f in frames)  # no damaged value got through
    gaps = result.events(of=SensorFrameGap)
    assert sum(g.missed for g in gaps) == 5


def test_lost_frames_are_a_gap_and_silence_makes_the_link_stale() -> None:
    emulator = board()

    async def scenario(h: Harness) -> None:
        await h.sleep(0.52)
        emulator.drop(1)
        await h.sleep(0.5)
        emulator.silence(until_board_s=2.0)
        await h.sleep(1.5)

    result = run(scenario=scenario, stats_period_s=0.5)
    gaps = result.events(of=SensorFrameGap)
    assert next((g.missed, g.restarted) for g in gaps) == (1, False)
    (stale,) = result.events(of=SensorLinkStale)
    (fresh,) = result.events(of=SensorLinkFresh)
    stale_after = CFG.sensor_board.stale_after_frames * PERIOD
    assert stale.silent_s == pytest.approx(stale_after)
    last_before = max(f.t for f in result.messages("frames", of=SensorFrame) if f.t < stale.t)
    assert stale.t == pytest.approx(last_before + stale_after)
    assert fresh.t > stale.t
    assert fresh.t == pytest.approx(2.0, abs=2e-3)  # the first frame after the silence
    assert fresh.silent_s == pytest.approx(fresh.t - last_before)
    stats = result.messages("stats", of=SensorStats)[-1]
    assert stats.missed == sum(g.missed for g in gaps)
    assert gaps[1].missed == round((2.0 - stale.t) / PERIOD) + 2  # the silence lost them all


def test_unplugged_board_is_reconnected_and_its_reset_is_not_a_gap() -> None:
    emulator = board()

    async def scenario(h: Harness) -> None:
        await h.sleep(1.0)
        emulator.unplug()
        await h.sleep(1.2)
        emulator.replug()
        await h.sleep(1.0)

    result = run(scenario=scenario)
    (down,) = result.events(of=SensorLinkDown)
    ups = result.events(of=SensorLinkUp)
    assert len(ups) == 2
    assert down.t == pytest.approx(1.0)
    reconnect = CFG.sensor_board.reconnect_period_s
    assert 2.2 <= ups[1].t <= 2.2 + reconnect + 1e-9
    assert emulator.resets == 2
    frames = result.messages("frames", of=SensorFrame)
    after = [f.seq for f in frames if f.t > ups[1].t]
    assert after[:3] == [0, 1, 2]  # the board reset on open…
    assert not result.events(of=SensorFrameGap)  # …which is not a loss
    assert result.events(of=SensorLinkStale)  # while unplugged, readings went stale
    assert result.exit_code == 0


def test_reader_sets_the_boards_frame_rate(tmp_path: Path) -> None:
    config = tmp_path / "robot.toml"
    config.write_text("[sensor_board]\nframe_rate_hz = 50.0\n")
    emulator = board(frame_rate_hz=20.0)
    result = run(duration=1.0, config=str(config))
    assert emulator.commands == [b"rate=50#"]
    frames = result.messages("frames", of=SensorFrame)
    late = [f for f in frames if f.t > 0.2]
    gaps = {round(b.t - a.t, 4) for a, b in itertools.pairwise(late)}
    assert gaps == {0.02}


def test_garbage_on_the_line_is_reported_and_the_next_frame_decodes() -> None:
    emulator = board()

    async def scenario(h: Harness) -> None:
        await h.sleep(0.33)
        emulator.inject(b"\xfe\xff boot v1.2 ;;==")
        await h.sleep(0.5)

    result = run(scenario=scenario)
    (rejected,) = result.events(of=SensorFrameRejected)
    assert "garbage before a frame" in rejected.reason
    seqs = [f.seq for f in result.messages("frames", of=SensorFrame)]
    assert seqs == list(range(len(seqs)))  # the frame the garbage preceded survived


def test_thesis_mode_publishes_plain_frames_without_seq() -> None:
    emulator = board()
    plain = b"ir1=5;ir2=7;accx=0;accy=1;accz=2;fsr0=5;fsr1=7;fsr2=3;fsr3=2;fsr4=6;fsr5=8#"

    async def scenario(h: Harness) -> None:
        await h.sleep(0.21)
        emulator.inject(plain)
        await h.sleep(0.1)

    checked = run(scenario=scenario)
    assert checked.events(of=SensorFrameRejected)[0].reason.startswith("no checksum")
    DEVICES.clear(SENSOR_BOARD)
    emulator = board()
    thesis = run(scenario=scenario, protocol="thesis")
    frames = thesis.messages("frames", of=SensorFrame)
    (plain_frame,) = [f for f in frames if f.seq is None]
    assert plain_frame.fsr_counts == (5, 7, 3, 2, 6, 8)
    assert plain_frame.roll_rad is None  # acc counts, but no accelerometer fitted
    assert not thesis.events(of=SensorFrameRejected)


def test_thesis_mode_rejects_a_frame_with_seq_but_no_crc() -> None:
    emulator = board()

    async def scenario(h: Harness) -> None:
        await h.sleep(0.21)
        emulator.inject(b"seq=3;ir1=5;ir2=7#")  # a checked frame cut short
        await h.sleep(0.1)

    result = run(scenario=scenario, protocol="thesis")
    (rejected,) = result.events(of=SensorFrameRejected)
    assert rejected.reason == "seq but no checksum (a checked frame cut short?)"
    frames = result.messages("frames", of=SensorFrame)
    assert (5, 7) not in {f.ir_counts for f in frames}
    assert [f.seq for f in frames] == list(range(len(frames)))


def test_missing_device_is_an_event_and_the_reader_keeps_looking(tmp_path: Path) -> None:
    graph = sensor_graph(str(tmp_path / "no-such-tty"))
    # A real device path on virtual time: allowed explicitly (it never opens anyway).
    result = run_actors(graph, duration=1.2, real_io=True)
    downs = result.events(of=SensorLinkDown)
    assert len(downs) == 1  # reported once, then retried quietly
    assert "cannot open" in downs[0].reason
    assert not result.events(of=ActorFailed)
    assert not result.events(of=SensorLinkStale)  # no frame ever came: nothing to go stale


def test_no_staleness_while_a_board_boots() -> None:
    # Opening the port resets the Mega; its bootloader keeps it silent about 1 s.
    board(boot_s=1.0)
    result = run(duration=2.0)
    frames = result.messages("frames", of=SensorFrame)
    assert frames[0].seq == 0
    assert frames[0].t == pytest.approx(1.0 + PERIOD, abs=2e-3)
    assert not result.events(of=SensorLinkStale)


def test_a_reconnection_is_not_stale_before_its_first_frame(tmp_path: Path) -> None:
    # With a 2 s staleness window, the link goes down at 1.0 s and is back at
    # 1.5 s, but the board boots for 2 s: no stale report from that boot…
    emulator = board(boot_s=2.0)
    config = robot_file(tmp_path, "[sensor_board]\nstale_after_frames = 40.0\n")

    async def scenario(h: Harness) -> None:
        await h.sleep(3.0)
        emulator.unplug()
        await h.sleep(0.2)
        emulator.replug()
        await h.sleep(3.0)
        emulator.silence(until_board_s=10.0)  # …but silence after frames is stale
        await h.sleep(3.0)

    result = run(scenario=scenario, config=config)
    ups = result.events(of=SensorLinkUp)
    assert len(ups) == 2
    after = [f for f in result.messages("frames", of=SensorFrame) if f.t > ups[1].t]
    assert after[0].t == pytest.approx(ups[1].t + 2.0 + PERIOD, abs=2e-3)
    (stale,) = result.events(of=SensorLinkStale)
    assert stale.t > after[-1].t
    assert stale.silent_s == pytest.approx(2.0)
    assert stale.last_seq == after[-1].seq


def test_the_rate_command_is_sent_again_after_a_board_restart(tmp_path: Path) -> None:
    emulator = board(frame_rate_hz=20.0)
    config = robot_file(tmp_path, "[sensor_board]\nframe_rate_hz = 50.0\n")

    async def scenario(h: Harness) -> None:
        await h.sleep(1.0)
        emulator.reset()  # a brown-out: the board restarts at its build's 20 Hz
        await h.sleep(1.0)

    result = run(scenario=scenario, config=config)
    (gap,) = result.events(of=SensorFrameGap)
    assert gap.restarted
    assert gap.seq == 0
    assert emulator.commands == [b"rate=50#", b"rate=50#"]
    assert emulator.rate_hz == 50
    frames = result.messages("frames", of=SensorFrame)
    after = [f for f in frames if f.t > gap.t]
    assert after[0].seq == 1
    # The frame after the restart's first is still at 20 Hz; from then on 50 Hz.
    steps = [
        round(b.t - a.t, 4) for a, b in itertools.pairwise([f for f in frames if f.t >= gap.t])
    ]
    assert steps[0] == 0.05
    assert set(steps[1:]) == {0.02}


def test_unknown_emulator_name_fails_with_the_registered_names() -> None:
    board("other")
    result = run_actors(sensor_graph("emulator:nope"), duration=0.5)
    failed = result.events(of=ActorFailed)
    assert failed
    assert "no emulated sensor board registered as 'nope'" in failed[0].error
    assert "other" in failed[0].error


def test_same_inputs_same_messages() -> None:
    digests = []
    for _ in range(2):
        emulator = board(counts={"ir1": 250, "fsr4": 700})

        async def scenario(h: Harness, emulator: SensorBoardEmulator = emulator) -> None:
            await h.sleep(0.4)
            emulator.corrupt(2)
            emulator.drop(1)
            await h.sleep(0.6)

        digests.append(run(scenario=scenario).digest)
        DEVICES.clear(SENSOR_BOARD)
    assert digests[0] == digests[1]


def test_shipped_sensors_graph_runs_both_readers(capsys: pytest.CaptureFixture[str]) -> None:
    graph = Path(__file__).resolve().parents[3] / "config" / "graphs" / "sensors.toml"
    assert main(["run", str(graph), "--virtual", "--duration", "2"]) == 0
    out = capsys.readouterr().out
    assert "SensorLinkUp    link='emulator'" in out
    assert "SensorLinkUp    link='i2c-1:0x6b'" in out
    assert "channel ranges: 39 published" in out  # 20 Hz board frames, 0.05 … 1.95 s
    tilts = int(out.split("channel tilt: ")[1].split()[0])
    assert 98 <= tilts <= 101  # the IMU's 50 Hz; the board has no accelerometer fitted
    assert "ActorFailed" not in out
