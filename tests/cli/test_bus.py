"""``whexar emulate`` and ``whexar bus scan`` from the command line."""

from __future__ import annotations

import json
import os
import queue
import selectors
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from whexar.cli import main
from whexar.config import RobotConfig
from whexar.robot import JOINT_NAMES

ROOT = Path(__file__).resolve().parents[2]
CFG = RobotConfig()
MODELS = {
    sid: CFG.joints.by_name(joint).model
    for leg in CFG.legs
    for sid, joint in zip(leg.servo_ids, JOINT_NAMES, strict=True)
}


def _readline(proc: subprocess.Popen[str], timeout_s: float = 20.0) -> str:
    assert proc.stdout is not None
    with selectors.DefaultSelector() as sel:
        sel.register(proc.stdout, selectors.EVENT_READ)
        if not sel.select(timeout_s):
            proc.kill()
            pytest.fail(f"no line from whexar emulate within {timeout_s} s")
    return proc.stdout.readline()


@pytest.fixture
def emulate(tmp_path: Path) -> Iterator[list[subprocess.Popen[str]]]:
    started: list[subprocess.Popen[str]] = []
    yield started
    for proc in started:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def _start(started: list[subprocess.Popen[str]], *args: str) -> tuple[subprocess.Popen[str], str]:
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(
        [sys.executable, "-m", "whexar.cli", "emulate", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
        env=env,
    )
    started.append(proc)
    first = _readline(proc)
    if not first:
        assert proc.stderr is not None
        pytest.fail(f"whexar emulate exited {proc.wait()}: {proc.stderr.read()}")
    assert first.startswith("servo emulator: 42 servos on /dev/"), first
    path = first.split(" on ", 1)[1].split(" at ")[0]
    assert first.rstrip().endswith("at 1000000 bps")
    return proc, path


@pytest.mark.slow
@pytest.mark.serial  # the emulator answers each read within the SDK's timeout
def test_emulate_then_scan_finds_42_servos_with_their_models(
    emulate: list[subprocess.Popen[str]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plan = tmp_path / "plan.toml"
    plan.write_text(
        '[[faults]]\nkind = "hardware_error"\nids = [4]\nbits = ["overload"]\nat_s = 0\n'
    )
    proc, path = _start(emulate, "--faults", str(plan))

    assert main(["bus", "scan", "--port", path, "--json"]) == 0
    found = json.loads(capsys.readouterr().out)
    assert [s["id"] for s in found] == sorted(MODELS)
    assert {s["id"]: s["model"] for s in found} == MODELS
    assert all(s["model_number"] == CFG.servo_models[s["model"]].model_number for s in found)
    errors = {s["id"]: (s["hardware_error"], s["hardware_error_text"]) for s in found}
    assert errors[4] == (0x20, "overload")
    assert errors[5] == (0, "none")

    assert main(["bus", "scan", "--port", path]) == 0
    table = capsys.readouterr().out.splitlines()
    assert table[0].split() == ["ID", "model", "firmware", "hardware", "errors"]
    assert table[4].split()[:2] == ["4", "MX-64"]
    assert table[4].endswith("overload")
    assert table[-1] == f"42 servos on {path}"

    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert "fault 0: hardware_error overload on servo 4 started" in out
    assert out.splitlines()[-1].startswith("stopped: ")


@pytest.mark.slow
def test_emulate_stops_cleanly_on_sigint(emulate: list[subprocess.Popen[str]]) -> None:
    proc, _path = _start(emulate, "--no-realtime")
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert "stopped: 0 requests" in out


def test_emulate_refuses_a_bad_fault_plan(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plan = tmp_path / "plan.toml"
    plan.write_text('[[faults]]\nkind = "silent"\nids = [99]\nat_s = 0\n')
    assert main(["emulate", "--faults", str(plan)]) == 1
    assert "faults[0].ids = 99: an ID on the bus: 1–42" in capsys.readouterr().err


@pytest.mark.slow
def test_scan_with_nobody_answering_exits_1(capsys: pytest.CaptureFixture[str]) -> None:
    master, slave = os.openpty()
    try:
        assert main(["bus", "scan", "--port", os.ttyname(slave), "--json"]) == 1
    finally:
        os.close(master)
        os.close(slave)
    captured = capsys.readouterr()
    assert json.loads(captured.out) == []
    assert "no servo answered on" in captured.err


def test_scan_of_a_missing_port_says_why(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bus", "scan", "--port", "/dev/does-not-exist"]) == 1
    assert (
        "whexar: cannot open servo port /dev/does-not-exist: No such file or directory"
        in capsys.readouterr().err
    )


def test_scan_refuses_a_baud_rate_the_sdk_cannot_set(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["bus", "scan", "--port", "/dev/null", "--baud", "4500000"])
    assert exc.value.code == 2
    assert "'4500000': allowed baud rates: 9600," in capsys.readouterr().err


_DRIVING_GRAPH = """
[runtime]
stop_timeout_s = 1.0

[[actors]]
name = "bus"
class = "whexar.actors.bus:BusScheduler"
params = {{ port = "{port}", plan = "positioning" }}
inputs = {{ goals = "goals" }}
outputs = {{ state = "state" }}

[[actors]]
name = "wiggle"
class = "whexar.actors.bus:GoalWiggle"
params = {{ amplitude_rad = 0.0, wheel_rad_s = 2.0 }}
inputs = {{ state = "state" }}
outputs = {{ goals = "goals" }}

[channels.goals]
message = "JointGoals"
policy = "queue"

[channels.state]
message = "ServoStates"
policy = "latest"
"""


@pytest.mark.slow
@pytest.mark.serial  # the watchdog's 100 ms, on the wall clock
def test_sigkill_of_a_runtime_driving_the_wheels_and_the_watchdog_stops_them(
    emulate: list[subprocess.Popen[str]], tmp_path: Path
) -> None:
    """The Bus Watchdog, end to end: real processes, a real pty, real time."""
    import time

    from whexar.bus import control_table as ct
    from whexar.bus.sdk import DxlBus, open_port

    _, path = _start(emulate)
    graph = tmp_path / "drive.toml"
    graph.write_text(_DRIVING_GRAPH.format(port=path))
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    runtime = subprocess.Popen(
        [sys.executable, "-m", "whexar.cli", "run", str(graph)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
        env=env,
    )
    emulate.append(runtime)  # killed by the fixture whatever happens
    # A thread reads its lines: it prints several at once, and a select() on the pipe
    # would not see those already buffered.
    lines: queue.Queue[str] = queue.Queue()
    out = runtime.stdout
    assert out is not None

    def pump() -> None:
        for text in out:
            lines.put(text)

    threading.Thread(target=pump, daemon=True).start()
    while "ActorReady" not in (line := lines.get(timeout=20.0)) or "wiggle" not in line:
        pass
    time.sleep(0.5)  # driving
    runtime.send_signal(signal.SIGKILL)
    runtime.wait()
    time.sleep(0.3)  # > bus.watchdog_ms (100 ms)
    wheels = [leg.servo_ids[JOINT_NAMES.index("wheel")] for leg in CFG.legs]
    reg = ct.MODELS["MX-28"].register
    port = open_port(path, 1_000_000)
    try:
        bus = DxlBus(port)

        def read(sid: int, name: str) -> int:
            for _ in range(3):  # a reply may be lost to the killed process's last bytes
                reply = bus.read(sid, reg(name))
                if reply.ok:
                    return reply.value
            pytest.fail(f"servo {sid} does not answer a read of {name}")

        first = {w: read(w, "present_position") for w in wheels}
        for w in wheels:
            assert read(w, "bus_watchdog") == -1  # stopped by the watchdog
            assert read(w, "present_velocity") == 0
            assert read(w, "torque_enable") == 1  # stopped, not limp
        time.sleep(0.2)
        assert {w: read(w, "present_position") for w in wheels} == first
    finally:
        port.closePort()
