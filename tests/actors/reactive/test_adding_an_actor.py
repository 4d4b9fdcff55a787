"""The worked example of docs/architecture.md, "Adding an actor", run as written.

The page's Python block is the new actor's module and its TOML block the lines added to the
robot's graph file; this test writes the one to a folder of its own, applies the other to
a copy of ``config/graphs/walk.toml``, and runs the robot on the emulators with it. So the
guide cannot drift from what works.
"""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

from whexar.actors.graph import ROBOT_GRAPH, robot_graph
from whexar.actors.messages import JointGoals, LegState, MotionCommand, SwingEnded
from whexar.testing import Harness, RunResult, run_actors

GUIDE = Path(__file__).resolve().parents[3] / "docs" / "architecture.md"
FEMUR = 2


def _section() -> str:
    return GUIDE.read_text().split("## Adding an actor", 1)[1]


def _block(language: str) -> str:
    (found,) = re.findall(rf"```{language}\n(.*?)```", _section(), flags=re.S)
    return str(found)


@pytest.fixture
def my_reflex(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> object:
    """The guide's module, importable as ``my_reflex`` (a user's project folder)."""
    (tmp_path / "my_reflex.py").write_text(_block("python"))
    monkeypatch.syspath_prepend(str(tmp_path))
    return importlib.import_module("my_reflex")


def edited_graph(folder: Path) -> Path:
    """walk.toml with the guide's lines: the actor and channel appended, the legs wired."""
    text = ROBOT_GRAPH.read_text()
    legs_inputs = 'loads = "loads" }'
    assert text.count(legs_inputs) == 6  # the six legs' input lines
    text = text.replace(legs_inputs, 'loads = "loads", reflex = "overrides" }')
    added = "\n".join(line for line in _block("toml").splitlines() if not line.startswith("#"))
    path = folder / "my-walk.toml"
    path.write_text(text + "\n" + added + "\n")
    return path


def test_the_policy_answers_only_a_swing_without_ground(my_reflex: object) -> None:
    policy = my_reflex.ReachDown(-0.3, name="reach-down")  # type: ignore[attr-defined]
    ended = SwingEnded(t=1.0, source="leg-RF", leg=0, outcome="no_contact", ground_offset_m=0.0)
    goals = policy.on_swing(ended)
    assert goals is not None
    assert goals.reflex
    assert [(g.leg, g.joint, g.position_rad) for g in goals.goals] == [(0, FEMUR, -0.3)]
    for outcome in ("completed", "early_contact", "blocked"):
        other = SwingEnded(t=1.0, source="leg-RF", leg=0, outcome=outcome, ground_offset_m=0.0)
        assert policy.on_swing(other) is None


def walk(graph: dict[str, object]) -> RunResult:
    async def scenario(h: Harness) -> None:
        await h.sleep_until(3.0)
        await h.feed("commands", MotionCommand(t=3.0, source="test", vx_m_s=0.08))

    return run_actors(graph, duration=7.0, scenario=scenario, feeds=["commands"])


@pytest.mark.slow
def test_the_robot_runs_with_the_new_actor_and_its_legs_reach_down(
    my_reflex: object, tmp_path: Path
) -> None:
    graph = robot_graph(path=edited_graph(tmp_path), feeds=["commands"])
    assert "reach-down" in [a["name"] for a in graph["actors"]]
    r = walk(graph)
    assert r.exit_code == 0
    no_ground = r.messages("swings", of=SwingEnded)
    assert no_ground
    assert {e.outcome for e in no_ground} == {"no_contact"}  # the emulators have no ground
    overrides = r.messages("overrides", of=JointGoals)
    assert len(overrides) == len(no_ground)
    # Each leg whose swing found no ground took the override and said so.
    reaching = {s.leg for s in r.messages("legs", of=LegState) if s.phase == "reflex"}
    assert reaching == {e.leg for e in no_ground}
    femur_goals = [
        g.position_rad
        for m in r.messages("goals", of=JointGoals)
        for g in m.goals
        if g.joint == FEMUR
    ]
    assert -0.3 in femur_goals
    # The leg decides: the bus never got a reflex goal.
    assert not any(m.reflex for m in r.messages("goals", of=JointGoals))


@pytest.mark.slow
def test_without_the_new_actor_no_leg_reaches_down() -> None:
    r = walk(robot_graph(feeds=["commands"]))
    assert r.messages("swings", of=SwingEnded)
    assert not [s for s in r.messages("legs", of=LegState) if s.phase == "reflex"]
