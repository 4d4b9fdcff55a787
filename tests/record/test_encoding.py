"""Every message type round-trips through its JSON encoding exactly, and its schema both
describes the encoding and stays within what Foxglove reads."""

from __future__ import annotations

import dataclasses
import enum
import json
import math
import random
import struct
import types
import typing
from collections.abc import Callable, Mapping
from typing import Any, Literal

import pytest

from whexar.actors.messages import (
    JointState,
    ObstacleRanges,
    SensorFrame,
    ServoStates,
)
from whexar.record.encoding import (
    EncodingError,
    LinkBytes,
    codec,
    codec_by_name,
    decode_link,
    dumps,
    encode_link,
    time_ns,
)
from whexar.runtime.messages import MESSAGE_TYPES, Message, message

Same = Callable[[Any, Any], bool]
Check = Callable[[Mapping[str, Any], Any], list[str]]
Foxglove = Callable[[Mapping[str, Any]], list[str]]

FLOATS = (0.1, -0.0, 1e-300, 123456.789012345, math.pi, math.inf, -math.inf, math.nan)


def _sample(tp: Any, filled: bool, k: int) -> Any:
    """A value of type hint ``tp``; ``filled=False`` puts ``None`` wherever allowed."""
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        present = [a for a in args if a is not type(None)]
        if not filled and len(present) < len(args):
            return None
        return _sample(present[0], filled, k)
    if origin is Literal:
        return args[k % len(args)]
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_sample(args[0], filled, k + i) for i in range(3))
        return tuple(_sample(a, filled, k + i) for i, a in enumerate(args))
    if tp is float:
        return FLOATS[k % len(FLOATS)]
    if tp is bool:
        return k % 2 == 0
    if tp is int:
        return -7 + k
    if tp is str:
        return f's{k} ü ☃ "quoted" \\ \n'
    if tp is bytes:
        return bytes(range(k, k + 5))
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        return list(tp)[k % len(tp)]
    if isinstance(tp, type) and issubclass(tp, tuple):
        hints = typing.get_type_hints(tp)
        names: tuple[str, ...] = tp._fields  # type: ignore[attr-defined]
        return tp(*(_sample(hints[f], filled, k + i) for i, f in enumerate(names)))
    if dataclasses.is_dataclass(tp) and isinstance(tp, type):
        return _instance(tp, filled, k)
    raise AssertionError(f"no sample for {tp!r}")


def _instance(cls: type, filled: bool, k: int = 0) -> Any:
    hints = typing.get_type_hints(cls)
    values = {
        f.name: _sample(hints[f.name], filled, k + i)
        for i, f in enumerate(dataclasses.fields(cls))
        if f.init
    }
    return cls(**values)


def _types() -> list[type[Message]]:
    return [MESSAGE_TYPES[name] for name in sorted(MESSAGE_TYPES)]


@pytest.mark.parametrize("filled", [True, False], ids=["filled", "nones"])
def test_every_registered_message_type_round_trips_exactly(filled: bool, same_value: Same) -> None:
    checked = 0
    for cls in _types():
        for k in range(len(FLOATS)):
            msg = _instance(cls, filled, k)
            c = codec(cls)
            data = c.encode(msg)
            back = c.decode(data)
            assert type(back) is cls
            assert same_value(back, msg), (cls.__name__, msg, back)
            assert same_value(codec_by_name(cls.__name__).decode(data), back)
            checked += 1
    assert checked >= 60 * len(FLOATS)


def test_every_schema_describes_the_encoding_and_foxglove_can_read_it(
    schema_problems: Check, foxglove_refuses: Foxglove
) -> None:
    for cls in _types():
        c = codec(cls)
        schema = json.loads(c.schema_data)
        assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
        assert schema["title"] == cls.__name__
        assert foxglove_refuses(schema) == [], cls.__name__
        for filled in (True, False):
            encoded = json.loads(c.encode(_instance(cls, filled, 1)))
            assert schema_problems(schema, encoded) == [], (cls.__name__, encoded)


def test_servo_states_keep_their_joint_state_tuples_and_missing_readings() -> None:
    joints = tuple(
        JointState(
            leg=leg,
            joint=j,
            servo_id=7 * leg + j + 1,
            position_rad=None if j == 6 else 0.1 * j - leg / 3,
            velocity_rad_s=-(j / 7),
            current_a=None if leg == 2 else 0.0134 * j,
            alert=j == 3,
        )
        for leg in range(6)
        for j in range(7)
    )
    msg = ServoStates(t=12.345678901, source="bus", cycle=1234, joints=joints)
    back = codec(ServoStates).decode(codec(ServoStates).encode(msg))
    assert back == msg
    assert all(type(j) is JointState for j in back.joints)
    encoded = json.loads(codec(ServoStates).encode(msg))
    assert "position_rad" not in encoded["joints"][6]  # None is an absent key


def test_floats_round_trip_bit_for_bit() -> None:
    rng = random.Random(15)
    raw = [struct.unpack("<d", rng.randbytes(8))[0] for _ in range(2000)]
    values = [x for x in raw if math.isfinite(x)] + [5e-324, -1.7976931348623157e308, -0.0]
    for x in values:
        msg = ObstacleRanges(t=x, source="s", seq=1, counts=(1, 2), distances_m=(x, None))
        back = codec(ObstacleRanges).decode(codec(ObstacleRanges).encode(msg))
        assert struct.pack("<d", back.t) == struct.pack("<d", x)
        assert back.distances_m[0] is not None
        assert struct.pack("<d", back.distances_m[0]) == struct.pack("<d", x)


def test_non_finite_floats_are_valid_json_that_reads_back(same_value: Same) -> None:
    msg = ObstacleRanges(t=1.0, source="s", seq=None, counts=(0, 1), distances_m=(math.inf, None))
    data = codec(ObstacleRanges).encode(msg)
    assert data == b'{"t":1.0,"source":"s","counts":[0,1],"distances_m":{"0":1e999}}'
    assert codec(ObstacleRanges).decode(data) == msg
    frame = _instance(SensorFrame, True, 7)  # NaN and inf in the tilt fields
    text = codec(SensorFrame).encode(frame).decode()
    assert "NaN" not in text
    assert "Infinity" not in text
    assert same_value(codec(SensorFrame).decode(text.encode()), frame)
    assert dumps([math.nan, -math.inf, 2.5]) == b"[null,-1e999,2.5]"


class _Mode(enum.Enum):
    WALK = "walk"
    RIDE = "ride"


@message
class RecordTestKinds(Message):
    """Field types no robot message uses yet: an enum, bytes, a literal, int | float."""

    mode: _Mode
    blob: bytes
    kind: Literal["a", "b"]
    number: int | float
    pair: tuple[int, str]
    nested: tuple[JointState, ...] = ()


def test_enums_bytes_literals_and_mixed_tuples_round_trip(
    same_value: Same, foxglove_refuses: Foxglove
) -> None:
    msg = RecordTestKinds(
        t=0.5,
        source="x",
        mode=_Mode.RIDE,
        blob=b"\x00\xff",
        kind="b",
        number=3,
        pair=(4, "four"),
        nested=(JointState(leg=0, joint=1, servo_id=2),),
    )
    c = codec(RecordTestKinds)
    assert c.decode(c.encode(msg)) == msg
    assert same_value(c.decode(c.encode(dataclasses.replace(msg, number=3.0))).number, 3.0)
    schema = json.loads(c.schema_data)
    assert schema["properties"]["mode"] == {"type": "string", "enum": ["walk", "ride"]} | {
        "title": "_Mode"
    }
    assert foxglove_refuses(schema) == []


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class _Unrecordable(Message):
    items: list[int]


def test_a_type_that_cannot_be_recorded_is_refused_by_name() -> None:
    with pytest.raises(EncodingError, match=r"_Unrecordable.items"):
        codec(_Unrecordable)


def test_a_message_that_does_not_fit_its_type_is_a_clear_error() -> None:
    c = codec(ServoStates)
    with pytest.raises(EncodingError, match="without its field 'cycle'"):
        c.decode(b'{"t":1.0,"source":"bus","joints":[]}')
    with pytest.raises(EncodingError, match="not JSON"):
        c.decode(b"{")
    with pytest.raises(EncodingError, match="does not fit"):
        c.decode(b'{"t":"soon","source":"bus","cycle":1,"joints":[]}')
    with pytest.raises(EncodingError, match="unknown message type 'NoSuchMessage'"):
        codec_by_name("NoSuchMessage", "os.path:NoSuchMessage")


def test_link_bytes_and_log_times() -> None:
    data = bytes(range(256))
    assert decode_link("bus", encode_link("rx", 0.25, data)) == LinkBytes("bus", "rx", 0.25, data)
    assert time_ns(0.0) == 1
    assert time_ns(-3.0) == 1
    assert time_ns(math.nan) == 1
    assert time_ns(1.5) == 1_500_000_000
    assert time_ns(1.8e9) == 1_800_000_000_000_000_000
