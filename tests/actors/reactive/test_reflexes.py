"""Reflexes as plug-ins: found by name, their parameters checked, run one actor each,
ranked by priority, held back by the reflexes that inhibit them, disabled when they keep
failing — and ``[[reflexes]]`` in a graph file or the robot configuration."""

from __future__ import annotations

import importlib
import sys
import textwrap
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from whexar.actors.graph import robot_graph
from whexar.actors.messages import JointGoals, ReflexActivity, SwingEnded
from whexar.actors.reactive import (
    ACTIVITY,
    OVERRIDES,
    REQUESTS,
    add_reflexes,
    check_params,
    parse_entries,
    resolve_reflex,
)
from whexar.config import ReflexEntry, RobotConfig
from whexar.errors import ConfigError
from whexar.runtime.messages import ActorDisabled, ActorFailed
from whexar.runtime.wiring import WiringError, build_graph
from whexar.testing import Harness, run_actors

FEMUR = 2

# A user's module of reflexes, written to a folder of its own (not part of whexar).
PLUGINS = '''
from pydantic import Field

from whexar.actors.messages import SwingEnded
from whexar.actors.reactive import Reflex, ReflexParams

FEMUR = 2


class ReachDown(Reflex):
    """A swing that found no ground: that leg's femur down, for a moment."""

    inputs = ("swings",)
    priority = 1

    class Params(ReflexParams):
        femur_rad: float = Field(-0.3, ge=-2.09, le=2.09)
        """Table 5.2: the femur turns ±120°."""

    def react(self, t, msg):
        if isinstance(msg, SwingEnded) and msg.outcome == "no_contact":
            self.active, self.reason = True, f"leg {msg.leg}: no ground"
            return [self.override(t, msg.leg, {FEMUR: self.params.femur_rad})]
        self.active = False
        return []


class Lift(Reflex):
    """Every swing end: the femur up (a reflex that contradicts ReachDown)."""

    inputs = ("swings",)
    inhibits = ("reflex-reachdown",)

    def react(self, t, msg):
        self.active, self.reason = True, "lifting"
        return [self.override(t, msg.leg, {FEMUR: 0.5})]


class Broken(Reflex):
    """Raises on every message."""

    inputs = ("swings",)

    def react(self, t, msg):
        raise ZeroDivisionError("a bug in a reflex")


class Ranging(Reflex):
    inputs = ("ranges",)


class NotAReflex:
    pass
'''


@pytest.fixture
def plugins(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> ModuleType:
    (tmp_path / "my_reflexes.py").write_text(textwrap.dedent(PLUGINS))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "my_reflexes", raising=False)
    return importlib.import_module("my_reflexes")


def swing(t: float, leg: int = 0, outcome: str = "no_contact") -> SwingEnded:
    return SwingEnded(t=t, source=f"leg-{leg}", leg=leg, outcome=outcome, ground_offset_m=0.0)  # type: ignore[arg-type]


# --------------------------------------------------------------------------- the policy


def test_the_policy_is_a_plain_class_its_test_calls(plugins: ModuleType) -> None:
    cls = resolve_reflex("my_reflexes:ReachDown")
    policy = cls(check_params(cls, {"femur_rad": -0.4}), name="reach", cfg=RobotConfig())
    (goals,) = policy.react(1.0, swing(1.0, leg=3))
    assert isinstance(goals, JointGoals)
    assert goals.reflex
    assert [(g.leg, g.joint, g.position_rad) for g in goals.goals] == [(3, FEMUR, -0.4)]
    assert policy.active
    assert list(policy.react(1.1, swing(1.1, outcome="completed"))) == []
    assert not policy.active


@pytest.mark.parametrize(
    ("kind", "says"),
    [
        ("my_reflexes:Nope", "module 'my_reflexes' has no 'Nope'"),
        ("no_such_module:Reflex", "module 'no_such_module' cannot be imported"),
        ("my_reflexes:NotAReflex", "not a subclass of whexar.actors.reactive.Reflex"),
        ("elevatorr", "not 'package.module:Class' and not a reflex of the 'whexar.reflexes'"),
        ("my_reflexes:", "expected 'package.module:Class'"),
    ],
)
def test_a_wrong_reflex_name_says_what_is_wrong(plugins: ModuleType, kind: str, says: str) -> None:
    with pytest.raises(LookupError, match=says):
        resolve_reflex(kind)


def test_bad_parameters_name_the_key_the_value_and_what_is_allowed(plugins: ModuleType) -> None:
    cls = resolve_reflex("my_reflexes:ReachDown")
    with pytest.raises(ValueError, match=r"params\.femur_rad = 5: Input should be less than"):
        check_params(cls, {"femur_rad": 5})
    with pytest.raises(ValueError, match=r"params\.femur = -0\.2: a parameter of it \(femur_rad\)"):
        check_params(cls, {"femur": -0.2})


# --------------------------------------------------------------------------- [[reflexes]]


def entries(*tables: dict[str, Any]) -> list[tuple[str, ReflexEntry]]:
    return parse_entries(list(tables), "reflexes", "my-walk.toml")


def test_reflexes_become_actors_wired_to_the_robot(plugins: ModuleType) -> None:
    doc = robot_graph()
    add_reflexes(
        doc,
        entries({"type": "my_reflexes:ReachDown", "params": {"femur_rad": -0.2}, "priority": 4}),
        source="my-walk.toml",
    )
    (actor,) = [a for a in doc["actors"] if a["name"] == "reflex-reachdown"]
    assert actor["inputs"] == {"swings": "swings", "activity_in": ACTIVITY}
    assert actor["outputs"] == {
        "override": OVERRIDES,
        "request": REQUESTS,
        "activity": ACTIVITY,
    }
    (coordinator,) = [a for a in doc["actors"] if a["name"] == "coordinator"]
    assert coordinator["inputs"]["requests"] == REQUESTS
    assert actor["params"]["priority"] == 4
    assert actor["restart"]["exhausted"] == "disable"
    legs = [a for a in doc["actors"] if a["name"].startswith("leg-")]
    assert {a["inputs"]["reflex"] for a in legs} == {OVERRIDES}
    build_graph(doc)  # a valid graph


def test_every_problem_of_the_entries_is_named_before_anything_is_added(
    plugins: ModuleType,
) -> None:
    doc = robot_graph()
    del doc["channels"]["ranges"]
    before = len(doc["actors"])
    with pytest.raises(ConfigError) as caught:
        add_reflexes(
            doc,
            entries(
                {"type": "my_reflexes:ReachDown", "params": {"femur_rad": "low"}},
                {"type": "my_reflexes:Nope"},
                {"type": "my_reflexes:ReachDown", "params": {"depth": 1}},
                {"type": "my_reflexes:Ranging"},
            ),
            source="my-walk.toml",
        )
    text = str(caught.value)
    assert "reflexes[0].params.femur_rad = 'low'" in text
    assert "reflexes[1].type = 'my_reflexes:Nope': a reflex class:" in text
    assert "reflexes[2].params.depth = 1: a parameter of it (femur_rad)" in text
    assert "reflexes[2].name = 'reachdown': a name no other actor has" in text
    assert "it reads 'ranges', and the graph has no channel 'ranges'" in text
    assert len(doc["actors"]) == before


def test_an_entry_with_an_unknown_key_is_refused_by_name() -> None:
    with pytest.raises(ConfigError, match=r"reflexes\[0\]\.threshold = 3: unknown key"):
        entries({"type": "elevator", "threshold": 3})
    with pytest.raises(ConfigError, match=r"reflexes\[1\]\.type = \(missing\)"):
        entries({"type": "elevator"}, {"name": "x"})


def test_the_robot_runs_the_battery_reflex_and_its_configuration_can_retune_or_drop_it(
    tmp_path: Path,
) -> None:
    (battery,) = [a for a in robot_graph()["actors"] if a["name"] == "reflex-battery"]
    assert battery["params"] == {"reflex": "battery", "params": {}}
    retuned = tmp_path / "retuned.toml"
    retuned.write_text('[[reflexes]]\ntype = "battery"\nparams = { warn_v = 11.0 }\n')
    (battery,) = [a for a in robot_graph(config=retuned)["actors"] if a["name"] == "reflex-battery"]
    assert battery["params"]["params"] == {"warn_v": 11.0}
    dropped = tmp_path / "dropped.toml"
    dropped.write_text('[[reflexes]]\ntype = "battery"\nenabled = false\n')
    doc = robot_graph(config=dropped)
    assert not [a for a in doc["actors"] if a["name"].startswith("reflex-")]
    assert OVERRIDES not in doc["channels"]
    build_graph(doc)


def test_a_reflex_whose_inputs_a_trimmed_graph_no_longer_publishes_is_left_out() -> None:
    doc = robot_graph(leave_out=("bus",), feeds=["servo-state"])  # no servo health
    assert "reflex-battery" not in [a["name"] for a in doc["actors"]]
    build_graph(doc, external={"servo-state": "test"})


def test_a_reflex_that_reads_the_imus_samples_has_them_published(tmp_path: Path) -> None:
    from whexar.actors.graph import ROBOT_GRAPH

    # A graph whose terrain estimator does not read the IMU's samples leaves them out…
    graph = tmp_path / "walk.toml"
    text = ROBOT_GRAPH.read_text()
    for wired in ('outputs = { tilt = "tilt", samples = "imu" }', ' imu = "imu",'):
        assert wired in text
        text = text.replace(wired, 'outputs = { tilt = "tilt" }' if "samples" in wired else "")
    graph.write_text(text.replace('[channels.imu]\nmessage = "ImuSample"\npolicy = "queue"\n', ""))
    assert "imu" not in robot_graph(path=graph)["channels"]  # nobody reads them
    # …until a reflex reads them.
    config = tmp_path / "hold.toml"
    config.write_text('[[reflexes]]\ntype = "heading-hold"\n')
    doc = robot_graph(config=config, path=graph)
    (imu,) = [a for a in doc["actors"] if a["name"] == "imu"]
    assert imu["outputs"]["samples"] == "imu"
    assert doc["channels"]["imu"] == {"message": "ImuSample", "policy": "queue"}
    (hold,) = [a for a in doc["actors"] if a["name"] == "reflex-heading-hold"]
    assert hold["inputs"]["imu"] == "imu"
    build_graph(doc)


def test_a_graph_file_and_the_robot_configuration_both_add_reflexes(
    plugins: ModuleType, tmp_path: Path
) -> None:
    from whexar.actors.graph import ROBOT_GRAPH

    graph = tmp_path / "walk.toml"
    graph.write_text(
        ROBOT_GRAPH.read_text()
        + '\n[[reflexes]]\ntype = "my_reflexes:ReachDown"\nparams = { femur_rad = -0.25 }\n'
    )
    config = tmp_path / "robot.toml"
    config.write_text('[[reflexes]]\ntype = "my_reflexes:Lift"\nname = "lift"\n')
    doc = robot_graph(path=graph, config=config)
    names = [a["name"] for a in doc["actors"]]
    assert names[-2:] == ["reflex-reachdown", "reflex-lift"]
    (lift,) = [a for a in doc["actors"] if a["name"] == "reflex-lift"]
    assert lift["params"]["config"] == str(config)
    build_graph(doc)


def test_the_graph_refuses_a_hand_written_reflex_actor_with_bad_parameters(
    plugins: ModuleType,
) -> None:
    doc = robot_graph()
    doc["actors"].append(
        {
            "name": "mine",
            "class": "whexar.actors.reactive:ReflexActor",
            "params": {"reflex": "my_reflexes:ReachDown", "params": {"femur_rad": 9}},
            "inputs": {"swings": "swings"},
            "outputs": {"override": "goals"},
        }
    )
    with pytest.raises(WiringError, match=r"reflex 'my_reflexes:ReachDown': params\.femur_rad = 9"):
        build_graph(doc)


# --------------------------------------------------------------------------- the actors


def reflex_graph(*tables: dict[str, Any]) -> dict[str, Any]:
    """The reflexes alone, the swing ends fed by the test."""
    doc: dict[str, Any] = {
        "actors": [],
        "channels": {"swings": {"message": "SwingEnded", "policy": "queue"}},
    }
    add_reflexes(doc, entries(*tables), source="test")
    return doc


def feed_swings(times: list[float]) -> Any:
    async def scenario(h: Harness) -> None:
        for t in times:
            await h.sleep_until(t)
            await h.feed("swings", swing(t))

    return scenario


def test_a_reflex_answers_its_input_at_once_with_its_priority(plugins: ModuleType) -> None:
    r = run_actors(
        reflex_graph({"type": "my_reflexes:ReachDown", "priority": 7}),
        duration=1.0,
        scenario=feed_swings([0.5]),
        feeds=["swings"],
    )
    (goals,) = r.messages(OVERRIDES, of=JointGoals)
    assert (goals.t, goals.priority, goals.source) == (0.5, 7, "reflex-reachdown")
    said, stopped = r.messages(ACTIVITY, of=ReflexActivity)
    assert (said.t, said.active, said.reason) == (0.5, True, "leg 0: no ground")
    assert (stopped.t, stopped.active, stopped.reason) == (1.0, False, "stopped")  # run's end


def test_an_active_reflex_holds_back_those_it_inhibits(plugins: ModuleType) -> None:
    r = run_actors(
        reflex_graph({"type": "my_reflexes:Lift"}, {"type": "my_reflexes:ReachDown"}),
        duration=2.0,
        scenario=feed_swings([0.5, 1.0, 1.5]),
        feeds=["swings"],
    )
    senders = [g.source for g in r.messages(OVERRIDES, of=JointGoals)]
    # Lift is active from its first swing on, so ReachDown is held back after the first
    # swing end, which both saw before either had said anything.
    assert senders.count("reflex-lift") == 3
    assert senders.count("reflex-reachdown") <= 1
    held = [m for m in r.messages(ACTIVITY, of=ReflexActivity) if m.reflex == "reflex-reachdown"]
    assert held[-1].inhibited
    assert held[-1].reason == "held back by reflex-lift"


def test_a_reflex_that_keeps_failing_is_disabled_and_the_others_go_on(
    plugins: ModuleType,
) -> None:
    r = run_actors(
        reflex_graph({"type": "my_reflexes:Broken"}, {"type": "my_reflexes:ReachDown"}),
        duration=6.0,
        scenario=feed_swings([0.5 + 0.6 * i for i in range(9)]),
        feeds=["swings"],
    )
    failed = [e for e in r.events(ActorFailed) if e.actor == "reflex-broken"]
    assert len(failed) == 4
    assert all("ZeroDivisionError: a bug in a reflex" in e.error for e in failed)
    (disabled,) = r.events(ActorDisabled)
    assert disabled.actor == "reflex-broken"
    assert r.exit_code == 0
    # The other reflex answered every swing end, before and after.
    assert len(r.messages(OVERRIDES, of=JointGoals)) == 9
