"""Campaigns: the file and its checks, the process pool, Ray, failures, ``--resume``."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import pytest

from whexar.campaign import Row, load_campaign, parse_campaign, run_campaign, run_one
from whexar.campaign.runner import RUNS_FILE, read_rows
from whexar.campaign.spec import parse_path, set_path
from whexar.cli import main
from whexar.errors import ConfigError

SMALL = """
name = "small"
description = "Four runs of 2 s: two slopes, two stand-up times."
scenario = "wheels"
metrics = ["progress_m", "distance_m", "speed_mps", "mean_current_a", "max_tilt_deg", "events"]
timeout_s = 300
measure = { from_s = 0.5 }

[grid]
duration_s = [2.0]
"terrain.slope_deg" = [0, 10]
"config.locomotion.stand_up_s" = [1.0, 1.5]
"""


def _write(folder: Path, text: str, name: str = "c.toml") -> Path:
    path = folder / name
    path.write_text(text)
    return path


def _problems(data: dict[str, Any]) -> list[str]:
    with pytest.raises(ConfigError) as caught:
        parse_campaign(data, "c.toml")
    return [str(p) for p in caught.value.problems]


# --------------------------------------------------------------------------- the file


def test_paths_parse_and_set() -> None:
    assert parse_path("faults.faults[0].ids") == ["faults", "faults", 0, "ids"]
    assert parse_path("config.fsr.threshold_n") == ["config", "fsr", "threshold_n"]
    for bad in ("", "a..b", "a.", "[0]", "a b"):
        with pytest.raises(ValueError):  # noqa: PT011 - the message is checked below
            parse_path(bad)
    doc: dict[str, Any] = {"commands": [{"t": 1.0}]}
    set_path(doc, ["commands", 0, "vx_m_s"], 0.1)
    set_path(doc, ["start", "x_m"], 2.0)
    assert doc == {"commands": [{"t": 1.0, "vx_m_s": 0.1}], "start": {"x_m": 2.0}}
    with pytest.raises(ValueError, match=r"commands\[3\]: the list has 1 items"):
        set_path(doc, ["commands", 3, "t"], 0.0)


def test_a_campaign_expands_runs_times_grid() -> None:
    campaign = parse_campaign(
        {
            "scenario": "wheels",
            "grid": {"seed": [0, 1]},
            "runs": [
                {"label": "short", "duration_s": 1.0},
                {"label": "slopes", "duration_s": 2.0, "grid": {"terrain.slope_deg": [5, 10]}},
            ],
        }
    )
    got = [(r.label, r.variation) for r in campaign.runs]
    assert got == [
        ("short", {"label": "short", "duration_s": 1.0, "seed": 0}),
        ("short", {"label": "short", "duration_s": 1.0, "seed": 1}),
        ("slopes", {"label": "slopes", "duration_s": 2.0, "terrain.slope_deg": 5, "seed": 0}),
        ("slopes", {"label": "slopes", "duration_s": 2.0, "terrain.slope_deg": 5, "seed": 1}),
        ("slopes", {"label": "slopes", "duration_s": 2.0, "terrain.slope_deg": 10, "seed": 0}),
        ("slopes", {"label": "slopes", "duration_s": 2.0, "terrain.slope_deg": 10, "seed": 1}),
    ]
    assert [r.id for r in campaign.runs] == ["0000", "0001", "0002", "0003", "0004", "0005"]
    # The wheels scenario's terrain is a name: setting a feature makes it a table on it.
    assert campaign.runs[2].scenario["terrain"] == {"base": "flat", "slope_deg": 5}
    assert campaign.variation_keys == ("label", "duration_s", "seed", "terrain.slope_deg")
    assert len({r.key for r in campaign.runs}) == 6


def test_config_and_fault_plan_variations_are_documents_of_their_own() -> None:
    campaign = parse_campaign(
        {
            "scenario": "wheels",
            "runs": [
                {
                    "faults": {"faults": [{"kind": "silent", "ids": [3], "at_s": 1.0}]},
                    "config.locomotion.trochanter_follows_pitch": False,
                    "grid": {"faults.faults[0].ids": [[3], [4]]},
                }
            ],
        }
    )
    a, b = campaign.runs
    assert a.config == {"locomotion": {"trochanter_follows_pitch": False}}
    assert a.faults is not None
    assert b.faults is not None
    assert a.faults["faults"][0]["ids"] == [3]
    assert b.faults["faults"][0]["ids"] == [4]
    assert "config" not in a.scenario
    assert "faults" not in a.scenario


def test_a_configuration_given_replaces_the_base_scenarios_for_every_run(
    tmp_path: Path,
) -> None:
    stiff = _write(tmp_path, "[joints.coxa]\ngains = { p = 1700 }\n", "stiff.toml")
    campaign = load_campaign(_write(tmp_path, SMALL), config=stiff)
    plain = load_campaign(_write(tmp_path, SMALL))
    assert campaign.config == str(stiff)
    assert plain.config is None
    for run, before in zip(campaign.runs, plain.runs, strict=True):
        assert run.config is not None
        assert before.config is not None
        assert run.config["joints"] == {"coxa": {"gains": {"p": 1700}}}
        assert run.config["locomotion"] == before.config["locomotion"]  # set on it
        assert run.key != before.key  # --resume runs them again
    bad = _write(tmp_path, "[locomotion]\nstand_up_s = -1\n", "bad.toml")
    with pytest.raises(ConfigError) as caught:
        load_campaign(_write(tmp_path, SMALL), config=bad)
    (problem,) = caught.value.problems  # once, not once per run
    assert problem.path == "config"
    assert "locomotion.stand_up_s" in problem.allowed


def test_unknown_keys_are_named_before_anything_runs() -> None:
    found = _problems({"scenario": "wheels", "grid": {"seed": [0]}, "workers": 3})
    assert any(p.startswith("workers = 3: unknown key") for p in found)
    found = _problems({"scenario": "wheels", "grid": {"terrain.slope_dg": [10]}})
    assert found == [
        "run 0000: terrain.slope_dg = 10: unknown key; "
        "allowed here: base, slope_deg, ramp, steps, blocks, ditch, rocks"
    ]
    found = _problems({"scenario": "wheels", "grid": {"config.locomotion.stand_up_s": [1.0, -1.0]}})
    assert found == [
        "run 0001: config.locomotion.stand_up_s = -1.0: Input should be greater than 0"
    ]
    found = _problems({"scenario": "wheels", "grid": {"config.locomotion.nope": [1]}})
    assert found[0].startswith("run 0000: config.locomotion.nope = 1: unknown key; allowed here: ")
    found = _problems({"scenario": "wheels", "grid": {"bogus": [1]}})
    assert found == [
        "grid.bogus = 1: a scenario key (name, description, duration_s, seed, spread, terrain, "
        "start, commands, faults, sensor_faults, world_faults, config, tilt, supply, motors, "
        "with .key and [index] inside them), "
        "config.<section>.<key>, measure.from_s, measure.to_s, timeout_s or label"
    ]
    found = _problems({"scenario": "wheels", "grid": {"commands[9].t": [1.0]}})
    assert found == ["grid.commands[9].t = 1.0: commands[9]: the list has 5 items"]


def test_bad_values_and_empty_campaigns_are_named() -> None:
    assert _problems({"scenario": "wheels", "grid": {"seed": []}}) == [
        "grid.seed = []: a non-empty list of values: an empty grid has no run"
    ]
    assert _problems({"scenario": "wheels"}) == [
        "(campaign) = '(no runs)': a [grid] or [[runs]]: the campaign has no run"
    ]
    found = _problems({"scenario": "wheels", "metrics": ["speed"], "grid": {"seed": [0]}})
    assert found[0].startswith("metrics[0] = 'speed': a metric: ")
    found = _problems({"scenario": "nowhere", "grid": {"seed": [0]}})
    assert found[0].startswith("scenario = 'nowhere': a readable scenario")
    found = _problems({"scenario": "wheels", "grid": {"terrain.slope_deg": [10, 70]}})
    assert any(p.startswith("run 0001: terrain.slope_deg = 70") for p in found), found
    found = _problems(
        {"scenario": "wheels", "grid": {"measure.to_s": [100.0]}, "measure": {"from_s": 1.0}}
    )
    assert found == ["run 0000: measure.to_s = 100.0: at most the run's duration_s = 60"]


def test_the_shipped_campaigns_load() -> None:
    from whexar.campaign import campaign_names

    names = campaign_names()
    assert names
    for name in names:
        assert load_campaign(name).runs


# --------------------------------------------------------------------------- running


def test_a_failed_run_is_a_row_never_an_exception(tmp_path: Path) -> None:
    campaign = parse_campaign({"scenario": "wheels", "grid": {"duration_s": [1.0]}})
    run = campaign.runs[0]
    broken = type(run)(**{**run.__dict__, "scenario": {**run.scenario, "duration_s": -1}})
    row = run_one(broken)
    assert row.outcome == "failed"
    assert row.error is not None
    assert row.error.startswith("ConfigError: run 0000")
    assert row.details is not None
    assert "Traceback" in row.details


@pytest.fixture(scope="module")
def pool_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Row]]:
    """The small campaign (4 runs of 2 s) on 2 local processes."""
    folder = tmp_path_factory.mktemp("campaign")
    out = folder / "out"
    result = run_campaign(load_campaign(_write(folder, SMALL)), out, workers=2)
    return out, result.rows


@pytest.mark.slow
def test_the_process_pool_runs_every_variation(pool_run: tuple[Path, list[Row]]) -> None:
    out, rows = pool_run
    assert [r.outcome for r in rows] == ["ok"] * 4
    assert len({r.state_hash for r in rows}) == 4  # every variation changes the run
    flat, slope = rows[0], rows[2]
    assert flat.metrics["progress_m"] < 1e-6 < slope.metrics["max_tilt_deg"]  # type: ignore[operator]
    for name in ("results.json", "results.csv", "summary.md", "metrics.png", RUNS_FILE):
        assert (out / name).is_file(), name
    doc = json.loads((out / "results.json").read_text())
    assert [Row.from_json(r).same_result(x) for r, x in zip(doc["rows"], rows, strict=True)]
    header = (out / "results.csv").read_text().splitlines()[0]
    assert header.startswith("id,label,duration_s,terrain.slope_deg,config.locomotion.stand_up_s,")


@pytest.mark.slow
def test_a_run_in_a_worker_equals_the_same_run_here(pool_run: tuple[Path, list[Row]]) -> None:
    out, rows = pool_run
    campaign = load_campaign(out.parent / "c.toml")
    assert run_one(campaign.runs[3]).same_result(rows[3])


@pytest.mark.slow
def test_ray_gives_the_same_rows_bit_for_bit(
    pool_run: tuple[Path, list[Row]], tmp_path: Path
) -> None:
    import ray  # the test extra installs it: this test must not skip

    out, rows = pool_run
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    try:
        result = run_campaign(load_campaign(out.parent / "c.toml"), tmp_path, ray="")
    finally:
        ray.shutdown()
    assert [r.outcome for r in result.rows] == ["ok"] * 4
    for a, b in zip(result.rows, rows, strict=True):
        assert a.same_result(b), (a, b)


@pytest.mark.slow
def test_a_run_over_its_time_fails_and_the_campaign_goes_on(tmp_path: Path) -> None:
    text = """
scenario = "wheels"
metrics = ["distance_m"]
[[runs]]
label = "quick"
duration_s = 1.0
[[runs]]
label = "too long"
duration_s = 60.0
timeout_s = 1.5
[[runs]]
label = "after"
duration_s = 1.0
"""
    result = run_campaign(load_campaign(_write(tmp_path, text)), tmp_path / "out", workers=1)
    assert [r.outcome for r in result.rows] == ["ok", "failed", "ok"]
    assert result.rows[1].error == "timed out after 1.5 s"
    # The worker that timed out was replaced; the next run is as it would have been.
    assert result.rows[2].state_hash == result.rows[0].state_hash
    summary = (tmp_path / "out" / "summary.md").read_text()
    assert "- run 0001 too long: timed out after 1.5 s" in summary


@pytest.mark.slow
def test_resume_keeps_finished_runs_and_runs_the_rest(
    pool_run: tuple[Path, list[Row]], tmp_path: Path
) -> None:
    out, rows = pool_run
    journal = tmp_path / RUNS_FILE
    # An interrupted campaign: two rows finished, one cut off mid-line by the kill.
    kept = [rows[0], rows[2]]
    journal.write_text(
        "".join(json.dumps(r.to_json()) + "\n" for r in kept) + '{"id": "0001", "lab'
    )
    seen: list[int] = []
    result = run_campaign(
        load_campaign(out.parent / "c.toml"),
        tmp_path,
        workers=2,
        resume=True,
        progress=lambda p: seen.append(p.skipped),
    )
    assert set(seen) == {2}
    for a, b in zip(result.rows, rows, strict=True):
        assert a.same_result(b)
    assert result.rows[0].wall_s == rows[0].wall_s  # kept, not run again
    assert sorted(r.id for r in read_rows(journal)) == ["0000", "0001", "0002", "0003"]


# --------------------------------------------------------------------------- the command


def test_the_command_names_the_problems_of_a_bad_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _write(tmp_path, 'scenario = "wheels"\n[grid]\nseed = []\n')
    assert main(["campaign", str(path)]) == 1
    err = capsys.readouterr().err
    assert f"{path}: 1 problem" in err
    assert "grid.seed = []: a non-empty list of values" in err


@pytest.mark.slow
def test_the_command_runs_a_configuration_given_and_its_results_name_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    stiff = _write(tmp_path, "[joints.coxa]\ngains = { p = 1700 }\n", "stiff.toml")
    one = _write(tmp_path, 'scenario = "wheels"\n[grid]\nduration_s = [1.0]\n')
    out = tmp_path / "out"
    assert (
        main(["campaign", str(one), "--config", str(stiff), "-o", str(out), "--workers", "1"]) == 0
    )
    capsys.readouterr()
    assert json.loads((out / "results.json").read_text())["config"] == str(stiff)
    assert f"Robot configuration: `{stiff}` (`--config`)" in (out / "summary.md").read_text()


def test_ray_missing_is_one_line_saying_how_to_install_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray now raises ImportError
    path = _write(tmp_path, 'scenario = "wheels"\n[grid]\nduration_s = [0.5]\n')
    assert main(["campaign", str(path), "--ray", "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert (
        err[-1] == "whexar: --ray needs Ray, which is not installed: pip install 'whexar[cluster]'"
    )


def test_a_slope_named_by_the_base_is_replaced_by_a_slope_variation() -> None:
    campaign = parse_campaign({"scenario": "slope", "grid": {"terrain.slope_deg": [0, 20]}})
    assert [r.scenario["terrain"] for r in campaign.runs] == [
        {"base": "flat", "slope_deg": 0},
        {"base": "flat", "slope_deg": 20},
    ]


@pytest.mark.slow
def test_a_campaign_that_keeps_recordings_writes_one_per_run(tmp_path: Path) -> None:
    from whexar.record.reader import Recording

    campaign = parse_campaign({"scenario": "wheels", "record": True, "grid": {"duration_s": [0.5]}})
    row = run_one(campaign.runs[0], str(tmp_path))
    assert row.outcome == "ok"
    recording = Recording(tmp_path / "0000.mcap")
    assert recording.last_ns is not None
    assert recording.last_ns > 0.4e9


def test_the_docs_list_every_metric() -> None:
    from whexar.campaign.results import metrics_table

    docs = (Path(__file__).resolve().parents[2] / "docs" / "campaigns.md").read_text()
    assert metrics_table() in docs, "docs/campaigns.md: paste results.metrics_table() again"


def test_the_readme_and_docs_examples_load() -> None:
    import re
    import tomllib

    root = Path(__file__).resolve().parents[2]
    for doc in ("README.md", "docs/campaigns.md"):
        text = (root / doc).read_text()
        blocks = [b for b in re.findall(r"```toml\n(.*?)```", text, re.S) if "scenario =" in b]
        assert blocks, doc
        for block in blocks:
            assert parse_campaign(tomllib.loads(block), doc).runs


@pytest.mark.slow
@pytest.mark.serial  # the kill comes 4 s in: the run must be under way by then
def test_a_worker_killed_mid_run_fails_its_run_and_the_campaign_goes_on(tmp_path: Path) -> None:
    import multiprocessing
    import os
    import signal
    import threading
    import time

    text = """
scenario = "wheels"
metrics = ["distance_m"]
[[runs]]
label = "killed"
duration_s = 60.0
[[runs]]
label = "after"
duration_s = 0.5
"""
    campaign = load_campaign(_write(tmp_path, text))

    def kill_the_worker() -> None:  # as the OOM killer would, while run 0000 is under way
        time.sleep(4.0)
        for child in multiprocessing.active_children():
            assert child.pid is not None
            os.kill(child.pid, signal.SIGKILL)

    killer = threading.Thread(target=kill_the_worker)
    killer.start()
    result = run_campaign(campaign, tmp_path / "out", workers=1)
    killer.join()
    assert [r.outcome for r in result.rows] == ["failed", "ok"]
    assert result.rows[0].error == "worker crashed: killed by SIGKILL"
