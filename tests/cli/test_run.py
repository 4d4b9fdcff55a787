"""``whexar run`` and ``whexar bench runtime`` from the command line.

The stop tests run a real ``python -m whexar.cli run`` on a small wiring file
and signal it: real time is their point. They synchronise on the events the
process prints, and measure only how long it takes to exit after a signal.
"""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from whexar.bench.runtime import run as bench_run
from whexar.cli import main
from whexar.runtime.supervisor import (
    EXIT_CLEAN,
    EXIT_ESCALATED,
    EXIT_GRACE_S,
    EXIT_INTERRUPTED,
    EXIT_REFUSED,
)

DEMO = Path(__file__).resolve().parents[2] / "config" / "graphs" / "demo.toml"


def test_demo_graph_runs_on_virtual_time_and_stops_in_reverse_order(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["run", str(DEMO), "--virtual", "--duration", "12"]) == 0
    out = capsys.readouterr().out
    stopped = [
        line.split("actor=")[1].split(",")[0] for line in out.splitlines() if "ActorStopped" in line
    ]
    assert stopped == ["'flaky'", "'monitor'", "'heart'"]
    assert "ActorEscalated" not in out
    assert out.count("ActorRestarted") == 2  # it healed at t = 5 s
    assert "stopped: duration 12 s elapsed" in out
    assert "channel beats:" in out
    assert "dropped for monitor" in out


def test_escalation_exits_with_its_own_status(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    graph = tmp_path / "escalates.toml"
    graph.write_text(DEMO.read_text().replace("heal_at_s = 5.0", "heal_at_s = 12.0"))
    assert main(["run", str(graph), "--virtual", "--duration", "20"]) == EXIT_ESCALATED
    out = capsys.readouterr().out
    assert "ActorEscalated  actor='flaky', failures=4" in out
    assert out.index("SafeStop") < out.index("ActorStopped    actor='monitor'")


def test_bad_wiring_exits_1_naming_actor_and_channel(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    graph = tmp_path / "bad.toml"
    graph.write_text(
        DEMO.read_text()
        .replace('inputs = { inp = "beats" }', 'inputs = { inp = "beets" }')
        .replace("whexar.testing:Sink", "whexar.testing:Sunk")
    )
    assert main(["run", str(graph), "--virtual", "--duration", "1"]) == 1
    err = capsys.readouterr().err
    assert "actors.monitor.class = 'whexar.testing:Sunk'" in err
    assert "module 'whexar.testing' has no 'Sunk'" in err


def test_run_refuses_a_non_positive_duration(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["run", str(DEMO), "--duration", "-1"])
    assert exc.value.code == 2
    assert "expected a number of seconds > 0" in capsys.readouterr().err


@pytest.mark.slow
def test_bench_runtime_reports_the_three_figures() -> None:
    # Small sizes: this checks the benchmark's wiring, not the speed (that is
    # what `whexar bench runtime` is for).
    report = bench_run(messages=2_000, hops=200, virtual_s=2.0, repeats=1)
    assert list(report.figures) == ["messages_per_s", "hop_us", "virtual_60s_wall_s"]
    assert all(value > 0 for value in report.figures.values())
    assert report.items[0].at_least
    assert not report.items[1].at_least
    assert "frozen dataclass" in report.render()


def test_whexar_run_prints_the_traceback_of_a_failure(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["run", str(DEMO), "--virtual", "--duration", "3"]) == 0
    lines = capsys.readouterr().out.splitlines()
    at = next(i for i, line in enumerate(lines) if "ActorFailed" in line)
    assert lines[at].endswith("error='InjectedFailure: flaky: failed at cycle 20'")
    assert "traceback=" not in lines[at]  # printed below it, as Python prints it
    below = lines[at + 1 :]
    assert below[0] == " " * 12 + "Traceback (most recent call last):"
    end = next(i for i, line in enumerate(below) if not line.startswith(" " * 12))
    trace = [line[12:] for line in below[:end]]
    assert any('whexar/testing/actors.py", line' in line for line in trace)
    assert trace[-1] == "whexar.testing.actors.InjectedFailure: flaky: failed at cycle 20"


def test_an_actor_calling_sys_exit_is_escalated_not_an_exit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    graph = tmp_path / "quits.toml"
    graph.write_text(
        DEMO.read_text().replace("heal_at_s = 5.0", 'heal_at_s = 12.0, fail_with = "sys.exit"')
    )
    assert main(["run", str(graph), "--virtual", "--duration", "20"]) == EXIT_ESCALATED
    out = capsys.readouterr().out
    assert out.count("error='SystemExit: flaky: failed at cycle ") == 4
    assert "ActorEscalated  actor='flaky', failures=4" in out
    assert "stopped: escalation: actor 'flaky' failed 4 times" in out


REAL_IO = """
[runtime]
real_io_on_virtual_time = {allowed}

[[actors]]
name = "io"
class = "whexar.testing:RealIO"
params = {{ via = "pipe" }}
"""


@pytest.mark.slow
def test_virtual_time_refuses_real_io_unless_the_graph_allows_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    graph = tmp_path / "io.toml"
    graph.write_text(REAL_IO.format(allowed="false"))
    assert main(["run", str(graph), "--virtual", "--duration", "1"]) == EXIT_REFUSED
    err = capsys.readouterr().err
    assert err.startswith("whexar: virtual time refuses real I/O: actor 'io': file descriptor")
    assert "real_io_on_virtual_time = true under [runtime]" in err
    graph.write_text(REAL_IO.format(allowed="true"))
    assert main(["run", str(graph), "--virtual", "--duration", "1"]) == EXIT_CLEAN


WALK = DEMO.with_name("walk.toml")


@pytest.mark.slow
def test_a_run_is_recorded_by_default_with_the_bus_bytes_and_the_wiring(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from whexar.record.reader import Recording

    folder = tmp_path / "logs"
    monkeypatch.setenv("WHEXAR_RECORDINGS", str(folder))
    assert main(["run", str(WALK), "--virtual", "--duration", "2", "--quiet"]) == EXIT_CLEAN
    (path,) = folder.glob("walk-*.mcap")
    assert f"recording: {path}" in capsys.readouterr().out
    log = Recording(path)
    assert log.complete
    assert "wiring.toml" in log.attachments
    topics = {r.topic for r in log.records(decode=False)}
    assert {"/servo-state", "/goals", "/links/bus", "/joint_states"} <= topics
    assert main(["run", str(WALK), "--virtual", "--duration", "1", "--no-record"]) == EXIT_CLEAN
    assert len(list(folder.glob("*.mcap"))) == 1


# --------------------------------------------------------------------------- stops, for real

STOP_TIMEOUT_S = 0.5
SLACK_S = 1.0
"""Allowance for starting and ending a Python process on a busy machine."""


class Running:
    """A ``whexar run`` process on a wiring file; its output read line by line."""

    def __init__(self, tmp_path: Path, wiring: str) -> None:
        graph = tmp_path / "graph.toml"
        graph.write_text(textwrap.dedent(wiring))
        self.proc = subprocess.Popen(
            # Stop bounds and fairness, not recording (its cost is `whexar bench record`).
            [sys.executable, "-m", "whexar.cli", "run", str(graph), "--no-record"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        self.lines: list[str] = []
        self._partial = b""
        self.signalled_at = 0.0

    def wait_for(self, text: str, timeout_s: float = 20.0) -> str:
        """The first line containing ``text`` (failing if none comes in time)."""
        assert self.proc.stdout is not None
        fd = self.proc.stdout.fileno()
        deadline = time.monotonic() + timeout_s
        checked = 0
        while True:
            for line in self.lines[checked:]:
                if text in line:
                    return line
            checked = len(self.lines)
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                self.proc.kill()
                pytest.fail(f"no line with {text!r} in time; printed: {self.lines}")
            chunk = os.read(fd, 65536)
            if not chunk:
                self.proc.kill()
                pytest.fail(f"the process ended before printing {text!r}: {self.lines}")
            *complete, self._partial = (self._partial + chunk).split(b"\n")
            self.lines += [line.decode() for line in complete]

    def signal(self, signum: int) -> None:
        self.signalled_at = time.monotonic()
        self.proc.send_signal(signum)

    def finish(self, timeout_s: float = 60.0) -> tuple[int, float, str, str]:
        """Exit status, wall seconds since the last signal, the rest of stdout, stderr."""
        try:
            out, err = self.proc.communicate(timeout=timeout_s)
        finally:
            self.proc.kill()
        elapsed = time.monotonic() - self.signalled_at
        rest = (self._partial + out).decode()
        return self.proc.returncode, elapsed, "\n".join([*self.lines, rest]), err.decode()


FLOODED = f"""
[runtime]
stop_timeout_s = {STOP_TIMEOUT_S}

[[actors]]
name = "flood"
class = "whexar.testing:Flood"
outputs = {{ out = "noise" }}

[[actors]]
name = "heart"
class = "whexar.testing:Pulse"
params = {{ period_s = 0.01, count = 20 }}
outputs = {{ out = "beats" }}

[[actors]]
name = "monitor"
class = "whexar.testing:Sink"
inputs = {{ inp = "noise" }}

[channels.noise]
message = "Heartbeat"
policy = "latest"

[channels.beats]
message = "Heartbeat"
policy = "queue"
"""


@pytest.mark.slow
@pytest.mark.serial  # a signalled process, its stop timed on the wall clock
def test_sigint_stops_a_tight_loop_publisher_within_the_bound(tmp_path: Path) -> None:
    run = Running(tmp_path, FLOODED)
    # The heart runs its 20 cycles (0.2 s) while the flood floods: it got its
    # turns, on time give or take the load of a busy test machine.
    returned = run.wait_for("ActorStopped    actor='heart', reason='returned'")
    assert float(returned.split()[0]) < 1.0
    run.wait_for("ActorReady      actor='monitor'")
    run.signal(signal.SIGINT)
    code, elapsed, out, err = run.finish()
    assert code == EXIT_CLEAN, err
    assert elapsed < 3 * STOP_TIMEOUT_S + EXIT_GRACE_S
    assert "StopRequested   reason='signal SIGINT'" in out
    # Neither the flood nor its subscriber (whose every wait ends at once) overran.
    assert "ActorStopped    actor='monitor', reason='stop', timed_out=False" in out
    assert "ActorStopped    actor='flood', reason='stop', timed_out=False" in out
    assert "channel beats: 20 published" in out
    flooded = next(line for line in out.splitlines() if line.startswith("channel noise:"))
    assert int(flooded.split()[2]) > 10_000


STUBBORN = f"""
[runtime]
stop_timeout_s = {STOP_TIMEOUT_S}

[[actors]]
name = "brake"
class = "whexar.testing:Brake"

[[actors]]
name = "stubborn"
class = "whexar.testing:Stubborn"
params = {{ cleanup = "{{cleanup}}" }}   # forever

[[actors]]
name = "heart"
class = "whexar.testing:Pulse"
params = {{ period_s = 0.01 }}
outputs = {{ out = "beats" }}

[channels.beats]
message = "Heartbeat"
policy = "latest"
"""


@pytest.mark.slow
@pytest.mark.serial  # a signalled process, its stop timed on the wall clock
@pytest.mark.parametrize(
    ("cleanup", "left_behind"),
    [
        ("shield", "actor 'stubborn' still running after the stop step"),
        ("swallow", "actor 'stubborn' still running after the stop step"),
        ("block", "the stop overran its bound (is the event loop blocked?)"),
    ],
)
def test_a_cleanup_that_ignores_the_stop_cannot_keep_the_process_alive(
    tmp_path: Path, cleanup: str, left_behind: str
) -> None:
    run = Running(tmp_path, STUBBORN.replace("{cleanup}", cleanup))
    run.wait_for("ActorReady      actor='heart'")
    run.signal(signal.SIGTERM)
    code, elapsed, out, err = run.finish()
    assert code == EXIT_CLEAN, err
    # Three steps of stop_timeout_s; with the loop blocked, the alarm adds its grace.
    assert elapsed < 3 * STOP_TIMEOUT_S + EXIT_GRACE_S + SLACK_S
    assert left_behind in err
    assert "ActorStopped    actor='heart', reason='stop'" in out
    if cleanup != "block":  # the loop ran on: the stubborn one was passed over
        assert "ActorStopped    actor='stubborn', reason='stop', timed_out=True" in out
        assert "ActorStopped    actor='brake', reason='stop', timed_out=False" in out


SLOW_CLEANUP = """
[runtime]
stop_timeout_s = 30.0

[[actors]]
name = "brake"
class = "whexar.testing:Brake"

[[actors]]
name = "slow"
class = "whexar.testing:Pulse"
params = { period_s = 0.01, cleanup_s = 20.0 }
outputs = { out = "beats" }

[channels.beats]
message = "Heartbeat"
policy = "latest"
"""


@pytest.mark.slow
@pytest.mark.serial  # a signalled process, its stop timed on the wall clock
def test_a_second_sigint_runs_the_safe_stop_and_exits_at_once(tmp_path: Path) -> None:
    run = Running(tmp_path, SLOW_CLEANUP)
    run.wait_for("ActorReady      actor='slow'")
    run.signal(signal.SIGINT)
    run.wait_for("StopRequested   reason='signal SIGINT'")  # 'slow' now cleans up for 20 s
    run.signal(signal.SIGINT)
    code, elapsed, out, err = run.finish()
    assert code == EXIT_INTERRUPTED, err
    assert elapsed < SLACK_S
    safe_stop = out.index("SafeStop        reason='second SIGINT: stop at once'")
    assert out.index("Braked          actor='brake'") > safe_stop
    assert "ActorStopped" not in out  # nobody waited for the cleanup
    assert "second SIGINT: safe stop done" in err


@pytest.mark.slow
@pytest.mark.serial  # a signalled process, its stop timed on the wall clock
def test_a_second_sigint_is_heard_while_a_cleanup_blocks_the_loop(tmp_path: Path) -> None:
    run = Running(tmp_path, STUBBORN.replace("{cleanup}", "block"))
    run.wait_for("ActorReady      actor='heart'")
    run.signal(signal.SIGINT)
    run.wait_for("ActorStopped    actor='heart'")  # next: the stubborn cleanup blocks the loop
    run.signal(signal.SIGINT)
    code, elapsed, _, err = run.finish()
    # The safe stop cannot run on a blocked loop; its bound still ends the process.
    assert code == EXIT_INTERRUPTED, err
    assert elapsed < 3 * STOP_TIMEOUT_S + EXIT_GRACE_S + SLACK_S
    assert "the stop overran its bound" in err


def test_a_missing_servo_port_is_one_line_and_no_restart(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    walk = Path(__file__).resolve().parents[2] / "config" / "graphs" / "walk.toml"
    port = tmp_path / "ttyUSB7"
    argv = ["run", str(walk), "--set", f"bus.port={port}", "--duration", "5", "--no-record"]
    assert main(argv) == 4
    out = capsys.readouterr().out
    assert "Traceback" not in out
    assert "ActorRestarted" not in out
    (failed,) = [line for line in out.splitlines() if "ActorFailed" in line]
    assert f"servo port {port}: no such device" in failed
    (stopped,) = [line for line in out.splitlines() if line.startswith("stopped:")]
    assert stopped.startswith("stopped: device unavailable: actor 'bus'")
    assert f"whexar doctor --port {port}" in stopped
