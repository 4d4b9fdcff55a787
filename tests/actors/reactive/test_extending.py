"""docs/extending.md, run as written: a reflex package from outside the tree, installed
with pip, found through its entry point and run by the robot on the emulators.

The page's code blocks are the package (its module and its ``pyproject.toml``), the robot
configuration that names it, the errors it promises and the policy's test; this test
writes each where the page says, installs the package into a folder of its own, and runs
the robot — in process and with ``whexar run`` — with it.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from whexar.actors.graph import robot_graph
from whexar.actors.messages import JointGoals, LegState, MotionCommand, SwingEnded
from whexar.errors import ConfigError
from whexar.testing import Harness, run_actors

PAGE = Path(__file__).resolve().parents[3] / "docs" / "extending.md"
ROOT = PAGE.parents[1]
FEMUR = 2


def blocks(language: str) -> list[str]:
    return [str(b) for b in re.findall(rf"```{language}\n(.*?)```", PAGE.read_text(), re.S)]


def block_named(language: str, first_line: str) -> str:
    (found,) = [b for b in blocks(language) if b.startswith(first_line)]
    return found


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The page's package, pip-installed into a folder of its own (not whexar's tree)."""
    project = tmp_path_factory.mktemp("project")
    (project / "reach_down.py").write_text(blocks("python")[0])
    (project / "pyproject.toml").write_text(block_named("toml", "# pyproject.toml"))
    target = tmp_path_factory.mktemp("site")
    subprocess.run(
        [
            sys.executable,
            *("-m", "pip", "install", "--quiet", "--disable-pip-version-check"),
            *("--no-deps", "--no-build-isolation", "--target", str(target), str(project)),
        ],
        check=True,
        capture_output=True,
    )
    assert list(target.glob("whexar_reach_down-*.dist-info/entry_points.txt"))
    return target


@pytest.fixture
def installed(site: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.delitem(sys.modules, "reach_down", raising=False)
    return site


@pytest.fixture
def config(tmp_path: Path) -> Path:
    path = tmp_path / "whexar.toml"
    path.write_text(block_named("toml", "# whexar.toml"))
    return path


@pytest.mark.slow
def test_the_installed_reflex_is_found_by_its_entry_point_and_run(
    installed: Path, config: Path
) -> None:
    graph = robot_graph(config=config, feeds=["commands"])
    (actor,) = [a for a in graph["actors"] if a["name"] == "reflex-reach-down"]
    assert actor["params"]["reflex"] == "reach-down"  # the entry point, not a module path

    async def scenario(h: Harness) -> None:
        await h.sleep_until(3.0)
        await h.feed("commands", MotionCommand(t=3.0, source="test", vx_m_s=0.08))

    r = run_actors(graph, duration=7.0, scenario=scenario, feeds=["commands"])
    assert r.exit_code == 0
    no_ground = r.messages("swings", of=SwingEnded)
    assert no_ground
    assert {e.outcome for e in no_ground} == {"no_contact"}  # the emulators have no ground
    overrides = r.messages("overrides", of=JointGoals)
    assert len(overrides) == len(no_ground)
    assert {(o.source, o.priority) for o in overrides} == {("reflex-reach-down", 1)}
    reaching = {s.leg for s in r.messages("legs", of=LegState) if s.phase == "reflex"}
    assert reaching == {e.leg for e in no_ground}
    bus = r.messages("goals", of=JointGoals)
    femur = {g.position_rad for m in bus for g in m.goals if g.joint == FEMUR}
    assert -0.35 in femur
    assert not any(m.reflex for m in r.messages("goals", of=JointGoals))  # the legs decide


@pytest.mark.slow
def test_whexar_run_runs_the_robot_with_it(installed: Path, config: Path) -> None:
    env = {**os.environ, "PYTHONPATH": str(installed)}
    done = subprocess.run(
        [
            *(sys.executable, "-m", "whexar.cli", "run", "config/graphs/walk.toml"),
            *("--config", str(config), "--virtual", "--duration", "6", "--no-record"),
            *("--commands", "config/commands/tour.jsonl"),
        ],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert "reflex-reach-down" in done.stdout + done.stderr  # its start is reported


@pytest.mark.slow
def test_the_pages_errors_are_what_a_bad_configuration_gets(
    installed: Path, tmp_path: Path
) -> None:
    bad = tmp_path / "whexar.toml"
    bad.write_text('[[reflexes]]\ntype = "reach-down"\nparams = { femur_rad = 5, depth = 1 }\n')
    with pytest.raises(ConfigError) as caught:
        robot_graph(config=bad)
    said = str(caught.value).replace(str(tmp_path) + "/", "")
    for line in block_named("text", "whexar.toml:").splitlines():
        assert line in said


@pytest.mark.slow
def test_the_pages_test_of_the_policy_passes(installed: Path) -> None:
    exec(compile(blocks("python")[1], str(PAGE), "exec"), {})
