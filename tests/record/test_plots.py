"""`whexar plot`: the plots of a recorded simulated run, what --legs, --joints and the window
select, a file cut short, and bad input."""

from __future__ import annotations

from pathlib import Path

import imageio.v2 as imageio
import numpy as np
import pytest

from whexar.actors.messages import JointState, ServoHealth, ServoStates
from whexar.cli import main
from whexar.errors import UsageError
from whexar.record.plots import (
    DPI,
    WIDTH_IN,
    LogData,
    currents,
    figure_height,
    joint_series,
    plotted_joints,
    power,
    read_log,
    swing_intervals,
    tilt,
    write_plots,
)
from whexar.robot import LEG_NAMES
from whexar.sim.run import simulate
from whexar.testing.walk import command

WALK_AT_S = 2.5
DURATION_S = 4.0


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Stand up, then walk the tripod gait for 1.5 s, recorded."""
    path = tmp_path_factory.mktemp("plots") / "walk.mcap"
    simulate(commands=[(WALK_AT_S, command(vx_m_s=0.1))], duration=DURATION_S, record=path)
    return path


@pytest.fixture(scope="module")
def whole(recording: Path) -> LogData:
    return read_log(recording)


def _size(path: Path) -> tuple[int, int]:
    """(width, height) of a PNG in pixels."""
    image = imageio.imread(path)
    return image.shape[1], image.shape[0]


def _px(inches: float) -> int:
    return round(inches * DPI)


@pytest.mark.slow
def test_every_plot_is_written_at_its_size(recording: Path, whole: LogData, tmp_path: Path) -> None:
    notes: list[str] = []
    written = write_plots(recording, tmp_path / "plots", say=notes.append)
    names = {p.name for p in written}
    legs = {f"joints_leg{leg}.png" for leg in range(len(LEG_NAMES))}
    assert names == legs | {"currents.png", "gait.png", "tilt.png", "power.png"}
    assert notes == []  # nothing skipped, the file is complete
    for path in written:
        assert path.parent == tmp_path / "plots"
        assert path.stat().st_size > 10_000
        width, height = _size(path)
        assert width == _px(WIDTH_IN)
        assert height > 300
    for leg in range(len(LEG_NAMES)):
        joints = plotted_joints(whole, leg)
        assert {0, 2, 3, 4} <= set(joints)  # Fig. 6.2's: coxa, femur, tibia, tarsus
        assert 6 not in joints  # the wheel has speed goals and no angle read
        height = _px(figure_height(len(joints), 1.8, 0.8))
        assert _size(tmp_path / "plots" / f"joints_leg{leg}.png")[1] == height
    assert _size(tmp_path / "plots" / "gait.png")[1] == _px(figure_height(6, 0.5, 1.0))
    assert _size(tmp_path / "plots" / "tilt.png")[1] == _px(5.5)
    assert _size(tmp_path / "plots" / "power.png")[1] == _px(figure_height(2, 3.0, 0.5))
    assert _size(tmp_path / "plots" / "currents.png")[1] == _px(figure_height(6, 1.6, 3.6))


@pytest.mark.slow
def test_the_data_behind_the_plots(whole: LogData) -> None:
    assert whole.ended is None
    assert whole.t1 == pytest.approx(whole.last_t)
    # Goals are addressed by (leg, joint): the femur follows its own goal while walking.
    femur = joint_series(whole, "RF", "femur")
    assert len(femur.goal_t) > 50
    assert len(femur.present_t) > 50
    walking = femur.present_t > WALK_AT_S
    goal_then = np.interp(femur.present_t[walking], femur.goal_t, femur.goal_rad)
    assert np.median(np.abs(goal_then - femur.present_rad[walking])) < np.radians(8)
    assert np.ptp(femur.goal_rad[femur.goal_t > WALK_AT_S]) > np.radians(10)  # it swings
    swings = swing_intervals(whole.legs)
    assert all(t0 >= WALK_AT_S for spans in swings.values() for t0, _ in spans)
    assert sum(len(spans) for spans in swings.values()) >= 3
    found = currents(whole)
    assert {j for _, j in found.per_servo} == {0, 2, 3, 4}  # the default read plan's
    assert set(found.per_leg) == set(range(6))
    assert all((a >= 0).all() for a in found.per_servo.values())
    p = power(whole)
    assert p.servos == 24
    # The robot's graph publishes the servos' health: the power uses their voltages.
    assert p.voltage == "V = each servo's input voltage from ServoHealth"
    assert whole.health
    assert (p.watts > 0).all()
    assert p.energy_j[-1] > 0
    sources = {s.source for s in tilt(whole)}
    assert "imu" in sources
    assert "world (/tf)" in sources  # the simulation records the body's pose
    assert whole.poses


@pytest.mark.slow
def test_legs_joints_and_window_select_what_they_say(
    recording: Path, whole: LogData, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "some"
    argv = ["plot", str(recording), "-o", str(out), "--legs", "LM", "0"]
    argv += ["--joints", "femur,tibia", "--from", "3", "--to", "3.8"]
    assert main(argv) == 0
    printed = capsys.readouterr().out.split()
    assert {Path(p).name for p in printed} == {
        "joints_leg0.png",
        "joints_leg3.png",
        "currents.png",
        "gait.png",
        "tilt.png",
        "power.png",
    }
    assert _size(out / "joints_leg3.png")[1] == _px(figure_height(2, 1.8, 0.8))
    assert _size(out / "currents.png")[1] == _px(figure_height(2, 1.6, 3.6))
    window = read_log(recording, t_from=3.0, t_to=3.8)
    assert (window.t0, window.t1) == (3.0, 3.8)
    times = [m.t for m in (*window.goals, *window.servo_states, *window.legs, *window.tilts)]
    assert min(times) >= 3.0
    assert max(times) <= 3.8
    assert len(window.servo_states) < len(whole.servo_states) / 3
    tibia = joint_series(window, 3, "tibia")
    assert tibia.goal_t.min() >= 3.0
    assert tibia.present_t.max() <= 3.8
    everything = joint_series(whole, 3, "tibia")
    inside = (everything.present_t >= 3.0) & (everything.present_t <= 3.8)
    assert np.array_equal(tibia.present_rad, everything.present_rad[inside])
    some = currents(window, [0, 3], [2, 3])
    assert set(some.per_servo) == {(0, 2), (0, 3), (3, 2), (3, 3)}
    assert set(some.per_leg) == {0, 3}


@pytest.mark.slow
def test_a_cut_file_plots_up_to_where_it_ends(
    recording: Path, whole: LogData, tmp_path: Path
) -> None:
    data = recording.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    notes: list[str] = []
    written = write_plots(cut, tmp_path / "cut", legs=["RF"], say=notes.append)
    assert {p.name for p in written} >= {"joints_leg0.png", "gait.png", "currents.png"}
    assert any("ends early" in n and "cut.mcap" in n for n in notes)
    part = read_log(cut)
    assert part.ended is not None
    assert "ends early" in part.ended
    assert part.last_t is not None
    assert whole.last_t is not None
    assert 0.5 < part.last_t < whole.last_t
    assert part.t1 == part.last_t
    assert 0 < len(part.servo_states) < len(whole.servo_states)


@pytest.mark.slow
def test_bad_legs_joints_files_and_windows_are_clear_errors(
    recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = str(tmp_path / "never")
    assert main(["plot", str(recording), "-o", out, "--legs", "RF", "7"]) == 2
    err = capsys.readouterr().err
    assert "unknown leg 7" in err
    assert "RF, LF, RM, LM, RR, LR" in err
    assert main(["plot", str(recording), "-o", out, "--joints", "knee"]) == 2
    err = capsys.readouterr().err
    assert "unknown joint 'knee'" in err
    assert "coxa, trochanter" in err
    assert main(["plot", str(tmp_path / "missing.mcap"), "-o", out]) == 2
    assert "cannot read" in capsys.readouterr().err
    junk = tmp_path / "junk.mcap"
    junk.write_text("not a recording")
    assert main(["plot", str(junk), "-o", out]) == 2
    assert "not an MCAP file" in capsys.readouterr().err
    assert main(["plot", str(recording), "-o", out, "--from", "100"]) == 2
    assert "no message between 100 s" in capsys.readouterr().err
    with pytest.raises(UsageError, match="not after"):
        write_plots(recording, out, t_from=2.0, t_to=1.0)
    assert not Path(out).exists()


def _states(t: float, amps: float) -> ServoStates:
    joints = tuple(JointState(0, j, j + 1, 0.0, 0.0, amps) for j in (0, 2))
    return ServoStates(t=t, source="bus", cycle=round(t * 100), joints=joints)


def test_power_uses_the_servos_recorded_voltage_else_the_supply(tmp_path: Path) -> None:
    states = [_states(0.01 * k, -1.0) for k in range(11)]
    data = LogData(path=tmp_path / "x.mcap", t0=0.0, t1=0.1, servo_states=states)
    p = power(data)
    assert p.servos == 2
    assert p.watts == pytest.approx([24.0] * 11)  # 2 servos × 12 V × |−1 A|
    assert "12 V" in p.voltage
    data.health = [
        ServoHealth(t=0.05, source="bus", servo_id=1, voltage_v=11.0),
        ServoHealth(t=0.08, source="bus", servo_id=3, voltage_v=10.0),
    ]
    p = power(data)
    assert "ServoHealth" in p.voltage
    assert p.watts[:5] == pytest.approx([24.0] * 5)  # no reading yet: the supply
    assert p.watts[5:8] == pytest.approx([22.0] * 3)  # servo 3 takes servo 1's mean
    assert p.watts[8:] == pytest.approx([21.0] * 3)
    assert p.energy_j[-1] == pytest.approx(0.01 * (24 * 4 + 23 + 22 * 2 + 21.5 + 21 * 2))
