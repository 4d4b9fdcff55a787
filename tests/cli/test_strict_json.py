"""Every ``--json`` of the command line is strict JSON (RFC 8259): no NaN, no infinities.

Python's :mod:`json` reads ``NaN``, ``Infinity`` and ``-Infinity`` as numbers, so a test
that parses with it passes what ``jq`` and ``JSON.parse`` refuse; here every output is
parsed with a parser that fails on them, whole or, for JSON lines, line by line.

The commands with ``--json`` are read from the argparse tree, and each case below says
which one it runs (:func:`covers`): a command that gains ``--json`` without a case fails
:func:`test_every_json_command_has_a_case`. The cases run with small, fast arguments;
the benchmarks with their sizes shrunk, as ``tests/bench`` shrinks them. Those that
need ptys, subprocesses or Ray, or draw plots, are marked slow: ``make test`` runs them.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import io
import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NoReturn, TypeVar

import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

import whexar.campaign
from whexar.bench import bus as bus_bench
from whexar.bench import campaign as campaign_bench
from whexar.bench import cycle as cycle_bench
from whexar.bench import fieldbus as fieldbus_bench
from whexar.bench import kin as kin_bench
from whexar.bench import median_seconds
from whexar.bench import record as record_bench
from whexar.bench import reflex as reflex_bench
from whexar.bench import replay as replay_bench
from whexar.bench import robot as robot_bench
from whexar.bench import runtime as runtime_bench
from whexar.bench import sensors as sensors_bench
from whexar.bench import sim as sim_bench
from whexar.campaign import parse_campaign, runner
from whexar.campaign.rows import Row
from whexar.campaign.spec import Campaign, RunSpec
from whexar.cli import build_parser, main
from whexar.cli.bench import SUITES

F = TypeVar("F", bound=Callable[..., Any])

COVERED: set[tuple[str, ...]] = set()
"""The commands the cases below run with ``--json`` (filled as the module loads)."""


def covers(*command: str) -> Callable[[F], F]:
    """Mark a test as the case of ``whexar COMMAND … --json``."""

    def mark(test: F) -> F:
        COVERED.add(command)
        return test

    return mark


def json_commands(
    parser: argparse.ArgumentParser, path: tuple[str, ...] = ()
) -> set[tuple[str, ...]]:
    """Every command under ``parser`` that takes ``--json``, as its words."""
    found: set[tuple[str, ...]] = set()
    # argparse has no public way to walk its tree: its actions and subparser tables.
    for action in parser._actions:
        if "--json" in action.option_strings:
            found.add(path)
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                found |= json_commands(sub, (*path, name))
    return found


def strict(text: str, where: str) -> Any:
    """``text`` parsed as RFC 8259 JSON: ``NaN``, ``Infinity`` and ``-Infinity`` fail."""

    def refuse(constant: str) -> NoReturn:
        pytest.fail(f"{where}: {constant} is not JSON (RFC 8259): {text[:300]}")

    return json.loads(text, parse_constant=refuse)


def run_json(
    args: Sequence[str], capsys: pytest.CaptureFixture[str], *, lines: bool = False
) -> tuple[int, Any]:
    """Run ``whexar ARGS``; its exit status and its stdout parsed strictly (a list of the
    lines' values with ``lines``)."""
    code = main(list(args))
    out = capsys.readouterr().out
    where = "whexar " + " ".join(args)
    if lines:
        return code, [strict(line, where) for line in out.splitlines()]
    return code, strict(out, where)


def in_process(
    runs: Sequence[RunSpec],
    workers: int,
    recordings: str | None,
    on_row: Callable[[Row], None],
    on_tick: Callable[[int], None],
) -> None:
    """The campaign runner's local back end without its worker processes, whose start
    (spawn, MuJoCo) takes seconds: the rows are the same (tests/campaign checks it)."""
    for run in runs:
        on_tick(1)
        on_row(runner.run_one(run, recordings))


def tiny_campaign() -> Campaign:
    """One run of 0.3 s, with the metrics whose value can be undefined."""
    return parse_campaign(
        {
            "name": "tiny",
            "scenario": "wheels",
            "metrics": [
                "distance_m",
                "cost_of_transport",
                "min_stability_margin_m",
                "window_cost_of_transport",
                "speed_mps",
            ],
            "runs": [{"duration_s": 0.3}],
        },
        "<tiny campaign>",
    )


# --------------------------------------------------------------------------- the tree


def test_the_tree_lists_the_commands_with_json() -> None:
    found = json_commands(build_parser())
    assert {("kin", "ik"), ("sim",), ("replay",), ("log", "info"), ("bench", "kin")} <= found
    assert all(("bench", suite) in found for suite in SUITES)
    assert ("config", "check") not in found


def test_every_json_command_has_a_case() -> None:
    missing = json_commands(build_parser()) - COVERED
    assert not missing, f"no strict-JSON case for: {sorted(' '.join(c) for c in missing)}"


# --------------------------------------------------------------------------- recordings


@pytest.fixture(scope="module")
def simulated(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """Half a second of ``whexar sim --json``, recorded: the recording and the output."""
    path = tmp_path_factory.mktemp("strict-json") / "sim.mcap"
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(["sim", "--duration", "0.5", "--record", str(path), "--json"])
    assert code == 0
    return path, out.getvalue()


@pytest.fixture(scope="module")
def late_start(simulated: tuple[Path, str]) -> Path:
    """The recording as a real clock makes it: its first message 1.9 ms late
    (``ActorStarting.t`` 0.0019, where a replay on virtual time publishes 0.0)."""
    source = simulated[0]
    target = source.with_name("late.mcap")
    with source.open("rb") as f, target.open("wb") as out:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        header = reader.get_header()
        writer = Writer(out, compression=CompressionType.ZSTD)
        writer.start(profile=header.profile, library=header.library)
        for meta in reader.iter_metadata():
            writer.add_metadata(meta.name, meta.metadata)
        for a in reader.iter_attachments():
            writer.add_attachment(a.log_time, a.create_time, a.name, a.media_type, a.data)
        schemas = {
            k: writer.register_schema(s.name, s.encoding, s.data)
            for k, s in summary.schemas.items()
        }
        channels = {
            k: writer.register_channel(
                c.topic, c.message_encoding, schemas.get(c.schema_id, 0), dict(c.metadata)
            )
            for k, c in summary.channels.items()
        }
        late = False
        for schema, channel, msg in reader.iter_messages(log_time_order=False):
            data = msg.data
            if not late and schema is not None and schema.name == "ActorStarting":
                assert data.startswith(b'{"t":0.0,')
                data, late = data.replace(b'"t":0.0,', b'"t":0.0019,', 1), True
            writer.add_message(
                channels[channel.id], msg.log_time, data, msg.publish_time, msg.sequence
            )
        writer.finish()  # type: ignore[no-untyped-call]  # mcap: no annotations
    assert late
    return target


# --------------------------------------------------------------------------- the cases


@covers("kin", "ik")
def test_kin_ik(capsys: pytest.CaptureFixture[str]) -> None:
    assert run_json(["kin", "ik", "--leg", "0", "190", "120", "0", "--json"], capsys)[0] == 0
    far = ["kin", "ik", "--leg", "LF", "900", "0", "0", "--clamp", "--json"]
    code, angles = run_json(far, capsys)
    assert (code, angles["clamped"]) == (0, True)


@covers("kin", "fk")
def test_kin_fk(capsys: pytest.CaptureFixture[str]) -> None:
    args = ["kin", "fk", "--leg", "0", "0", "0", "1.8", "-92.69", "0.9", "--json"]
    assert run_json(args, capsys)[0] == 0


@covers("kin", "gait")
@pytest.mark.parametrize("gait", ["tripod", "tetrapod", "ripple", "wave"])
def test_kin_gait(gait: str, capsys: pytest.CaptureFixture[str]) -> None:
    code, data = run_json(["kin", "gait", gait, "--json"], capsys)
    assert code == 0
    assert data["gait"] == gait


def test_config_schema_has_no_flag_and_is_json(capsys: pytest.CaptureFixture[str]) -> None:
    # JSON whatever the flags: not in the tree's list, checked all the same.
    code, schema = run_json(["config", "schema"], capsys)
    assert code == 0
    assert schema["type"] == "object"


@covers("sim")
def test_sim(simulated: tuple[Path, str]) -> None:
    summary = strict(simulated[1], "whexar sim --json")
    assert summary["sim_seconds"] == 0.5


@pytest.mark.slow
def test_sim_report_summary_file(tmp_path: Path) -> None:
    # summary.json is written for the readers of --json; the report's plots make it slow.
    report = tmp_path / "report"
    assert main(["sim", "--duration", "0.5", "--no-record", "--report", str(report)]) == 0
    summary = strict((report / "summary.json").read_text(), "summary.json")
    assert summary["sim_seconds"] == 0.5


@covers("log", "info")
def test_log_info(simulated: tuple[Path, str], capsys: pytest.CaptureFixture[str]) -> None:
    code, info = run_json(["log", "info", str(simulated[0]), "--json"], capsys)
    assert code == 0
    assert info["complete"] is True


@covers("log", "diff")
def test_log_diff(simulated: tuple[Path, str], capsys: pytest.CaptureFixture[str]) -> None:
    code, report = run_json(["log", "diff", str(simulated[0]), str(simulated[0]), "--json"], capsys)
    assert code == 0
    assert report["agrees"] is True


@covers("replay")
def test_replay_that_stops_before_its_clock_starts(
    late_start: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # The first message differs, before the replay's clock has started: the summary had
    # replayed_s and realtime_factor = -Infinity (issue 29).
    code, _ = run_json(["replay", str(late_start), "--check", "--json"], capsys)
    assert code == 1  # diverged


@covers("sensors")
def test_sensors_json_lines(capsys: pytest.CaptureFixture[str]) -> None:
    # The in-process board on real time: its first frames come within 0.1 s.
    args = ["sensors", "--port", "emulator", "--duration", "0.3", "--json"]
    code, records = run_json(args, capsys, lines=True)
    assert code == 0
    assert {r["kind"] for r in records} == {"event", "frame"}


@covers("campaign")
def test_campaign_and_its_results_files(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(runner, "_local", in_process)
    monkeypatch.setattr(whexar.campaign, "load_campaign", lambda _name, **_: tiny_campaign())
    out = tmp_path / "out"
    code, outcome = run_json(["campaign", "tiny", "-o", str(out), "--json"], capsys)
    assert (code, outcome["runs"], outcome["failed"]) == (0, 1, 0)
    results = strict((out / "results.json").read_text(), "results.json")
    assert results["rows"][0]["metrics"]["min_stability_margin_m"] is None  # never on its legs


@covers("sim")
def test_sim_experiments(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # The experiments' 165 runs take minutes: one tiny run instead. The table's figures
    # then have no runs to read, and the simulation's side is null or "not simulated".
    monkeypatch.setattr(runner, "_local", in_process)
    monkeypatch.setattr(whexar.campaign, "load_campaign", lambda _name, **_: tiny_campaign())
    args = ["sim", "--experiments", "--report", str(tmp_path / "report"), "--json"]
    code, table = run_json(args, capsys)
    assert code == 0
    assert table["experiments"]
    assert any(isinstance(row["thesis"], float) for row in table["experiments"])


@covers("bench", "kin")
def test_bench_kin(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(
        kin_bench, "median_seconds", lambda fn, _repeats: median_seconds(fn, 3, warmup=1)
    )
    run_json(["bench", "kin", "--json"], capsys)  # the status is the targets' verdict


@covers("bench", "runtime")
def test_bench_runtime(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    small = functools.partial(runtime_bench.run, messages=200, hops=50, virtual_s=0.5, repeats=1)
    monkeypatch.setattr(runtime_bench, "run", small)
    run_json(["bench", "runtime", "--json"], capsys)


@covers("bench", "cycle")
def test_bench_cycle(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(
        cycle_bench, "run", functools.partial(cycle_bench.run, cycles=10, repeats=1)
    )
    run_json(["bench", "cycle", "--json"], capsys)


@covers("bench", "sim")
def test_bench_sim(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(sim_bench, "measure", functools.partial(sim_bench.measure, 0.3))
    run_json(["bench", "sim", "--json"], capsys)


@covers("bench", "record")
@pytest.mark.slow
def test_bench_record(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(
        record_bench, "measure", functools.partial(record_bench.measure, seconds=0.5, repeats=1)
    )
    # Valgrind's probes take minutes; without them the suite reports the CPU it measured,
    # as on a machine without Valgrind (tests/bench checks the count itself).
    monkeypatch.setattr(record_bench, "count_instructions", lambda progress=None: None)
    monkeypatch.setattr(
        replay_bench, "measure", functools.partial(replay_bench.measure, seconds=0.5, repeats=1)
    )
    run_json(["bench", "record", "--json"], capsys)


@covers("bench", "fieldbus")
@pytest.mark.slow
def test_bench_fieldbus(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(
        fieldbus_bench,
        "measure",
        functools.partial(fieldbus_bench.measure, seconds=0.5, repeats=1),
    )
    run_json(["bench", "fieldbus", "--json"], capsys)


@covers("bench", "bus")
@pytest.mark.slow
def test_bench_bus_that_measured_no_cycle_over_the_pty(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # The real-time runs over the pty cut to their warm-up: no cycle is measured, and the
    # CPU per cycle was Infinity in the JSON; now null (the bench's docstring says so).
    # The rest in 0.3 s of each (run() passes its seconds on to the baseline).
    monkeypatch.setattr(bus_bench, "run", functools.partial(bus_bench.run, seconds=0.3))
    monkeypatch.setattr(
        bus_bench, "cpu_per_cycle_ms", functools.partial(bus_bench.cpu_per_cycle_ms, seconds=0.3)
    )
    warm_up_only = bus_bench.realtime_run
    monkeypatch.setattr(
        bus_bench,
        "realtime_run",
        lambda plan, _seconds, **kw: warm_up_only(plan, seconds=0.0, **kw),
    )
    _, figures = run_json(["bench", "bus", "--json"], capsys)
    runtime = figures["realtime_cpu_ms_per_cycle"]
    assert set(runtime["native"].values()) == set(runtime["sdk"].values()) == {None}
    assert None not in runtime["loop"].values()


@covers("bench", "sensors")
@pytest.mark.slow
def test_bench_sensors(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(
        sensors_bench, "run", functools.partial(sensors_bench.run, frames=500, repeats=1)
    )
    monkeypatch.setattr(
        sensors_bench, "latencies_ms", functools.partial(sensors_bench.latencies_ms, frames=30)
    )
    run_json(["bench", "sensors", "--json"], capsys)


@covers("bench", "campaign")
@pytest.mark.slow
def test_bench_campaign(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(
        campaign_bench,
        "bench_campaign",
        functools.partial(campaign_bench.bench_campaign, runs=2, duration_s=0.3),
    )
    monkeypatch.setattr(campaign_bench, "RAY_RUNS", 2)
    run_json(["bench", "campaign", "--json"], capsys)


@covers("bench", "robot")
@pytest.mark.slow
def test_bench_robot(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(robot_bench, "run", functools.partial(robot_bench.run, seconds=0.5))
    run_json(["bench", "robot", "--json"], capsys)


@covers("bench", "reflex")
@pytest.mark.slow
def test_bench_reflex(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(
        reflex_bench, "run", functools.partial(reflex_bench.run, repeats=1, end_s=8.0)
    )
    _, figures = run_json(["bench", "reflex", "--json"], capsys)
    # On virtual time the latency is the graph's, not the machine's: one cycle.
    assert 0.5 < figures["latency_cycles_p99"] < 1.1  # the next write, not the one after
    assert figures["latency_from_reading_cycles_p99"] > 1.5
    assert figures["policies_ms_per_cycle"] > 0.0


@covers("doctor")
def test_doctor(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    # No servo port: a verdict of not ready, in strict JSON all the same.
    code, doc = run_json(["doctor", "--json", "--port", str(tmp_path / "ttyUSB9")], capsys)
    assert code == 1
    assert doc["ready"] is False


@covers("bus", "scan")
@pytest.mark.slow
@pytest.mark.serial  # the emulator answers each read within the SDK's timeout
def test_bus_scan(capsys: pytest.CaptureFixture[str]) -> None:
    from whexar.bus.emulator.chain import ServoChain
    from whexar.bus.emulator.pty import PtyEmulator
    from whexar.config import RobotConfig

    chain = ServoChain.for_models(RobotConfig().servos())
    with PtyEmulator(chain, realtime=False) as emulator:
        code, found = run_json(["bus", "scan", "--port", str(emulator.path), "--json"], capsys)
    assert code == 0
    assert len(found) == 42
