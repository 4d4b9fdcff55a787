"""The gamepad: its records decoded, its mapping as a plain class, and the actor on a pipe.

The recorded bytes are made here with ``struct`` from the layout of linux/input.h
(:func:`recorded`), independently of the codec, in both record sizes: 24 bytes
(a 64-bit process) and 16 (32-bit Raspberry Pi OS). The actor reads them from an
``os.pipe()`` (:class:`~whexar.sensors.evdev_link.EventPipe`) on virtual time:
the scenario writes into the pipe at chosen times and the loop polls the pipe
before every jump of time, so every run is the same. Real I/O is allowed for
it (a pipe is a descriptor the loop watches).
"""

from __future__ import annotations

import math
import struct
import sys
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import pytest

from whexar.actors.commands import MODES, AxisRange, GamepadMapping, GamepadPolicy
from whexar.actors.commands.gamepad import choose_mapping
from whexar.actors.messages import (
    GamepadEventsDropped,
    GamepadLayoutUnknown,
    GamepadLinkDown,
    GamepadLinkHeard,
    GamepadLinkSilent,
    GamepadLinkUp,
    MotionCommand,
)
from whexar.config import GamepadSpec, RobotConfig, parse_config
from whexar.config.gamepad import MODES as CONFIG_MODES
from whexar.errors import ConfigError
from whexar.runtime.clock import VirtualTimeRealIOError
from whexar.runtime.devices import DEVICES
from whexar.runtime.messages import ActorFailed
from whexar.sensors.evdev import (
    ABS_CODES,
    ABS_HAT0X,
    ABS_HAT0Y,
    ABS_RX,
    ABS_RZ,
    ABS_X,
    ABS_Y,
    BTN_EAST,
    BTN_NORTH,
    BTN_SELECT,
    BTN_SOUTH,
    BTN_START,
    BTN_TL,
    BTN_TR,
    EV_ABS,
    EV_KEY,
    EV_MSC,
    EV_SYN,
    KEY_CODES,
    NATIVE_RECORD_BYTES,
    RECORD_32,
    RECORD_64,
    SYN_DROPPED,
    SYN_REPORT,
    AbsInfo,
    Dropped,
    EventDecoder,
    InputEvent,
    Report,
    encode,
    eviocgabs,
    eviocgkey,
    eviocgname,
    keys_held,
)
from whexar.sensors.evdev_link import EVENT_PIPE, EventDevice, EventPipe
from whexar.testing import Harness, run_actors

FULL = 32767  # xpad's stick range is -32768..32767
Event3 = tuple[int, int, int]

# --------------------------------------------------------------------------- recorded bytes


def recorded(record_bytes: int, *reports: Iterable[Event3], t0: int = 1_700_000_000) -> bytes:
    """Reports as the kernel writes them: each event one ``struct input_event``, each report
    closed by EV_SYN/SYN_REPORT, 10 ms apart. Packed here from linux/input.h's layout,
    not by the codec under test."""
    order = "<" if sys.byteorder == "little" else ">"
    # struct timeval of a 64-bit process (two 8-byte longs) or of a 32-bit one (4 bytes each)
    layout = struct.Struct(order + ("qqHHi" if record_bytes == 24 else "LLHHi"))
    out = b""
    for i, report in enumerate(reports):
        sec, usec = t0 + i // 100, (i % 100) * 10_000
        for kind, code, value in [*report, (EV_SYN, SYN_REPORT, 0)]:
            out += layout.pack(sec, usec, kind, code, value)
    return out


SESSION: tuple[list[Event3], ...] = (
    [(EV_KEY, BTN_TL, 1)],  # the dead-man down
    [(EV_ABS, ABS_Y, -FULL), (EV_MSC, 4, 0x90001)],  # full ahead (and a scan code)
    [(EV_KEY, BTN_SOUTH, 1)],  # A: walk
    [(EV_KEY, BTN_SOUTH, 0)],
    [(EV_KEY, BTN_TL, 0)],  # the dead-man let go
)
"""A short drive: dead-man, stick forward, a button, dead-man let go."""


@pytest.mark.parametrize("size", [RECORD_32, RECORD_64])
def test_recorded_records_decode_in_both_layouts(size: int) -> None:
    data = recorded(size, *SESSION)
    assert len(data) == size * (6 + 5)  # six events, five SYN_REPORTs
    items = EventDecoder(size).feed(data)
    assert [tuple(e[:3] for e in item.events) for item in items if isinstance(item, Report)] == [
        ((EV_KEY, BTN_TL, 1),),
        ((EV_ABS, ABS_Y, -FULL), (EV_MSC, 4, 0x90001)),
        ((EV_KEY, BTN_SOUTH, 1),),
        ((EV_KEY, BTN_SOUTH, 0),),
        ((EV_KEY, BTN_TL, 0),),
    ]
    first = items[1]
    assert isinstance(first, Report)
    assert first.events[0].time_s == pytest.approx(1_700_000_000.01)


def test_the_other_layout_does_not_decode_as_this_one() -> None:
    # 24-byte records read as 16-byte ones: garbage, not the same events.
    items = EventDecoder(RECORD_32).feed(recorded(RECORD_64, *SESSION))
    events = [e[:3] for item in items if isinstance(item, Report) for e in item.events]
    assert (EV_KEY, BTN_TL, 1) not in events


def test_the_native_record_is_two_longs_and_eight_bytes() -> None:
    assert struct.calcsize("@l") * 2 + 8 == NATIVE_RECORD_BYTES
    assert (RECORD_64 if sys.maxsize > 2**32 else RECORD_32) == NATIVE_RECORD_BYTES
    with pytest.raises(ValueError, match="16 or 24 bytes, not 20"):
        EventDecoder(20)


@pytest.mark.parametrize("size", [RECORD_32, RECORD_64])
def test_records_cut_anywhere_decode_the_same(size: int) -> None:
    data = recorded(size, *SESSION)
    whole = EventDecoder(size).feed(data)
    decoder = EventDecoder(size)
    byte_by_byte = [item for i in range(len(data)) for item in decoder.feed(data[i : i + 1])]
    assert byte_by_byte == whole
    events = [InputEvent(EV_KEY, BTN_TL, 1, 5, 7), InputEvent(EV_SYN, SYN_REPORT, 0, 5, 7)]
    assert EventDecoder(size).feed(encode(events, size)) == [Report((events[0],))]


def test_syn_dropped_discards_up_to_the_next_report() -> None:
    data = recorded(
        RECORD_64,
        [(EV_ABS, ABS_X, 100)],
    ) + encode(
        [
            InputEvent(EV_ABS, ABS_Y, 5),  # an unfinished report, then the overrun
            InputEvent(EV_SYN, SYN_DROPPED, 0),
            InputEvent(EV_KEY, BTN_TL, 0),  # thrown away, up to and with the SYN_REPORT
            InputEvent(EV_ABS, ABS_X, 7),
            InputEvent(EV_SYN, SYN_REPORT, 0),
            InputEvent(EV_ABS, ABS_X, 9),
            InputEvent(EV_SYN, SYN_REPORT, 0),
        ],
        RECORD_64,
    )
    items = EventDecoder(RECORD_64).feed(data)
    assert [type(i).__name__ for i in items] == ["Report", "Dropped", "Report"]
    assert items[1] == Dropped(discarded=3)
    assert isinstance(items[2], Report)
    assert items[2].events[0][:3] == (EV_ABS, ABS_X, 9)


def test_codes_and_ioctl_numbers_are_the_kernels() -> None:
    # input-event-codes.h, and the numbers strace shows for evtest on x86-64 and ARM.
    assert (KEY_CODES["BTN_SOUTH"], KEY_CODES["BTN_A"], KEY_CODES["BTN_EAST"]) == (0x130,) * 2 + (
        0x131,
    )
    assert (KEY_CODES["BTN_NORTH"], KEY_CODES["BTN_X"], KEY_CODES["BTN_WEST"]) == (
        0x133,
        0x133,
        0x134,
    )
    assert (BTN_TL, BTN_TR, BTN_SELECT, BTN_START) == (0x136, 0x137, 0x13A, 0x13B)
    assert (ABS_X, ABS_Y, ABS_RX, ABS_HAT0X, ABS_HAT0Y) == (0, 1, 3, 0x10, 0x11)
    assert ABS_CODES["ABS_HAT3Y"] == 0x17
    assert KEY_CODES["BTN_TRIGGER_HAPPY40"] == 0x2E7
    assert eviocgabs(ABS_X) == 0x80184540
    assert eviocgabs(ABS_HAT0Y) == 0x80184551
    assert eviocgname(256) == 0x81004506
    assert eviocgkey(96) == 0x80604518
    assert keys_held(bytes([0] * 38 + [0b0100_0001] + [0] * 57)) == {0x130, 0x136}


# --------------------------------------------------------------------------- the policy


def mapping(**changes: Any) -> GamepadMapping:
    spec = RobotConfig().gamepad.model_copy(update=changes)
    return GamepadMapping.from_config(spec)


def pad(**changes: Any) -> GamepadPolicy:
    policy = GamepadPolicy(mapping(**changes), source="pad")
    policy.connected(0.0)
    return policy


def press(policy: GamepadPolicy, *events: Event3, t: float = 1.0) -> list[MotionCommand]:
    return policy.report(t, [InputEvent(*e) for e in events])


def velocity(command: MotionCommand) -> tuple[float | None, float | None, float | None]:
    return (command.vx_m_s, command.vy_m_s, command.yaw_rate_rad_s)


DEAD_MAN = (EV_KEY, BTN_TL, 1)


def test_the_sticks_give_forward_sideways_and_turn_at_full_travel() -> None:
    policy = pad()
    assert press(policy, DEAD_MAN) == []  # held, sticks centred: nothing changes
    (command,) = press(policy, (EV_ABS, ABS_Y, -FULL - 1), t=2.0)  # left stick up
    assert velocity(command) == (0.2, 0.0, 0.0)
    assert (command.t, command.source, command.stop) == (2.0, "pad", False)
    (command,) = press(policy, (EV_ABS, ABS_Y, FULL), (EV_ABS, ABS_X, -FULL - 1))
    assert velocity(command) == (-0.2, 0.1, 0.0)  # back, and to the left (+y)
    (command,) = press(policy, (EV_ABS, ABS_RX, -FULL - 1))  # right stick left
    assert command.yaw_rate_rad_s == pytest.approx(math.radians(30))
    (command,) = press(policy, (EV_ABS, ABS_RX, FULL), (EV_ABS, ABS_X, 0), (EV_ABS, ABS_Y, 0))
    assert (command.vx_m_s, command.vy_m_s) == (0.0, 0.0)
    assert command.yaw_rate_rad_s == pytest.approx(-math.radians(30))


def test_the_dead_zone_reads_as_zero_and_the_speed_rises_from_its_edge() -> None:
    policy = pad()
    press(policy, DEAD_MAN)
    assert press(policy, (EV_ABS, ABS_Y, -int(0.19 * FULL))) == []  # inside 20 %
    (command,) = press(policy, (EV_ABS, ABS_Y, -int(0.6 * FULL)))
    # (0.6 - 0.2) / (1 - 0.2) = half speed
    assert command.vx_m_s == pytest.approx(0.1)
    (command,) = press(policy, (EV_ABS, ABS_Y, 300))  # back near the centre: exactly zero
    assert velocity(command) == (0.0, 0.0, 0.0)
    assert not command.stop


def test_a_sticks_jitter_sends_nothing() -> None:
    policy = pad()
    press(policy, DEAD_MAN)
    (first,) = press(policy, (EV_ABS, ABS_Y, -int(0.6 * FULL)))
    wobble = [-int(0.6 * FULL) + d for d in (150, -200, 320, -90, 250)]
    assert [press(policy, (EV_ABS, ABS_Y, v)) for v in wobble] == [[]] * 5
    (command,) = press(policy, (EV_ABS, ABS_Y, -int(0.8 * FULL)))
    assert command.vx_m_s == pytest.approx(0.15)  # (0.8 - 0.2) / 0.8 = 0.75 of full speed
    assert first.vx_m_s != command.vx_m_s


def test_the_device_range_normalises_a_playstation_stick() -> None:
    policy = GamepadPolicy(mapping(), source="pad")
    policy.connected(0.0, ranges={ABS_Y: AxisRange(0, 255)}, values={ABS_Y: 128})
    press(policy, DEAD_MAN)
    (command,) = press(policy, (EV_ABS, ABS_Y, 0))
    assert command.vx_m_s == 0.2
    assert press(policy, (EV_ABS, ABS_Y, 127)) != []  # back to rest: zero velocity


def test_letting_go_of_the_dead_man_stops_and_then_nothing_drives() -> None:
    policy = pad()
    press(policy, DEAD_MAN, (EV_ABS, ABS_Y, -FULL))
    (stop,) = press(policy, (EV_KEY, BTN_TL, 0))
    assert stop.stop
    assert velocity(stop) == (0.0, 0.0, 0.0)
    assert press(policy, (EV_ABS, ABS_X, FULL)) == []  # sticks do nothing now
    assert press(policy, (EV_KEY, BTN_SOUTH, 1)) == []  # nor buttons but stop
    (again,) = press(policy, (EV_KEY, BTN_EAST, 1))
    assert again.stop
    (command,) = press(policy, DEAD_MAN)  # held again: the sticks as they are now
    assert velocity(command) == (0.2, -0.1, 0.0)


def test_buttons_choose_gait_mode_stance_and_flip_on_the_press() -> None:
    policy = pad()
    press(policy, DEAD_MAN)
    got = [
        press(policy, e)
        for e in [
            (EV_KEY, BTN_SOUTH, 1),
            (EV_KEY, BTN_SOUTH, 2),  # the kernel's auto-repeat: nothing
            (EV_KEY, BTN_SOUTH, 0),  # the release: nothing
            (EV_KEY, BTN_NORTH, 1),
            (EV_ABS, ABS_HAT0Y, -1),  # d-pad up
            (EV_ABS, ABS_HAT0Y, 0),
            (EV_ABS, ABS_HAT0X, -1),  # d-pad left
            (EV_KEY, BTN_TR, 1),
            (EV_ABS, ABS_RZ, 250),  # right trigger pulled
            (EV_KEY, BTN_SELECT, 1),
            (EV_KEY, BTN_SELECT, 0),
            (EV_KEY, BTN_SELECT, 1),
        ]
    ]
    fields = [
        {k: getattr(c, k) for k in ("gait", "mode", "stance", "upside_down") if getattr(c, k)}
        | ({"upside_down": c.upside_down} if c.upside_down is not None else {})
        for cmds in got
        for c in cmds
    ]
    assert [len(cmds) for cmds in got] == [1, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1]
    assert fields == [
        {"mode": "walk"},
        {"mode": "ride"},
        {"gait": "tripod"},
        {"gait": "wave"},
        {"stance": "high"},
        {"stance": "low"},
        {"upside_down": True},
        {"upside_down": False},
    ]
    assert MODES == CONFIG_MODES


def test_a_stop_holds_until_the_sticks_come_back_to_the_centre() -> None:
    policy = pad()
    press(policy, DEAD_MAN, (EV_ABS, ABS_Y, -FULL))
    (stop,) = press(policy, (EV_KEY, BTN_EAST, 1))
    assert stop.stop
    assert press(policy, (EV_ABS, ABS_Y, -FULL + 9000)) == []  # still off centre: stopped
    assert press(policy, (EV_ABS, ABS_Y, 0)) == []  # centred: free again, nothing to send
    (command,) = press(policy, (EV_ABS, ABS_Y, -FULL))
    assert command.vx_m_s == 0.2


def test_a_dead_man_held_when_the_pad_is_opened_counts_only_once_pressed_again() -> None:
    # The left trigger as the dead-man, pulled when the pad was plugged in.
    policy = GamepadPolicy(mapping(dead_man="ABS_Z+"), source="pad")
    policy.connected(0.0, values={ABS_Y: -FULL, 2: 255})
    assert press(policy, (EV_ABS, 2, 250)) == []
    assert press(policy, (EV_ABS, 2, 0)) == []  # let go
    (command,) = press(policy, (EV_ABS, 2, 255))  # pulled again: drives
    assert command.vx_m_s == 0.2


def test_silence_is_watched_only_while_the_pad_drives() -> None:
    policy = pad()
    press(policy, DEAD_MAN, t=1.0)
    assert policy.silence_deadline() is None  # held, but standing still
    press(policy, (EV_ABS, ABS_Y, -FULL), t=3.0)
    assert policy.silence_deadline() == 5.0
    (stop,) = policy.silence(5.0)
    assert stop.stop
    assert policy.silent
    assert policy.silence_deadline() is None
    (command,) = press(policy, (EV_ABS, ABS_X, 10), t=6.0)  # the pad speaks: it drives again
    assert command.vx_m_s == 0.2
    assert not policy.silent


def test_a_drop_without_the_devices_state_forgets_the_dead_man() -> None:
    policy = pad()
    press(policy, DEAD_MAN, (EV_ABS, ABS_Y, -FULL))
    (stop,) = policy.dropped(2.0)
    assert stop.stop
    assert press(policy, (EV_ABS, ABS_Y, -FULL + 1)) == []  # not armed until pressed again
    (command,) = press(policy, DEAD_MAN)
    assert command.vx_m_s == 0.2


def test_a_drop_with_the_devices_state_takes_it() -> None:
    policy = pad()
    press(policy, DEAD_MAN, (EV_ABS, ABS_Y, -FULL))
    (command,) = policy.dropped(2.0, keys={BTN_TL, BTN_SOUTH}, values={ABS_Y: -int(0.6 * FULL)})
    assert command.vx_m_s == pytest.approx(0.1)  # held all along: slower now; no walk press
    (stop,) = policy.dropped(3.0, keys=set(), values={})
    assert stop.stop  # let go during the drop


def test_a_lost_pad_stops_once() -> None:
    policy = pad()
    press(policy, DEAD_MAN, (EV_ABS, ABS_Y, -FULL))
    (stop,) = policy.lost(2.0)
    assert stop.stop
    assert policy.lost(3.0) == []
    assert policy.last_heard is None


# --------------------------------------------------------------------------- configuration


def problems(gamepad: dict[str, Any]) -> dict[str, str]:
    with pytest.raises(ConfigError) as caught:
        parse_config({"gamepad": gamepad}, "pad.toml")
    return {p.path: str(p) for p in caught.value.problems}


def test_the_default_mapping_is_the_shipped_files() -> None:
    spec = RobotConfig().gamepad
    assert isinstance(spec, GamepadSpec)
    assert spec.dead_man == "BTN_TL"
    built = GamepadMapping.from_config(spec)
    assert built.axes == {ABS_Y, ABS_X, ABS_RX, ABS_HAT0X, ABS_HAT0Y, ABS_RZ}
    assert built.record_bytes == NATIVE_RECORD_BYTES


def test_a_bad_mapping_names_key_value_and_what_is_allowed() -> None:
    found = problems(
        {
            "dead_man": "BTN_FOO",
            "record_bytes": 20,
            "forward": {"axis": "ABS_Q"},
            "buttons": {"BTN_SOUTH": "jump", "KEY_A": "stop"},
        }
    )
    assert "gamepad.dead_man = 'BTN_FOO': a button (BTN_SOUTH, BTN_TL" in found["gamepad.dead_man"]
    assert "'native', 16 or 24" in found["gamepad.record_bytes"]
    assert "an axis: one of ABS_X, ABS_Y" in found["gamepad.forward.axis"]
    assert "gait:tripod, gait:tetrapod" in found["gamepad.buttons.BTN_SOUTH"]
    assert "mode:walk" in found["gamepad.buttons.BTN_SOUTH"]
    assert "a valid key name: a button" in found["gamepad.buttons.KEY_A"]


def test_mapping_relations_are_checked_across_the_section() -> None:
    found = problems(
        {
            "dead_man": "BTN_A",  # BTN_SOUTH's code, which walks
            "turn": {"axis": "ABS_X"},  # sideways has it
            "buttons": {"ABS_Y+": "stop", "ABS_THROTTLE-": "flip", "BTN_TR": "stance:crouch"},
            "ranges": {"ABS_HAT0X": [1, -1]},
        }
    )
    assert "the same code as gamepad.dead_man" in found["gamepad.buttons.BTN_SOUTH"]
    assert "an axis no other stick uses (sideways)" in found["gamepad.turn.axis"]
    assert "an axis no stick drives (forward uses ABS_Y)" in found['gamepad.buttons."ABS_Y+"']
    assert "(add ABS_THROTTLE)" in found['gamepad.buttons."ABS_THROTTLE-"']
    assert "minimum below the maximum" in found["gamepad.ranges.ABS_HAT0X"]
    assert "stance:NAME of a preset: basic, default, high" in found["gamepad.buttons.BTN_TR"]


def test_a_default_button_can_be_unmapped_and_a_stance_added() -> None:
    cfg = parse_config(
        {
            "stances": {"crouch": {"reach_mm": 230.0, "height_mm": 220.0}},
            "gamepad": {"buttons": {"BTN_EAST": "none", "BTN_TR": "stance:crouch"}},
        }
    )
    policy = GamepadPolicy(GamepadMapping.from_config(cfg.gamepad))
    policy.connected(0.0)
    press(policy, DEAD_MAN)
    assert press(policy, (EV_KEY, BTN_EAST, 1)) == []
    (command,) = press(policy, (EV_KEY, BTN_TR, 1))
    assert command.stance == "crouch"


# --------------------------------------------------------------------------- the actor on a pipe


def graph(source: str = "gamepad:pipe:pad", config: Path | None = None) -> dict[str, Any]:
    params: dict[str, Any] = {"source": source}
    if config is not None:
        params["config"] = str(config)
    return {
        "actors": [
            {
                "name": "commands",
                "class": "whexar.actors.commands:CommandSource",
                "params": params,
                "outputs": {"commands": "motion"},
            },
            {"name": "sink", "class": "whexar.testing:Sink", "inputs": {"inp": "motion"}},
        ],
        "channels": {"motion": {"message": "MotionCommand", "policy": "backpressure"}},
    }


@pytest.fixture
def pipe() -> Iterator[EventPipe]:
    events = EventPipe()
    with DEVICES.registered(EVENT_PIPE, "pad", events):
        yield events
    events.close()


def timeline(result: Any) -> list[tuple[float, str, Any]]:
    """(t, what, detail) of every gamepad event and command, in order."""
    out: list[tuple[float, str, Any]] = []
    for entry in result.log.entries:
        m = entry.message
        if isinstance(m, MotionCommand):
            detail = {
                f: getattr(m, f)
                for f in ("vx_m_s", "vy_m_s", "yaw_rate_rad_s", "gait", "mode", "stop")
                if getattr(m, f) not in (None, False)
            }
            out.append((m.t, "command", detail))
        elif type(m).__name__.startswith("Gamepad"):
            out.append((m.t, type(m).__name__, m))
    return out


def kinds(result: Any) -> list[tuple[float, str]]:
    return [(t, what) for t, what, _ in timeline(result)]


def drive(pipe: EventPipe, *reports: Iterable[Event3]) -> None:
    for report in reports:
        pipe.send(*report)


def test_the_actor_drives_from_the_pipe_and_stops_when_the_dead_man_is_let_go(
    pipe: EventPipe,
) -> None:
    async def scenario(h: Harness) -> None:
        await h.sleep(0.5)
        drive(pipe, [DEAD_MAN], [(EV_ABS, ABS_Y, -FULL)])
        await h.wait_for(MotionCommand)
        await h.sleep(0.5)
        drive(pipe, [(EV_KEY, BTN_SOUTH, 1)], [(EV_ABS, ABS_HAT0X, 1)])
        await h.wait_for(MotionCommand, lambda c: c.gait is not None)
        await h.sleep(0.5)
        drive(pipe, [(EV_KEY, BTN_TL, 0)])
        await h.wait_for(MotionCommand, lambda c: c.stop)

    result = run_actors(graph(), scenario=scenario, real_io=True)
    assert result.exit_code == 0
    assert not result.events(ActorFailed)
    up = result.events(GamepadLinkUp)
    assert [(e.t, e.link, e.name) for e in up] == [(0.0, "pipe:pad", "")]
    assert [(t, what, d) for t, what, d in timeline(result) if what == "command"] == [
        (0.5, "command", {"vx_m_s": 0.2}),
        (1.0, "command", {"mode": "walk"}),
        (1.0, "command", {"gait": "tetrapod"}),
        (1.5, "command", {"stop": True}),
    ]
    assert all(c.source == "commands" for c in result.messages("motion", of=MotionCommand))


@pytest.mark.parametrize("size", [RECORD_32, RECORD_64])
def test_the_recorded_session_gives_the_same_commands_in_both_layouts(
    size: int, tmp_path: Path
) -> None:
    config = tmp_path / "pad.toml"
    config.write_text(f"[gamepad]\nrecord_bytes = {size}\n")
    events = EventPipe(record_bytes=size)
    events.write(recorded(size, *SESSION))  # there before the actor opens the pipe

    with DEVICES.registered(EVENT_PIPE, "pad", events):
        result = run_actors(graph(config=config), duration=1.0, real_io=True)
    events.close()
    assert [d for _, what, d in timeline(result) if what == "command"] == [
        {"vx_m_s": 0.2},
        {"mode": "walk"},
        {"stop": True},
    ]


def test_a_closed_pipe_is_an_unplugged_pad_stop_event_and_reopen(pipe: EventPipe) -> None:
    async def scenario(h: Harness) -> None:
        drive(pipe, [DEAD_MAN, (EV_ABS, ABS_Y, -FULL)])
        await h.wait_for(MotionCommand)
        await h.sleep(0.25)
        pipe.unplug()
        await h.wait_for(GamepadLinkDown)
        await h.sleep(2.5)  # looked for at 1.25 (absent) and 2.25 (absent)
        pipe.plug()
        await h.wait_for(GamepadLinkUp)
        drive(pipe, [DEAD_MAN, (EV_ABS, ABS_X, FULL)])
        await h.wait_for(MotionCommand)

    result = run_actors(graph(), scenario=scenario, real_io=True)
    assert kinds(result) == [
        (0.0, "GamepadLinkUp"),
        (0.0, "command"),
        (0.25, "GamepadLinkDown"),
        (0.25, "command"),
        (1.25, "GamepadLinkDown"),  # a new cause: not there, rather than gone
        (3.25, "GamepadLinkUp"),
        (3.25, "command"),
    ]
    line = timeline(result)
    assert line[3][2] == {"stop": True}
    gone, absent = result.events(GamepadLinkDown)
    assert gone.reason == "pipe:pad: end of file (the pad went away)"
    assert absent.reason == "cannot open pipe:pad: No such file or directory"
    assert line[6][2] == {"vy_m_s": -0.1}  # the new pad's state, not the old one's
    assert not result.events(ActorFailed)


def test_a_silent_pad_stops_the_robot_and_is_heard_again(pipe: EventPipe) -> None:
    async def scenario(h: Harness) -> None:
        await h.sleep(1.0)
        drive(pipe, [DEAD_MAN], [(EV_ABS, ABS_Y, -FULL)])
        await h.wait_for(GamepadLinkSilent)
        await h.sleep(1.0)
        drive(pipe, [(EV_ABS, ABS_Y, -FULL + 5)])
        await h.wait_for(MotionCommand)

    result = run_actors(graph(), scenario=scenario, real_io=True)
    assert kinds(result) == [
        (0.0, "GamepadLinkUp"),
        (1.0, "command"),
        (3.0, "GamepadLinkSilent"),
        (3.0, "command"),
        (4.0, "GamepadLinkHeard"),
        (4.0, "command"),
    ]
    (silent,) = result.events(GamepadLinkSilent)
    assert silent.silent_s == 2.0
    (heard,) = result.events(GamepadLinkHeard)
    assert heard.silent_s == 3.0
    assert [d for _, what, d in timeline(result) if what == "command"] == [
        {"vx_m_s": 0.2},
        {"stop": True},
        {"vx_m_s": 0.2},
    ]


def test_a_held_dead_man_with_centred_sticks_is_not_silence(pipe: EventPipe) -> None:
    drive(pipe, [DEAD_MAN])
    result = run_actors(graph(), duration=10.0, real_io=True)
    assert not result.events(GamepadLinkSilent)
    assert result.messages("motion") == []


def test_syn_dropped_on_the_pipe_stops_and_asks_for_the_dead_man_again(
    pipe: EventPipe,
) -> None:
    async def scenario(h: Harness) -> None:
        drive(pipe, [DEAD_MAN, (EV_ABS, ABS_Y, -FULL)])
        await h.wait_for(MotionCommand)
        await h.sleep(0.5)
        pipe.send((EV_SYN, SYN_DROPPED, 0), (EV_KEY, BTN_TL, 0), (EV_ABS, ABS_Y, 0))
        await h.wait_for(GamepadEventsDropped)
        await h.sleep(0.5)
        drive(pipe, [(EV_ABS, ABS_Y, -FULL)])  # not driving: the dead-man is unknown
        await h.sleep(0.5)
        drive(pipe, [DEAD_MAN])
        await h.wait_for(MotionCommand)

    result = run_actors(graph(), scenario=scenario, real_io=True)
    assert kinds(result) == [
        (0.0, "GamepadLinkUp"),
        (0.0, "command"),
        (0.5, "GamepadEventsDropped"),
        (0.5, "command"),
        (1.5, "command"),
    ]
    (dropped,) = result.events(GamepadEventsDropped)
    assert (dropped.discarded, dropped.resynced) == (2, False)  # a pipe has no EVIOCGKEY
    assert [d for _, what, d in timeline(result) if what == "command"] == [
        {"vx_m_s": 0.2},
        {"stop": True},
        {"vx_m_s": 0.2},
    ]


def test_a_pad_absent_at_start_is_an_event_not_a_failure() -> None:
    events = EventPipe()
    events.unplug()

    async def scenario(h: Harness) -> None:
        await h.sleep(1.5)
        events.plug()
        await h.wait_for(GamepadLinkUp)

    with DEVICES.registered(EVENT_PIPE, "pad", events):
        result = run_actors(graph(), scenario=scenario, real_io=True)
    events.close()
    assert kinds(result) == [(0.0, "GamepadLinkDown"), (2.0, "GamepadLinkUp")]
    assert not result.events(ActorFailed)


def test_an_unregistered_pipe_fails_the_start_naming_the_setting() -> None:
    result = run_actors(graph("gamepad:pipe:nobody"), duration=0.1, real_io=True)
    failed = result.events(ActorFailed)[0]  # and again after its restart
    assert failed.phase == "start"
    assert "source = 'gamepad:pipe:nobody': no gamepad pipe registered as 'nobody'" in failed.error


def test_a_gamepad_on_virtual_time_without_real_io_is_refused(pipe: EventPipe) -> None:
    refused = "real I/O: actor 'commands': gamepad pipe:pad"
    with pytest.raises(VirtualTimeRealIOError, match=refused):
        run_actors(graph(), duration=0.1)


def test_an_event_device_on_a_pipe_answers_no_ioctl(pipe: EventPipe) -> None:
    device = EventDevice.from_pipe(pipe, "pipe:pad")
    try:
        assert (device.name(), device.keys(), device.abs_info(ABS_X)) == (None, None, None)
        assert device.read(24) is None  # nothing yet, and no blocking
        pipe.send((EV_KEY, BTN_TL, 1))
        assert device.read(1024) == encode(
            [InputEvent(EV_KEY, BTN_TL, 1), InputEvent(EV_SYN, SYN_REPORT, 0)]
        )
        pipe.unplug()
        assert device.read(24) == b""
    finally:
        device.close()
    assert AbsInfo(0, -1, 1).maximum == 1


def test_a_missing_device_path_says_why(tmp_path: Path) -> None:
    from whexar.errors import DeviceGoneError

    with pytest.raises(DeviceGoneError, match=r"cannot open .*event9: No such file or directory"):
        EventDevice.open(str(tmp_path / "event9"))


# --------------------------------------------------------------------------- a pad's layout

PAD_KEYS = frozenset({BTN_SOUTH, BTN_EAST, BTN_TL, BTN_TR})
PAD_AXES = frozenset({ABS_X, ABS_Y, ABS_RX, ABS_HAT0X})
"""A common pad's buttons and axes, as EVIOCGBIT reports them (enough for the default)."""


def test_a_pad_that_fits_the_configured_mapping_keeps_it() -> None:
    default = GamepadMapping.from_config(GamepadSpec())
    chosen, missing, using = choose_mapping(default, default, (PAD_KEYS, PAD_AXES))
    assert (chosen, missing, using) == (default, (), None)
    # A pad that cannot tell (a pipe) keeps it too.
    assert choose_mapping(default, default, None) == (default, (), None)


def test_a_pad_without_the_configured_controls_falls_back_to_the_default() -> None:
    custom = GamepadMapping.from_config(parse_config({"gamepad": {"dead_man": "BTN_TL2"}}).gamepad)
    default = GamepadMapping.from_config(GamepadSpec())
    chosen, missing, using = choose_mapping(custom, default, (PAD_KEYS, PAD_AXES))
    assert chosen == default
    assert missing == ("BTN_TL2",)
    assert using == "default"
    # Neither fits a pad without sticks: the configured one stays, and it is said.
    chosen, missing, using = choose_mapping(custom, default, (PAD_KEYS, frozenset({ABS_HAT0X})))
    assert chosen is custom
    assert using == "configured"
    assert "BTN_TL2" in missing
    assert "ABS_Y" in missing


def test_the_fallback_takes_the_defaults_controls_and_keeps_the_configured_tunables() -> None:
    spec = parse_config(
        {
            "gamepad": {
                "dead_man": "BTN_TL2",
                "forward": {"axis": "ABS_RY", "invert": False},
                "max_forward_m_s": 0.05,
                "max_yaw_rate_deg_s": 10.0,
                "dead_zone": 0.4,
                "silent_after_s": 0.5,
                "ranges": {"ABS_RY": [-100, 100], "ABS_Y": [0, 255]},
            }
        }
    ).gamepad
    custom = GamepadMapping.from_config(spec)
    default = GamepadMapping.from_config(GamepadSpec())
    chosen, _, using = choose_mapping(custom, default, (PAD_KEYS, PAD_AXES))
    assert using == "default"
    # The default's controls: its dead-man, its forward axis and sense, its buttons.
    assert chosen.dead_man == default.dead_man
    assert (chosen.forward.axis, chosen.forward.sign) == (ABS_Y, -1.0)
    assert chosen.buttons == default.buttons
    # The configured tunables: a slow robot stays slow on another pad.
    assert chosen.forward.full == pytest.approx(0.05)
    assert chosen.turn.full == pytest.approx(math.radians(10.0))
    assert chosen.sideways.full == default.sideways.full  # not configured: the default's
    assert (chosen.dead_zone, chosen.silent_after_s) == (0.4, 0.5)
    assert chosen.ranges[ABS_Y] == AxisRange(0, 255)  # the configured range of that axis


def test_the_actor_says_the_layout_is_unknown_and_drives_with_the_default(
    pipe: EventPipe, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    config = tmp_path / "robot.toml"
    config.write_text('[gamepad]\ndead_man = "BTN_TL2"\n')  # a trigger this pad lacks
    monkeypatch.setattr(EventDevice, "capabilities", lambda self: (PAD_KEYS, PAD_AXES))

    async def scenario(h: Harness) -> None:
        await h.sleep(0.5)
        drive(pipe, [DEAD_MAN], [(EV_ABS, ABS_Y, -FULL)])  # the default's dead-man: BTN_TL
        await h.wait_for(MotionCommand)

    result = run_actors(graph(config=config), scenario=scenario, real_io=True)
    (unknown,) = result.events(GamepadLayoutUnknown)
    assert (unknown.link, unknown.missing, unknown.using) == ("pipe:pad", ("BTN_TL2",), "default")
    assert [d for _, what, d in timeline(result) if what == "command"] == [{"vx_m_s": 0.2}]
