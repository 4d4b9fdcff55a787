"""``whexar run --set``, ``--commands`` and ``--keyboard``, on a small graph of their own.

Each test writes a wiring file with a command source feeding a sink to
``tmp_path`` and runs it on virtual time through :func:`whexar.cli.main`.
"""

from __future__ import annotations

import argparse
import textwrap
from pathlib import Path
from typing import Any

import pytest

from whexar.cli import main
from whexar.cli.run import assignment, toml_value
from whexar.errors import ConfigError
from whexar.runtime.wiring import set_param

GRAPH = """
[[actors]]
name = "commands"
class = "whexar.actors.commands:CommandSource"
params = { source = "none" }
outputs = { commands = "motion" }

[[actors]]
name = "sink"
class = "whexar.testing:Sink"
inputs = { inp = "motion" }

[channels.motion]
message = "MotionCommand"
policy = "backpressure"
"""


def wiring(tmp_path: Path, text: str = GRAPH) -> Path:
    path = tmp_path / "graph.toml"
    path.write_text(textwrap.dedent(text))
    return path


def write_script(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "walk.jsonl"
    path.write_text(textwrap.dedent(text).lstrip())
    return path


def run(*argv: str) -> int:
    return main(["run", *argv, "--virtual", "--duration", "2"])


def test_set_overrides_a_param_before_the_graph_is_built(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    graph = wiring(tmp_path)
    assert run(str(graph), "--set", "commands.source=stdin") == 0
    out = capsys.readouterr().out
    assert "CommandRefused  command='stdin', reason='stdin is not read on virtual time" in out


def test_set_values_are_read_as_toml_and_checked_with_the_wiring(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    graph = wiring(tmp_path)
    assert run(str(graph), "--set", "sink.stop_after=1", "--set", "sink.delay_s=0.5") == 0
    capsys.readouterr()
    assert run(str(graph), "--set", "sink.delay_s=slow") == 1
    err = capsys.readouterr().err
    assert "actors.sink.params.delay_s = 'slow'" in err
    assert toml_value("3") == 3
    assert toml_value("true") is True
    assert toml_value('"3"') == "3"
    assert toml_value("/dev/ttyUSB0") == "/dev/ttyUSB0"
    assert toml_value("[1, 2]") == [1, 2]


def test_set_an_unknown_actor_lists_the_actors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert run(str(wiring(tmp_path)), "--set", "legs.speed=3") == 1
    err = capsys.readouterr().err
    assert "--set = 'legs.speed'" in err
    assert "its actors: commands, sink" in err


def test_set_needs_actor_param_and_value(capsys: pytest.CaptureFixture[str]) -> None:
    for bad in ("commands", "commands.source", ".source=x", "commands.=x"):
        with pytest.raises(argparse.ArgumentTypeError):
            assignment(bad)
    with pytest.raises(SystemExit) as exc:
        main(["run", "graph.toml", "--set", "nodot=1"])
    assert exc.value.code == 2
    assert "expected ACTOR.PARAM=VALUE" in capsys.readouterr().err


def test_set_param_takes_the_longest_actor_name_and_nested_tables() -> None:
    data: dict[str, Any] = {
        "actors": [
            {"name": "leg", "class": "x:Y"},
            {"name": "leg.front", "class": "x:Y", "params": {"gains": {"p": 1}}},
        ]
    }
    set_param(data, "leg.front.gains.p", 2, source="g.toml")
    set_param(data, "leg.speed", 0.1, source="g.toml")
    assert data["actors"][1]["params"] == {"gains": {"p": 2}}
    assert data["actors"][0]["params"] == {"speed": 0.1}
    with pytest.raises(ConfigError, match=r"actors\.leg\.params\.speed is not a table"):
        set_param(data, "leg.speed.x", 1, source="g.toml")


def test_commands_plays_a_script_on_virtual_time(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    script = write_script(
        tmp_path,
        """
        {"t": 0.5, "vx_m_s": 0.1}
        {"t": 1.0, "stop": true}
        """,
    )
    graph = wiring(tmp_path)
    assert run(str(graph), "--commands", str(script), "--set", "sink.stop_after=2") == 0
    out = capsys.readouterr().out
    assert "stopped: sink: consumed 2 messages" in out
    assert "channel motion: 2 published" in out


def test_commands_with_a_bad_script_lists_its_problems(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    script = write_script(tmp_path, '{"t": 1}\n{"t": 0, "vx": 1}\n')
    assert run(str(wiring(tmp_path)), "--commands", str(script)) == 1
    err = capsys.readouterr().err
    assert "line 2: vx = 1: unknown key; allowed here: t, vx_m_s" in err
    assert "line 2: t = 0: at least 1, the t of line 1" in err


def test_commands_needs_an_existing_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    missing = tmp_path / "nope.jsonl"
    assert run(str(wiring(tmp_path)), "--commands", str(missing)) == 1
    assert f"--commands = '{missing}': an existing command script file" in capsys.readouterr().err


def test_commands_needs_an_actor_named_commands(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    graph = wiring(tmp_path, GRAPH.replace('name = "commands"', 'name = "driver"'))
    script = write_script(tmp_path, '{"t": 0, "stop": true}\n')
    assert run(str(graph), "--commands", str(script)) == 1
    err = capsys.readouterr().err
    assert "--commands = 'commands': a graph with an actor named 'commands'" in err
    assert "its actors: driver, sink" in err


def test_keyboard_refuses_virtual_time(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert run(str(wiring(tmp_path)), "--keyboard") == 2
    err = capsys.readouterr().err
    assert "--keyboard reads a person's keys in real time; it cannot run with --virtual" in err


def test_keyboard_needs_a_terminal(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # Under pytest stdin is no terminal.
    assert main(["run", str(wiring(tmp_path)), "--keyboard", "--duration", "1"]) == 2
    assert "--keyboard needs a terminal on stdin" in capsys.readouterr().err


def test_commands_and_keyboard_exclude_each_other(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["run", str(wiring(tmp_path)), "--keyboard", "--commands", "x.jsonl"])
    assert exc.value.code == 2
    assert "not allowed with argument" in capsys.readouterr().err


def _run_args(graph: Path, config: Path | None, *sets: str) -> argparse.Namespace:
    return argparse.Namespace(
        graph=graph,
        set=[assignment(s) for s in sets],
        commands=None,
        keyboard=False,
        gamepad=None,
        virtual=True,
        config=config,
    )


def test_config_reaches_every_actor_that_reads_the_robot_configuration(tmp_path: Path) -> None:
    from whexar.cli.run import load_run_graph

    config = tmp_path / "robot.toml"
    config.write_text("[imu]\naccel_offset_g = [0.01, 0.0, 0.0]\n")
    walk = Path(__file__).resolve().parents[2] / "config" / "graphs" / "walk.toml"
    other = tmp_path / "other.toml"
    other.write_text("")
    graph = load_run_graph(_run_args(walk, config, f"imu.config={other}"))
    configured = {n.name for n in graph.actors if getattr(n.params, "config", None)}
    legs = {f"leg-{leg}" for leg in ("RF", "LF", "RM", "LM", "RR", "LR")}
    assert {"bus", "sensors", "coordinator", "commands", *legs} <= configured
    for name in configured - {"imu"}:
        assert str(graph.actor(name).params.config) == str(config)  # type: ignore[attr-defined]
    assert str(graph.actor("imu").params.config) == str(other)  # type: ignore[attr-defined]


def test_config_that_is_wrong_or_has_no_taker_is_named(tmp_path: Path) -> None:
    from whexar.cli.run import load_run_graph

    bad = tmp_path / "robot.toml"
    bad.write_text("[imu]\naccel_offset_g = [0.0, 0.9, 0.0]\n")
    walk = Path(__file__).resolve().parents[2] / "config" / "graphs" / "walk.toml"
    with pytest.raises(ConfigError) as err:
        load_run_graph(_run_args(walk, bad))
    assert "imu.accel_offset_g" in str(err.value)
    good = tmp_path / "good.toml"
    good.write_text("")
    small = tmp_path / "small.toml"
    small.write_text(GRAPH.replace('name = "commands"', 'name = "cmd"'))
    with pytest.raises(ConfigError) as err:
        load_run_graph(_run_args(small, good))
    assert "--config" in str(err.value)


def test_run_gamepad_refuses_virtual_time(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    graph = wiring(tmp_path)
    assert main(["run", str(graph), "--gamepad", "--virtual", "--duration", "1"]) == 2
    assert "--gamepad reads a person's gamepad in real time" in capsys.readouterr().err


def test_run_gamepad_sets_the_command_source(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from whexar.runtime.devices import DEVICES
    from whexar.sensors.evdev_link import EVENT_PIPE, EventPipe

    graph = wiring(tmp_path)
    events = EventPipe()
    argv = ["run", str(graph), "--gamepad", "pipe:pad", "--duration", "0.2", "--no-record"]
    with DEVICES.registered(EVENT_PIPE, "pad", events):
        assert main(argv) == 0
    events.close()
    out = capsys.readouterr().out
    assert "GamepadLinkUp   link='pipe:pad', name=''" in out
