"""Wiring: a graph is checked before anything runs, and every problem names its place."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from whexar.errors import MISSING, ConfigError, Problem
from whexar.runtime.actor import Actor, Input, Output
from whexar.runtime.channels import Policy
from whexar.runtime.messages import Event, Heartbeat, Message
from whexar.runtime.wiring import (
    EVENTS_CHANNEL,
    RUNTIME,
    WiringError,
    build_graph,
    load_graph,
)
from whexar.testing import Pulse, Sink

PULSE = "whexar.testing:Pulse"
SINK = "whexar.testing:Sink"
RELAY = "whexar.testing:Relay"


class Needs(Actor):
    """An actor with a required input and an optional one, and one optional output."""

    inp = Input(Heartbeat)
    extra = Input(Heartbeat, optional=True)
    out = Output(Heartbeat, optional=True)


NEEDS = f"{__name__}:Needs"


def pulse(name: str, out: str | list[str] = "beats", **params: Any) -> dict[str, Any]:
    return {"name": name, "class": PULSE, "params": params, "outputs": {"out": out}}


def sink(name: str, inp: str = "beats", **params: Any) -> dict[str, Any]:
    return {"name": name, "class": SINK, "params": params, "inputs": {"inp": inp}}


def channel(message: str = "Heartbeat", policy: str = "latest") -> dict[str, Any]:
    return {"message": message, "policy": policy}


def problems(spec: dict[str, Any], **kwargs: Any) -> dict[str, Problem]:
    """The problems ``build_graph`` reports, by path (paths are unique in these tests)."""
    with pytest.raises(WiringError) as info:
        build_graph(spec, **kwargs)
    error = info.value
    assert isinstance(error, ConfigError)
    found = {p.path: p for p in error.problems}
    assert len(found) == len(error.problems), "each test expects one problem per path"
    assert str(error).startswith(f"{kwargs.get('source', '<graph>')}: {len(found)} problem")
    return found


# --------------------------------------------------------------------------- a good graph


def test_a_good_graph_resolves_classes_params_ports_and_channels() -> None:
    graph = build_graph(
        {
            "runtime": {"stop_timeout_s": 0.5, "restart": {"max_restarts": 1}},
            "actors": [
                pulse("p", ["beats", "copy"], period_s=0.5),
                sink("s"),
                {
                    "name": "n",
                    "class": NEEDS,
                    "inputs": {"inp": "copy"},
                    "restart": {"max_restarts": 7, "window_s": 2.0, "delay_s": 0.0},
                },
                {"name": "watch", "class": SINK, "inputs": {"inp": EVENTS_CHANNEL}},
            ],
            "channels": {
                "beats": channel(),
                "copy": {"message": "whexar.runtime.messages:Heartbeat", "policy": "queue"},
            },
        }
    )
    assert [a.name for a in graph.actors] == ["p", "s", "n", "watch"]
    p = graph.actor("p")
    assert p.cls is Pulse
    assert isinstance(p.params, Pulse.Params)
    assert p.params.period_s == 0.5
    assert p.outputs == {"out": ("beats", "copy")}
    assert p.restart.max_restarts == 1  # the runtime's default policy
    assert graph.actor("s").cls is Sink
    assert graph.actor("s").outputs == {"seen": ()}  # optional output left unwired
    n = graph.actor("n")
    assert n.inputs == {"inp": "copy", "extra": None}
    assert n.restart.max_restarts == 7
    assert graph.settings.stop_timeout_s == 0.5
    beats = graph.channels["beats"]
    assert (beats.message_type, beats.policy, beats.capacity) == (Heartbeat, Policy.LATEST, 1)
    assert (beats.publishers, beats.subscribers) == (("p",), ("s",))
    assert graph.channels["copy"].capacity == 256
    events = graph.channels[EVENTS_CHANNEL]
    assert (events.message_type, events.policy, events.capacity) == (Event, Policy.QUEUE, 1024)
    assert (events.publishers, events.subscribers) == ((RUNTIME,), ("watch",))
    with pytest.raises(KeyError):
        graph.actor("nobody")


# --------------------------------------------------------------------------- each problem


def test_unknown_message_type() -> None:
    found = problems({"actors": [pulse("p")], "channels": {"beats": channel("Heartbeet")}})
    assert list(found) == ["channels.beats.message"]
    assert found["channels.beats.message"].value == "Heartbeet"
    assert "registered message type" in found["channels.beats.message"].allowed
    assert "Heartbeat" in found["channels.beats.message"].allowed  # the known ones are listed


def test_message_type_by_path_must_be_a_message() -> None:
    found = problems(
        {
            "actors": [pulse("p"), sink("s")],
            "channels": {"beats": channel("whexar.testing:Pulse")},
        }
    )
    assert "is not a Message" in found["channels.beats.message"].allowed


def test_subscriber_without_publisher() -> None:
    found = problems({"actors": [sink("s")], "channels": {"beats": channel()}})
    assert list(found) == ["channels.beats"]
    text = found["channels.beats"].allowed
    assert "actor 's'" in text
    assert "no actor publishes Heartbeat on channel 'beats'" in text


def test_two_publishers_on_a_backpressure_channel() -> None:
    found = problems(
        {
            "actors": [pulse("p1"), pulse("p2"), sink("s")],
            "channels": {"beats": channel(policy="backpressure")},
        }
    )
    assert list(found) == ["channels.beats.policy"]
    assert found["channels.beats.policy"].value == "backpressure"
    assert "actor 'p1', actor 'p2'" in found["channels.beats.policy"].allowed


def test_two_publishers_on_a_latest_channel_are_fine() -> None:
    graph = build_graph(
        {"actors": [pulse("p1"), pulse("p2"), sink("s")], "channels": {"beats": channel()}}
    )
    assert graph.channels["beats"].publishers == ("p1", "p2")


@pytest.mark.parametrize(
    ("path", "expected"),
    [
        ("no_such_module.here:Thing", "module 'no_such_module.here' cannot be imported"),
        ("whexar.testing:Nope", "module 'whexar.testing' has no 'Nope'"),
        ("whexar.testing:run_actors", "is not a subclass of whexar Actor"),
        (f"{__name__}:Problem", "is not a subclass of whexar Actor"),
        ("whexar.testing.Pulse", "as 'package.module:Name'"),
    ],
)
def test_unknown_actor_class(path: str, expected: str) -> None:
    found = problems({"actors": [{"name": "x", "class": path}]})
    assert list(found) == ["actors.x.class"]
    assert found["actors.x.class"].value == path
    assert expected in found["actors.x.class"].allowed


def test_unknown_ports() -> None:
    found = problems(
        {
            "actors": [
                {"name": "p", "class": PULSE, "outputs": {"out": "beats", "beat": "beats"}},
                {"name": "s", "class": SINK, "inputs": {"inp": "beats", "input": "beats"}},
            ],
            "channels": {"beats": channel()},
        }
    )
    assert set(found) == {"actors.p.outputs.beat", "actors.s.inputs.input"}
    assert found["actors.p.outputs.beat"].allowed.endswith("its outputs: out")
    assert found["actors.s.inputs.input"].allowed.endswith("its inputs: inp")


def test_an_output_named_as_an_input_is_unknown() -> None:
    found = problems(
        {
            "actors": [pulse("p"), {"name": "s", "class": SINK, "outputs": {"inp": "beats"}}],
            "channels": {"beats": channel()},
        }
    )
    # "inp" is an input of Sink, not an output; Sink's required input is also unwired.
    assert found["actors.s.outputs.inp"].allowed.endswith("its outputs: seen")
    assert "required but not wired" in found["actors.s.inputs.inp"].allowed


def test_unknown_channel() -> None:
    found = problems({"actors": [pulse("p"), sink("s", "beatz")], "channels": {"beats": channel()}})
    assert list(found) == ["actors.s.inputs.inp"]
    assert found["actors.s.inputs.inp"].value == "beatz"
    assert "a declared channel (beats, events)" in found["actors.s.inputs.inp"].allowed


def test_type_mismatch_on_input_and_output() -> None:
    found = problems(
        {
            "actors": [
                pulse("p", "ev"),
                sink("s", "beats"),
                {"name": "n", "class": NEEDS, "inputs": {"inp": "msgs"}},
            ],
            "channels": {
                "ev": channel("Event", "queue"),
                "beats": channel(),
                "msgs": channel("Message", "queue"),
            },
        }
    )
    # Pulse publishes Heartbeat, which is not an Event.
    out = found["actors.p.outputs.out"]
    assert out.value == "ev"
    assert out.allowed == "a channel of Heartbeat; channel 'ev' carries Event"
    # Needs.inp wants Heartbeat; a channel of any Message may carry something else.
    inp = found["actors.n.inputs.inp"]
    assert inp.allowed == "a channel of Heartbeat; channel 'msgs' carries Message"


def test_required_ports_must_be_wired_optional_ones_need_not() -> None:
    found = problems(
        {
            "actors": [{"name": "p", "class": PULSE}, {"name": "n", "class": NEEDS}],
        }
    )
    assert set(found) == {"actors.p.outputs.out", "actors.n.inputs.inp"}
    assert found["actors.p.outputs.out"].value is None
    assert "output 'out' of actor 'p' is required" in found["actors.p.outputs.out"].allowed
    assert "input 'inp' of actor 'n' is required" in found["actors.n.inputs.inp"].allowed


def test_unused_channel() -> None:
    found = problems(
        {"actors": [pulse("p"), sink("s")], "channels": {"beats": channel(), "spare": channel()}}
    )
    assert list(found) == ["channels.spare"]
    assert "no actor wires it" in found["channels.spare"].allowed


def test_duplicate_actor_name() -> None:
    found = problems(
        {"actors": [pulse("twin"), {**sink("twin")}], "channels": {"beats": channel()}}
    )
    assert list(found) == ["actors.twin.name"]
    assert found["actors.twin.name"].value == "twin"


def test_bad_params_are_reported_under_the_actor() -> None:
    found = problems(
        {
            "actors": [pulse("p", period_s=-1.0, bogus=2), sink("s", delay_s="slow")],
            "channels": {"beats": channel()},
        }
    )
    assert set(found) == {
        "actors.p.params.period_s",
        "actors.p.params.bogus",
        "actors.s.params.delay_s",
    }
    assert found["actors.p.params.period_s"].value == -1.0
    assert "greater than 0" in found["actors.p.params.period_s"].allowed
    assert found["actors.p.params.bogus"].allowed.startswith("unknown key; allowed here: period_s")
    assert found["actors.s.params.delay_s"].value == "slow"


def test_structural_errors_are_mapped_to_actor_names() -> None:
    found = problems(
        {
            "runtime": {"stop_timeout_s": 0},
            "actors": [
                {"name": "p", "class": PULSE, "restart": {"max_restarts": -1}},
                {"name": "s", "klass": SINK},
                {"class": SINK},
            ],
            "channels": {"beats": channel(policy="sometimes")},
        }
    )
    assert set(found) == {
        "runtime.stop_timeout_s",
        "actors.p.restart.max_restarts",
        "actors.s.class",
        "actors.s.klass",
        "actors[2].name",  # no name to map to: the index stays
        "channels.beats.policy",
    }
    assert found["actors.s.class"].value is MISSING
    assert found["actors.s.klass"].allowed.startswith("unknown key")
    assert "name, class, params" in found["actors.s.klass"].allowed  # the alias, as written
    assert "'latest', 'backpressure' or 'queue'" in found["channels.beats.policy"].allowed


def test_bad_names_are_refused() -> None:
    found = problems({"actors": [pulse("has space")], "channels": {"be ats": channel()}})
    assert len(found) == 2
    assert 'actors."has space".name' in found
    assert found['channels."be ats"'].allowed.startswith("a valid key name:")
    assert all("should match pattern" in p.allowed for p in found.values())


def test_a_bad_port_or_class_does_not_also_blame_its_channel() -> None:
    # The channel lacks a publisher only because the publisher's port is
    # wrong (or its class is unknown): one problem each, not two.
    mismatch = problems(
        {
            "actors": [pulse("p", out="acks"), sink("s", inp="acks")],
            "channels": {"acks": channel(message="ActorReady")},
        }
    )
    assert list(mismatch) == ["actors.p.outputs.out"]
    unknown = problems(
        {
            "actors": [
                {"name": "p", "class": "whexar.testing:Pulsar", "outputs": {"out": "beats"}},
                sink("s"),
            ],
            "channels": {"beats": channel()},
        }
    )
    assert list(unknown) == ["actors.p.class"]


def test_events_is_reserved() -> None:
    found = problems(
        {
            "actors": [pulse("p", EVENTS_CHANNEL), sink("s", EVENTS_CHANNEL)],
            "channels": {EVENTS_CHANNEL: channel()},
        }
    )
    assert set(found) == {"channels.events", "actors.p.outputs.out"}
    assert "other than the built-in 'events'" in found["channels.events"].allowed
    assert "only the runtime publishes there" in found["actors.p.outputs.out"].allowed


def test_several_problems_are_reported_at_once() -> None:
    found = problems(
        {
            "actors": [
                pulse("p", period_s=0),
                {"name": "x", "class": "nowhere:Actor"},
                sink("s", "missing"),
                sink("s"),
            ],
            "channels": {"beats": channel("Nothing"), "idle": channel()},
        },
        source="robot.toml",
    )
    assert set(found) == {
        "channels.beats.message",
        "actors.p.params.period_s",
        "actors.x.class",
        "actors.s.inputs.inp",
        "actors.s.name",
        "channels.idle",
    }


def test_external_publishers() -> None:
    graph = build_graph(
        {"actors": [sink("s", "cmd")], "channels": {"cmd": channel(policy="backpressure")}},
        external={"cmd": "harness"},
    )
    assert graph.channels["cmd"].publishers == ("harness",)
    found = problems(
        {"actors": [sink("s", "cmd")], "channels": {"cmd": channel()}},
        external={"cmd": "harness", "nowhere": "harness"},
    )
    assert list(found) == ["channels.nowhere"]
    assert found["channels.nowhere"].value is MISSING
    assert "fed by harness" in found["channels.nowhere"].allowed


# --------------------------------------------------------------------------- TOML files

GOOD_TOML = """
[runtime]
stop_timeout_s = 0.25

[[actors]]
name = "pulse"
class = "whexar.testing:Pulse"
params = { period_s = 0.01 }
outputs = { out = "beats" }

[[actors]]
name = "sink"
class = "whexar.testing:Sink"
inputs = { inp = "beats" }

[channels.beats]
message = "Heartbeat"
policy = "queue"
capacity = 4
"""


def test_load_graph_from_toml(tmp_path: Path) -> None:
    path = tmp_path / "graph.toml"
    path.write_text(GOOD_TOML)
    graph = load_graph(path)
    assert [a.name for a in graph.actors] == ["pulse", "sink"]
    assert graph.settings.stop_timeout_s == 0.25
    assert graph.channels["beats"].capacity == 4
    assert graph.channels["beats"].policy is Policy.QUEUE


def test_load_graph_names_the_file_in_wiring_errors(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(GOOD_TOML.replace('inp = "beats"', 'inp = "beets"'))
    with pytest.raises(WiringError) as info:
        load_graph(path)
    assert info.value.source == str(path)
    assert [p.path for p in info.value.problems] == ["actors.sink.inputs.inp"]
    assert str(info.value).startswith(f"{path}: 1 problem")


def test_load_graph_reports_toml_syntax_errors(tmp_path: Path) -> None:
    path = tmp_path / "broken.toml"
    path.write_text(GOOD_TOML.replace('name = "sink"', "name = sink"))
    with pytest.raises(ConfigError) as info:
        load_graph(path)
    assert not isinstance(info.value, WiringError)
    assert info.value.source == str(path)
    assert len(info.value.problems) == 1


def test_load_graph_reports_a_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError) as info:
        load_graph(tmp_path / "absent.toml")
    assert info.value.problems[0].path == "(file)"


def test_messages_of_a_subtype_fit_an_input_of_the_base_type() -> None:
    graph = build_graph(
        {
            "actors": [pulse("p"), sink("s")],
            "channels": {"beats": channel("Heartbeat")},
        }
    )
    assert issubclass(graph.channels["beats"].message_type, Message)
    assert Sink.ports()["inp"].message_type is Message
