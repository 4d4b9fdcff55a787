"""The command source: scripts, stdin and the keyboard's pure parts.

Scripts run on virtual time and are checked against the runtime clock; the
keyboard's key mapping, key splitting and status line are pure functions and
are tested without a terminal. Reading stdin is tested on a pipe, on real
time, synchronising on the commands it sends.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

import anyio
import pytest

from whexar.actors.commands import (
    GAITS,
    STDIN_ON_VIRTUAL_TIME,
    KeyboardState,
    LineReader,
    key_command,
    load_script,
    parse_command,
    split_keys,
    status_line,
)
from whexar.actors.messages import CommandRefused, LocomotionState, MotionCommand
from whexar.errors import ConfigError
from whexar.runtime.messages import ActorFailed
from whexar.runtime.wiring import WiringError, build_graph
from whexar.testing import Harness, run_actors


def script(tmp_path: Path, *lines: str) -> Path:
    path = tmp_path / "walk.jsonl"
    path.write_text("\n".join(lines) + "\n")
    return path


def graph(source: str) -> dict[str, Any]:
    return {
        "actors": [
            {
                "name": "commands",
                "class": "whexar.actors.commands:CommandSource",
                "params": {"source": source},
                "outputs": {"commands": "motion"},
            },
            {"name": "sink", "class": "whexar.testing:Sink", "inputs": {"inp": "motion"}},
        ],
        "channels": {"motion": {"message": "MotionCommand", "policy": "backpressure"}},
    }


def problems_of(path: Path) -> str:
    with pytest.raises(ConfigError) as caught:
        load_script(path)
    assert caught.value.source == str(path)
    return str(caught.value)


# --------------------------------------------------------------------------- script format


def test_a_script_parses_into_commands_stamped_with_their_times(tmp_path: Path) -> None:
    path = script(
        tmp_path,
        "# forward, then stop",
        "",
        '{"t": 0.0, "vx_m_s": 0.1, "gait": "tripod"}',
        '{"t": 2, "yaw_rate_rad_s": -0.2, "mode": "hybrid", "upside_down": false}',
        '{"t": 5, "stop": true}',
    )
    first, second, third = load_script(path, source="cmd")
    assert first == MotionCommand(t=0.0, source="cmd", vx_m_s=0.1, gait="tripod")
    assert second == MotionCommand(
        t=2.0, source="cmd", yaw_rate_rad_s=-0.2, mode="hybrid", upside_down=False
    )
    assert third.stop
    assert third.t == 5.0
    assert third.vx_m_s is None
    assert isinstance(second.t, float)


def test_an_unknown_key_names_line_key_and_the_allowed_keys(tmp_path: Path) -> None:
    text = problems_of(script(tmp_path, '{"t": 0, "vx_m_s": 0.1}', '{"t": 1, "speed": 0.2}'))
    assert "1 problem" in text
    assert "line 2: speed = 0.2: unknown key; allowed here: t, vx_m_s, vy_m_s" in text
    assert "stop" in text
    assert "source" not in text.split("allowed here:")[1]


def test_a_value_of_the_wrong_type_names_the_expected_type(tmp_path: Path) -> None:
    text = problems_of(
        script(
            tmp_path,
            '{"t": 0, "vx_m_s": "fast"}',
            '{"t": 1, "stop": 1, "gait": "gallop"}',
            '{"t": 2, "vy_m_s": true, "upside_down": "yes"}',
        )
    )
    assert "5 problems" in text
    assert "line 1: vx_m_s = 'fast': a finite number or null" in text
    assert "line 2: stop = 1: true or false" in text
    assert "line 2: gait = 'gallop': one of tripod, tetrapod, ripple, wave, auto or null" in text
    assert "line 3: vy_m_s = True: a finite number or null" in text
    assert "line 3: upside_down = 'yes': true, false or null" in text


def test_time_going_backwards_names_both_lines(tmp_path: Path) -> None:
    text = problems_of(
        script(tmp_path, '{"t": 1}', '{"t": 4, "vx_m_s": 0}', '{"t": 3.5, "vx_m_s": 0.1}')
    )
    assert "line 3: t = 3.5: at least 4, the t of line 2: a script's times never go" in text


def test_a_missing_or_bad_time_is_a_problem(tmp_path: Path) -> None:
    text = problems_of(script(tmp_path, '{"vx_m_s": 0.1}', '{"t": -1}', '{"t": "soon"}'))
    assert "line 1: t = (missing): required key is missing" in text
    assert "line 2: t = -1: a finite number of seconds ≥ 0" in text
    assert "line 3: t = 'soon'" in text


def test_bad_json_names_the_line_and_column(tmp_path: Path) -> None:
    text = problems_of(
        script(tmp_path, '{"t": 0}', "# fine", '{"t": 1, "vx_m_s": 0.1,', "[1, 2]", "NaN")
    )
    assert 'line 3 = \'{"t": 1, "vx_m_s": 0.1,\': a JSON object (Expecting property name' in text
    assert "at column 24" in text
    assert "line 4 = '[1, 2]': a JSON object such as" in text
    assert "line 5 = 'NaN': a JSON object" in text


def test_every_problem_of_the_file_is_listed_at_once(tmp_path: Path) -> None:
    text = problems_of(script(tmp_path, "{", '{"t": 0, "x": 1}', '{"t": 0, "t": 1}'))
    assert text.startswith(f"{tmp_path / 'walk.jsonl'}: 3 problems")
    assert "line 3: t = 1: a key given once per line" in text


def test_a_missing_script_file_is_a_config_error(tmp_path: Path) -> None:
    text = problems_of(tmp_path / "nope.jsonl")
    assert "(file)" in text
    assert "a readable command script (No such file or directory)" in text


def test_a_bad_script_is_a_wiring_problem_before_anything_runs(tmp_path: Path) -> None:
    path = script(tmp_path, '{"t": 0, "vx": 1}')
    with pytest.raises(WiringError) as caught:
        run_actors(graph(str(path)), duration=1.0)
    text = str(caught.value)
    assert f"actors.commands.params.source = '{path}'" in text
    assert "line 1: vx = 1: unknown key" in text


def test_parse_command_checks_a_line_and_ignores_its_time() -> None:
    command = parse_command('{"t": 99, "vx_m_s": 1}', t=2.5, source="stdin")
    assert command == MotionCommand(t=2.5, source="stdin", vx_m_s=1.0)
    with pytest.raises(ConfigError) as caught:
        parse_command('{"vx_m_s": null, "jump": 1}', t=0.0, source="s", where="stdin line 7")
    assert [str(p) for p in caught.value.problems] == [
        "stdin line 7: jump = 1: unknown key; allowed here: t, vx_m_s, vy_m_s, yaw_rate_rad_s, "
        "turn_radius_m, gait, mode, stance, step_height_m, step_length_m, body_height_m, "
        "roll_rad, pitch_rad, upside_down, stop"
    ]


# --------------------------------------------------------------------------- playing a script


def test_a_script_on_virtual_time_delivers_each_command_at_its_time(tmp_path: Path) -> None:
    path = script(
        tmp_path,
        '{"t": 0.0, "vx_m_s": 0.1, "gait": "tripod"}',
        '{"t": 0.25, "yaw_rate_rad_s": 0.3}',
        '{"t": 0.25, "mode": "ride"}',
        '{"t": 3, "stop": true}',
    )
    delivered: list[tuple[float, MotionCommand]] = []

    async def scenario(h: Harness) -> None:
        # Woken by each publish: the clock then reads the time it was published at.
        seen = 0
        while len(delivered) < 4:
            for entry in h.log.entries[seen:]:
                if entry.channel == "motion" and isinstance(entry.message, MotionCommand):
                    delivered.append((h.now(), entry.message))
            seen = len(h.log.entries)
            if len(delivered) < 4:
                await h.log.changed()

    result = run_actors(graph(str(path)), scenario=scenario)
    assert result.exit_code == 0
    assert [(now, c.t) for now, c in delivered] == [(0.0, 0.0), (0.25, 0.25), (0.25, 0.25), (3, 3)]
    assert all(c.source == "commands" for _, c in delivered)
    assert [c for _, c in delivered] == list(load_script(path))
    assert not result.events(ActorFailed)


def test_after_the_last_line_the_script_idles(tmp_path: Path) -> None:
    path = script(tmp_path, '{"t": 0.5, "vx_m_s": 0.1}')
    result = run_actors(graph(str(path)), duration=10.0)
    assert result.exit_code == 0
    assert len(result.messages("motion", of=MotionCommand)) == 1
    assert not result.events(ActorFailed)


def test_the_same_script_gives_the_same_run(tmp_path: Path) -> None:
    path = script(tmp_path, '{"t": 0.1, "vx_m_s": 0.1}', '{"t": 0.2, "stop": true}')
    digests = {run_actors(graph(str(path)), duration=1.0).digest for _ in range(2)}
    assert len(digests) == 1


def test_a_script_broken_after_the_wiring_was_checked_fails_the_start(tmp_path: Path) -> None:
    path = script(tmp_path, '{"t": 0, "vx_m_s": 0.1}')
    built = build_graph(graph(str(path)))
    path.write_text('{"t": 0, "vx_m_s": "fast"}\n')
    result = run_actors(built, duration=0.05)
    failed = result.events(ActorFailed)
    assert failed
    assert failed[0].phase == "start"
    assert "line 1: vx_m_s = 'fast': a finite number or null" in failed[0].error


def test_none_sends_nothing() -> None:
    result = run_actors(graph("none"), duration=5.0)
    assert result.exit_code == 0
    assert result.messages("motion") == []
    assert not result.events(ActorFailed)


# --------------------------------------------------------------------------- stdin


def test_stdin_on_virtual_time_is_one_refusal_not_a_failure() -> None:
    result = run_actors(graph("stdin"), duration=5.0)
    assert result.exit_code == 0
    refused = result.events(CommandRefused)
    assert [(e.command, e.reason) for e in refused] == [("stdin", STDIN_ON_VIRTUAL_TIME)]
    assert not result.events(ActorFailed)
    assert result.messages("motion") == []


def test_stdin_is_the_default_source() -> None:
    spec = graph("stdin")
    del spec["actors"][0]["params"]
    result = run_actors(spec, duration=1.0)
    assert [e.command for e in result.events(CommandRefused)] == ["stdin"]


def test_stdin_lines_become_commands_and_bad_lines_refusals(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    read, write = os.pipe()
    lines = (
        b'{"vx_m_s": 0.1, "t": 123}\n'
        b"\n"
        b"# a comment\n"
        b'{"vx_m_s": "fast"}\n'
        b"not json\n"
        b'{"stop": true}'  # the last line needs no newline
    )
    os.write(write, lines)
    os.close(write)
    with os.fdopen(read, "rb", buffering=0) as stdin:
        monkeypatch.setattr(sys, "stdin", stdin)

        async def scenario(h: Harness) -> None:
            await h.wait_for(MotionCommand, lambda c: c.stop, timeout=5.0)

        result = run_actors(graph("stdin"), scenario=scenario, virtual=False)
    assert result.exit_code == 0
    commands = result.messages("motion", of=MotionCommand)
    assert [(c.vx_m_s, c.stop, c.source) for c in commands] == [
        (0.1, False, "commands"),
        (None, True, "commands"),
    ]
    assert commands[0].t < 5.0  # the time it was read, not the line's own
    refused = result.events(CommandRefused)
    assert [e.command for e in refused] == ['{"vx_m_s": "fast"}', "not json"]
    assert refused[0].reason == "stdin line 4: vx_m_s = 'fast': a finite number or null"
    assert refused[1].reason.startswith("stdin line 5 = 'not json': a JSON object (Expecting")
    assert not result.events(ActorFailed)


def test_the_line_reader_splits_lines_and_refuses_to_grow_without_bound() -> None:
    async def main() -> list[bytes | None]:
        read, write = os.pipe()
        try:
            os.write(write, b"one\ntwo\n" + b"x" * 20 + b"\nthree\nfour")
            os.close(write)
            reader = LineReader(read, limit=8)
            return [await reader.readline() for _ in range(6)]
        finally:
            os.close(read)

    got = anyio.run(main)
    assert got == [b"one", b"two", b"x" * 9, b"three", b"four", None]


def test_the_line_reader_drops_the_rest_of_a_long_line_that_arrives_in_pieces() -> None:
    async def main() -> list[bytes | None]:
        read, write = os.pipe()
        try:
            reader = LineReader(read, limit=8)
            os.write(write, b"x" * 20)
            head = await reader.readline()
            os.write(write, b"yyyyyyyyyyyy\nnext\n")
            os.close(write)
            return [head, await reader.readline(), await reader.readline()]
        finally:
            os.close(read)

    assert anyio.run(main) == [b"x" * 9, b"next", None]


# --------------------------------------------------------------------------- the keyboard


def press(*keys: str, state: KeyboardState | None = None) -> tuple[KeyboardState, MotionCommand]:
    current = state or KeyboardState()
    command: MotionCommand | None = None
    for key in keys:
        current, command = key_command(key, current, t=1.5, source="kb")
    assert command is not None
    return current, command


def test_arrows_and_wasd_step_speed_and_turn_rate() -> None:
    state, command = press("up", "w", "W")
    assert state.vx_m_s == pytest.approx(0.06)
    assert (command.vx_m_s, command.vy_m_s, command.yaw_rate_rad_s) == (state.vx_m_s, 0.0, 0.0)
    assert (command.t, command.source, command.stop) == (1.5, "kb", False)
    state, command = press("down", "s", state=state)
    assert command.vx_m_s == pytest.approx(0.02)
    state, command = press("left", "a", "right", state=state)
    assert command.yaw_rate_rad_s == pytest.approx(0.1)
    state, command = press("d", "d", state=state)
    assert command.yaw_rate_rad_s == pytest.approx(-0.1)
    state, command = press("q", "q", "e", state=state)
    assert command.vy_m_s == pytest.approx(0.02)
    assert (command.vx_m_s, command.yaw_rate_rad_s) == (state.vx_m_s, state.yaw_rate_rad_s)


def test_steps_up_and_down_come_back_to_exactly_zero() -> None:
    state, command = press(*["up"] * 7, *["down"] * 7, *["a"] * 3, *["d"] * 3)
    assert (state.vx_m_s, state.yaw_rate_rad_s) == (0.0, 0.0)
    assert command.vx_m_s == 0.0


def test_speed_keys_stop_at_a_limit() -> None:
    state, _ = press(*["up"] * 200)
    assert state.vx_m_s == 0.5
    state, _ = press("down", state=state)
    assert state.vx_m_s == pytest.approx(0.48)


def test_space_stops_with_zero_velocity() -> None:
    state, _ = press("up", "q", "a")
    state, command = press(" ", state=state)
    assert command.stop
    assert (command.vx_m_s, command.vy_m_s, command.yaw_rate_rad_s) == (0.0, 0.0, 0.0)
    assert (state.vx_m_s, state.vy_m_s, state.yaw_rate_rad_s, state.quit) == (0, 0, 0, False)


def test_x_stops_and_quits() -> None:
    state, command = press("up", "x")
    assert command.stop
    assert command.vx_m_s == 0.0
    assert state.quit


def test_number_keys_choose_the_gait_and_letters_the_mode() -> None:
    gaits = ("tripod", "tetrapod", "ripple", "wave", "auto")
    for key, gait in zip("12340", gaits, strict=True):
        state, command = press(key)
        assert command.gait == gait == state.gait
        assert command.vx_m_s is None
    assert gaits == GAITS
    for key, mode in (("r", "ride"), ("k", "walk"), ("h", "hybrid"), ("H", "hybrid")):
        state, command = press(key)
        assert command.mode == mode == state.mode


def test_plus_minus_step_height_and_f_flips() -> None:
    state, command = press("+", "+", "-", state=KeyboardState(step_height_m=0.06))
    assert command.step_height_m == state.step_height_m == pytest.approx(0.07)
    state, command = press(*["-"] * 30, state=state)
    assert command.step_height_m == 0.01
    state, command = press("f")
    assert command.upside_down is True
    assert state.upside_down
    state, command = press("f", state=state)
    assert command.upside_down is False


def test_other_keys_send_nothing() -> None:
    current = KeyboardState(vx_m_s=0.1)
    for key in ("z", "\x1b", "5", "\n", "page_up"):
        assert key_command(key, current) == (current, None)


def test_split_keys_names_arrows_and_keeps_an_unfinished_sequence() -> None:
    assert split_keys("w\x1b[A\x1b[B\x1b[C\x1b[Dx") == (
        ["w", "up", "down", "right", "left", "x"],
        "",
    )
    assert split_keys("\x1bOA\x1b[1;5D\x1b[5~ ") == (["up", "left", "\x1b", " "], "")
    assert split_keys("a\x1b[") == (["a"], "\x1b[")
    assert split_keys("\x1b") == ([], "\x1b")
    keys, tail = split_keys("\x1b[1;")
    assert (keys, split_keys(tail + "2A")) == ([], (["up"], ""))


def test_the_status_line_shows_the_command_and_the_state() -> None:
    current = KeyboardState(
        vx_m_s=0.1, yaw_rate_rad_s=-0.2, gait="ripple", mode="walk", upside_down=True
    )
    state = LocomotionState(
        t=1.0,
        source="coordinator",
        activity="walking",
        mode="walk",
        gait="ripple",
        stance="normal",
        twist=(0.08, 0.0, -0.15),
        gait_phase=0.3,
        swing_legs=(0, 3),
        margin_m=0.052,
        upside_down=True,
    )
    line = status_line(current, state)
    assert "vx +0.10 vy +0.00 yaw -0.20" in line
    assert "ripple walk step 6 cm flipped" in line
    assert "walking ripple walk twist +0.08 +0.00 -0.15 margin 52 mm swing 0,3" in line
    assert "\n" not in line
    assert "\r" not in line


def test_the_status_line_without_state_and_within_a_width() -> None:
    line = status_line(KeyboardState())
    assert "gait - mode -" in line
    assert "no locomotion state" in line
    assert len(status_line(KeyboardState(), width=40)) == 39
