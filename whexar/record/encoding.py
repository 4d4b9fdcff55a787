"""Messages as JSON: a JSON Schema per message type, a fast encoder and an exact decoder.

Theory of operation
-------------------
A message type is compiled once, on first use, from its dataclass fields and type
hints into a :class:`MessageCodec`: its JSON Schema (draft 2020-12) and two functions
generated as Python source, the way :mod:`dataclasses` writes ``__init__``. One turns
a message into plain values (dicts, lists, numbers, strings) that the C JSON encoder
turns into compact bytes; the other turns parsed JSON back into the same typed message,
found by its class name in :data:`~whexar.runtime.messages.MESSAGE_TYPES`. No
``dataclasses.asdict`` (it deep-copies), no reflection per message.

The encoding (what the schema says, and what Foxglove and PlotJuggler read):

* a message, a message inside a message and a ``NamedTuple`` (``JointState``) are
  objects keyed by field name;
* ``None`` is an absent key: optional fields are not ``required``;
* a tuple is an array; a fixed-length tuple whose items may be ``None`` or differ in
  type is an object keyed ``"0"``, ``"1"``, … (an absent key is ``None``);
* a float is written as Python's ``repr``, the shortest text that reads back as the
  same float, so floats round-trip exactly; ``inf`` and ``-inf`` as ``1e999`` and
  ``-1e999`` (JSON numbers out of range: Python reads them back as ``inf``, JavaScript
  as ``Infinity``); NaN as ``null``, the one value a schema ``"number"`` does not admit
  (the decoder restores NaN wherever a float is expected: ``None`` is never ``null``);
* an enum by its value; bytes as a base64 string (``contentEncoding: base64``).

Why: Foxglove's JSON Schema reader (``parseJsonSchema`` in Foxglove Studio's
``mcap-support``, kept in its fork Lichtblick) takes exactly one ``type`` per property
and one item type per array, and rejects ``null``, type lists, ``anyOf`` and ``$ref``;
a channel whose schema it cannot read shows nothing. Absent keys and index-keyed
objects express ``None`` within those rules.

Encoding and decoding go through msgspec's C code: the standard library's encoder
spends most of a message's time in ``float.__repr__``, and its parser is several times
slower too (docs/recording.md, "Encoding", has the costs). Decoding falls back to
``json.loads`` for what msgspec refuses: ``1e999`` must read back as ``inf``
(:func:`loads`).
"""

from __future__ import annotations

import base64
import contextlib
import dataclasses
import enum
import importlib
import json
import math
import operator
import types
import typing
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from json.encoder import encode_basestring_ascii
from typing import Any, Final, Generic, NamedTuple, TypeVar

import msgspec

import whexar.actors.messages  # noqa: F401  (registers the robot's message types)
from whexar.errors import UsageError
from whexar.runtime.messages import MESSAGE_TYPES, Message

__all__ = [
    "LINK_DIRECTIONS",
    "LINK_SCHEMA",
    "LINK_SCHEMA_NAME",
    "MESSAGE_ENCODING",
    "SCHEMA_ENCODING",
    "EncodingError",
    "LinkBytes",
    "MessageCodec",
    "RecordingError",
    "codec",
    "codec_by_name",
    "decode_link",
    "dumps",
    "encode_link",
    "loads",
    "time_ns",
    "type_path",
]

JSON_SCHEMA_DRAFT = "https://json-schema.org/draft/2020-12/schema"
MESSAGE_ENCODING = "json"
"""MCAP message encoding of every channel whexar writes (MCAP well-known encodings)."""
SCHEMA_ENCODING = "jsonschema"
"""MCAP schema encoding of every schema whexar writes."""

ENCODING_RULES = (
    "whexar JSON: None is an absent key; a fixed tuple with optional or mixed items is an "
    'object keyed "0", "1", ...; floats are exact (shortest repr); inf and -inf are 1e999 '
    "and -1e999; NaN is null; enums by value; bytes base64."
)
"""The rules above, in one line, as every generated schema's ``$comment``."""


class RecordingError(UsageError):
    """A recording cannot be read or written as asked: not MCAP, not whexar's, damaged,
    from an incompatible version, or a message that does not fit its type."""


class EncodingError(RecordingError):
    """A message type, or a value, that the JSON encoding cannot express or read back."""


# --------------------------------------------------------------------------- JSON text

_fast_dumps: Final = msgspec.json.Encoder().encode


def dumps(value: Any) -> bytes:
    """Compact JSON bytes of plain values, with the float rules of this module.

    msgspec's C encoder does the work: it writes a float as its shortest text that
    reads back as the same float, like ``repr`` but without the standard library's
    ``float.__repr__``, which is most of a message's cost there. It writes
    NaN and ±inf as ``null``, which these rules give only to NaN, and ``None`` never
    reaches it (an absent key): so output holding ``null`` anywhere (a string may, at
    worst a false alarm) goes again through a small Python writer that knows the rules,
    as does a value msgspec refuses (a numpy number). Non-ASCII text stays UTF-8.
    """
    try:
        data = _fast_dumps(value)
    except (TypeError, ValueError, OverflowError):
        return _slow_dumps(value).encode("ascii")
    if b"null" in data:
        return _slow_dumps(value).encode("ascii")
    return data


def _float_text(x: float) -> str:
    if x != x:
        return "null"
    if x == math.inf:
        return "1e999"
    if x == -math.inf:
        return "-1e999"
    return float.__repr__(x)


def _slow_dumps(v: Any) -> str:
    if v is None:
        return "null"
    if v is True:
        return "true"
    if v is False:
        return "false"
    if isinstance(v, str):
        return encode_basestring_ascii(v)
    if isinstance(v, float):
        return _float_text(v)
    if isinstance(v, int):
        return int.__repr__(v)
    if isinstance(v, dict):
        items = (f"{encode_basestring_ascii(str(k))}:{_slow_dumps(x)}" for k, x in v.items())
        return "{" + ",".join(items) + "}"
    if isinstance(v, list | tuple):
        return "[" + ",".join(_slow_dumps(x) for x in v) + "]"
    if hasattr(v, "__index__"):  # numpy integers
        return str(operator.index(v))
    if hasattr(v, "__float__"):  # numpy floats of other widths
        return _float_text(float(v))
    raise EncodingError(f"cannot write a {type(v).__name__} as JSON: {v!r:.60}")


def time_ns(t: float) -> int:
    """An MCAP log time (integer ns) for runtime-clock seconds ``t``; never below 1.

    Foxglove's timeline breaks when log time 0 mixes with other times (the project's
    notes on recording), and a runtime clock starts at 0: so 0, negative and
    non-finite times become 1 ns.
    """
    try:
        ns = round(t * 1e9)
    except (OverflowError, ValueError, TypeError):
        return 1
    return ns if ns > 0 else 1


# --------------------------------------------------------------------------- compiling types


def _as_float(x: Any) -> float:
    """A float field's JSON value back to the float (``null`` is NaN; ints widen)."""
    if x.__class__ is float:
        return x
    if x is None:
        return math.nan
    if x.__class__ is bool or not isinstance(x, int | float):
        raise TypeError(f"expected a number, got {x!r:.40}")
    return float(x)


def _as_number(x: Any) -> Any:
    """An ``int | float`` field's JSON value (kept as parsed; ``null`` is NaN)."""
    return math.nan if x is None else x


def _b64encode(b: bytes) -> str:
    return base64.b64encode(b).decode("ascii")


def _b64decode(s: str) -> bytes:
    return base64.b64decode(s, validate=True)


@dataclass(frozen=True, slots=True)
class _Conv:
    """How one type hint is written: its schema and the code that converts a value.

    ``enc``/``dec`` map the source text of a value to the source text of its JSON form
    (and back); ``None`` means the value is its own JSON form.
    """

    schema: dict[str, Any]
    enc: Callable[[str], str] | None = None
    dec: Callable[[str], str] | None = None
    optional: bool = False


class _Compiler:
    """Writes the source of the converters of one message type, then runs it once."""

    def __init__(self) -> None:
        self.ns: dict[str, Any] = {
            "_f": _as_float,
            "_n": _as_number,
            "_b64e": _b64encode,
            "_b64d": _b64decode,
        }
        self.source: list[str] = []
        self._count = 0
        self._objects: dict[type, tuple[str, str, dict[str, Any]]] = {}

    def fresh(self, prefix: str) -> str:
        self._count += 1
        return f"{prefix}{self._count}"

    def bind(self, prefix: str, value: Any) -> str:
        name = self.fresh(prefix)
        self.ns[name] = value
        return name

    # ------------------------------------------------------------------ type hints

    def conv(self, tp: Any, where: str) -> _Conv:
        origin = typing.get_origin(tp)
        if origin in (typing.Union, types.UnionType):
            return self._union(typing.get_args(tp), where)
        if origin is typing.Literal:
            values = typing.get_args(tp)
            kinds = {type(v) for v in values}
            if kinds <= {str}:
                return _Conv({"type": "string", "enum": list(values)})
            if kinds <= {int}:
                return _Conv({"type": "integer", "enum": list(values)})
            raise EncodingError(f"{where}: a Literal of mixed types is not supported")
        if origin is tuple:
            return self._tuple(typing.get_args(tp), where)
        if tp is bool:
            return _Conv({"type": "boolean"})
        if tp is int:
            return _Conv({"type": "integer"})
        if tp is float:
            return _Conv({"type": "number"}, dec=lambda x: f"_f({x})")
        if tp is str:
            return _Conv({"type": "string"})
        if tp is bytes:
            return _Conv(
                {"type": "string", "contentEncoding": "base64"},
                enc=lambda x: f"_b64e({x})",
                dec=lambda x: f"_b64d({x})",
            )
        if isinstance(tp, type) and issubclass(tp, enum.Enum):
            return self._enum(tp, where)
        if isinstance(tp, type) and issubclass(tp, tuple) and hasattr(tp, "_fields"):
            return self._object(tp, where)
        if isinstance(tp, type) and dataclasses.is_dataclass(tp):
            return self._object(tp, where)
        raise EncodingError(f"{where}: type {tp!r} cannot be recorded (see whexar.record)")

    def _union(self, args: tuple[Any, ...], where: str) -> _Conv:
        present = [a for a in args if a is not type(None)]
        optional = len(present) < len(args)
        if len(present) == 1:
            inner = self.conv(present[0], where)
            if inner.optional:
                return inner
            return dataclasses.replace(inner, optional=optional)
        if set(present) == {int, float}:
            return _Conv({"type": "number"}, dec=lambda x: f"_n({x})", optional=optional)
        raise EncodingError(f"{where}: a union of {present} cannot be recorded (one type only)")

    def _enum(self, tp: type[enum.Enum], where: str) -> _Conv:
        values = [m.value for m in tp]
        if all(isinstance(v, str) for v in values):
            kind = "string"
        elif all(isinstance(v, int) and not isinstance(v, bool) for v in values):
            kind = "integer"
        else:
            raise EncodingError(f"{where}: enum {tp.__name__} needs all-str or all-int values")
        cls = self.bind("_enum", tp)
        return _Conv(
            {"type": kind, "enum": values, "title": tp.__name__},
            enc=lambda x: f"{x}.value",
            dec=lambda x: f"{cls}({x})",
        )

    def _tuple(self, args: tuple[Any, ...], where: str) -> _Conv:
        if not args:
            raise EncodingError(f"{where}: a bare tuple says nothing of its items")
        if len(args) == 2 and args[1] is Ellipsis:
            item = self.conv(args[0], f"{where}[]")
            if item.optional:
                raise EncodingError(
                    f"{where}: a tuple of any length with optional items cannot be recorded"
                )
            return _Conv(
                {"type": "array", "items": item.schema},
                enc=None if item.enc is None else _each_list(item.enc, self.fresh("x")),
                dec=_each_tuple(item.dec, self.fresh("x")),
            )
        if args == ((),):  # tuple[()]
            return _Conv({"type": "array", "maxItems": 0}, dec=lambda x: f"tuple({x})")
        items = [self.conv(a, f"{where}[{i}]") for i, a in enumerate(args)]
        first = items[0]
        if all(a == args[0] for a in args) and not first.optional:
            n = len(items)
            return _Conv(
                {"type": "array", "items": first.schema, "minItems": n, "maxItems": n},
                enc=None if first.enc is None else _each_list(first.enc, self.fresh("x")),
                dec=_each_tuple(first.dec, self.fresh("x")),
            )
        return self._keyed_tuple(items)

    def _keyed_tuple(self, items: list[_Conv]) -> _Conv:
        """A fixed tuple of optional or mixed items: an object keyed by index."""
        enc, dec = self.fresh("_e"), self.fresh("_d")
        keys = [str(i) for i in range(len(items))]
        lines = [f"def {enc}(v):", "    d = {}"]
        for i, (key, c) in enumerate(zip(keys, items, strict=True)):
            value = _apply(c.enc, f"v[{i}]")
            if c.optional:
                lines.append(f"    if v[{i}] is not None: d[{key!r}] = {value}")
            else:
                lines.append(f"    d[{key!r}] = {value}")
        lines.append("    return d")
        parts = []
        for key, c in zip(keys, items, strict=True):
            value = _apply(c.dec, f"d[{key!r}]")
            parts.append(f"({value} if {key!r} in d else None)" if c.optional else value)
        lines += [f"def {dec}(d):", f"    return ({', '.join(parts)},)"]
        self.source.append("\n".join(lines))
        schema = {
            "type": "object",
            "properties": {k: c.schema for k, c in zip(keys, items, strict=True)},
            "required": [k for k, c in zip(keys, items, strict=True) if not c.optional],
            "additionalProperties": False,
        }
        return _Conv(schema, enc=lambda x: f"{enc}({x})", dec=lambda x: f"{dec}({x})")

    def _object(self, tp: type, where: str) -> _Conv:
        """A dataclass (a message) or a NamedTuple: an object keyed by field name."""
        known = self._objects.get(tp)
        if known is None:
            known = self._write_object(tp, where)
            self._objects[tp] = known
        enc, dec, schema = known
        return _Conv(schema, enc=lambda x: f"{enc}({x})", dec=lambda x: f"{dec}({x})")

    def _write_object(self, tp: type, where: str) -> tuple[str, str, dict[str, Any]]:
        hints = typing.get_type_hints(tp)
        is_tuple = issubclass(tp, tuple)
        # (name, getter source, default source or None when required)
        fields: list[tuple[str, str, str | None]] = []
        default: str | None
        if is_tuple:
            tuple_defaults: dict[str, Any] = getattr(tp, "_field_defaults", {})
            for i, name in enumerate(getattr(tp, "_fields", ())):
                default = self.bind("_dv", tuple_defaults[name]) if name in tuple_defaults else None
                fields.append((name, f"v[{i}]", default))
        else:
            for f in dataclasses.fields(tp):
                if not f.init:
                    continue
                if f.default is not dataclasses.MISSING:
                    default = self.bind("_dv", f.default)
                elif f.default_factory is not dataclasses.MISSING:
                    default = self.bind("_df", f.default_factory) + "()"
                else:
                    default = None
                fields.append((f.name, f"v.{f.name}", default))
        convs = {name: self.conv(hints[name], f"{tp.__name__}.{name}") for name, _, _ in fields}
        enc, dec, cls = self.fresh("_e"), self.fresh("_d"), self.bind("_cls", tp)

        # Encoder: plain fields go into one dict literal until the first optional one
        # (a literal is the fastest way to build a dict); keys stay in field order.
        lines = [f"def {enc}(v):"]
        literal: list[str] = []
        started = False
        for name, get, _ in fields:
            c = convs[name]
            if c.optional:
                if not started:
                    lines.append(f"    d = {{{', '.join(literal)}}}")
                    started = True
                lines.append(f"    x = {get}")
                lines.append(f"    if x is not None: d[{name!r}] = {_apply(c.enc, 'x')}")
            elif started:
                lines.append(f"    d[{name!r}] = {_apply(c.enc, get)}")
            else:
                literal.append(f"{name!r}: {_apply(c.enc, get)}")
        if started:
            lines.append("    return d")
        else:
            lines.append(f"    return {{{', '.join(literal)}}}")

        # Decoder: absent optional -> None; absent with a default -> the default.
        args = []
        for name, _, default in fields:
            c = convs[name]
            value = _apply(c.dec, f"d[{name!r}]")
            if c.optional:
                value = f"({value} if {name!r} in d else None)"
            elif default is not None:
                value = f"({value} if {name!r} in d else {default})"
            args.append(value if is_tuple else f"{name}={value}")
        lines += [f"def {dec}(d):", f"    return {cls}({', '.join(args)})"]
        self.source.append("\n".join(lines))

        schema: dict[str, Any] = {"title": tp.__name__}
        doc = _summary(tp)
        if doc:
            schema["description"] = doc
        schema |= {
            "type": "object",
            "properties": {name: convs[name].schema for name, _, _ in fields},
            "required": [n for n, _, d in fields if not convs[n].optional and d is None],
            "additionalProperties": False,
        }
        return enc, dec, schema

    def top(self, cls: type) -> tuple[str, str, dict[str, Any]]:
        """Write the converters of message type ``cls``: (encoder, decoder, schema)."""
        self._object(cls, cls.__name__)
        return self._objects[cls]

    def build(self) -> dict[str, Callable[[Any], Any]]:
        """Run the source written so far; the namespace holds the converters by name."""
        exec("\n\n".join(self.source), self.ns)
        return self.ns


def _apply(conv: Callable[[str], str] | None, value: str) -> str:
    return value if conv is None else conv(value)


def _each_list(enc: Callable[[str], str], var: str) -> Callable[[str], str]:
    return lambda x: f"[{enc(var)} for {var} in {x}]"


def _each_tuple(dec: Callable[[str], str] | None, var: str) -> Callable[[str], str]:
    if dec is None:
        return lambda x: f"tuple({x})"
    return lambda x: f"tuple([{dec(var)} for {var} in {x}])"


def _summary(tp: type) -> str:
    """The first paragraph of a class's own docstring, on one line."""
    doc = tp.__dict__.get("__doc__") or ""
    return " ".join(doc.strip().split("\n\n")[0].split())


# --------------------------------------------------------------------------- codecs


M = TypeVar("M", bound=Message)


@dataclass(frozen=True, slots=True, eq=False)
class MessageCodec(Generic[M]):
    """The JSON Schema and the converters of one message type (see the module docstring)."""

    cls: type[M]
    schema: Mapping[str, Any]
    """The JSON Schema (draft 2020-12) of the encoded message."""
    schema_data: bytes
    """:attr:`schema` as the bytes written into the MCAP file."""
    to_json: Callable[[Any], Any]
    """Message → plain JSON values (dicts, lists, numbers, strings)."""
    from_json: Callable[[Any], Any]
    """Parsed JSON → the message."""

    @property
    def name(self) -> str:
        """The type's registered name: the class name, the MCAP schema name."""
        return self.cls.__name__

    def encode(self, msg: M) -> bytes:
        """Compact JSON bytes of ``msg``."""
        return dumps(self.to_json(msg))

    def decode(self, data: bytes | str) -> M:
        """The message encoded in ``data``; :class:`EncodingError` if it does not fit."""
        return self.decode_value(loads(data, self.name))

    def decode_value(self, value: Any) -> M:
        """The message from already parsed JSON ``value``."""
        try:
            return typing.cast(M, self.from_json(value))
        except KeyError as exc:
            raise EncodingError(f"a {self.name} without its field {exc}") from None
        except (TypeError, ValueError, AttributeError) as exc:
            raise EncodingError(f"a {self.name} that does not fit its type: {exc}") from None


_fast_loads: Final = msgspec.json.Decoder().decode


def loads(data: bytes | str, what: str = "message") -> Any:
    """Parsed JSON of a recorded message: msgspec's C parser (faster than the standard
    library's, floats read back exactly, tested), the standard library's where msgspec refuses a
    number (``±1e999``, whexar's infinities); :class:`EncodingError` if it is not JSON."""
    try:
        return _fast_loads(data)
    except (msgspec.ValidationError, msgspec.DecodeError):
        pass
    try:
        return json.loads(data)
    except ValueError as exc:
        raise EncodingError(f"a {what} that is not JSON: {exc}") from None


_CODECS: dict[type, MessageCodec[Any]] = {}


def codec(cls: type[M]) -> MessageCodec[M]:
    """The codec of message type ``cls``, compiled on first use and cached."""
    known = _CODECS.get(cls)
    if known is not None:
        return known
    if not (isinstance(cls, type) and issubclass(cls, Message)):
        raise EncodingError(f"{cls!r} is not a message type")
    compiler = _Compiler()
    enc, dec, body = compiler.top(cls)
    schema = {"$schema": JSON_SCHEMA_DRAFT, "$comment": ENCODING_RULES, **body}
    ns = compiler.build()
    made: MessageCodec[M] = MessageCodec(
        cls=cls,
        schema=schema,
        schema_data=json.dumps(schema, separators=(",", ":")).encode(),
        to_json=ns[enc],
        from_json=ns[dec],
    )
    _CODECS[cls] = made
    return made


def type_path(cls: type) -> str:
    """``module:QualName`` of a type, as recorded in channel metadata."""
    return f"{cls.__module__}:{cls.__qualname__}"


def codec_by_name(name: str, path: str | None = None) -> MessageCodec[Message]:
    """The codec of the message type registered as ``name``.

    A type not registered yet is imported from ``path`` (``module:Name``, from the
    channel's metadata) when its module is part of whexar; other modules are never
    imported because a file names them.
    """
    cls = MESSAGE_TYPES.get(name)
    if cls is None and path is not None and path.startswith("whexar."):
        module = path.split(":", 1)[0]
        with contextlib.suppress(ImportError):
            importlib.import_module(module)
        cls = MESSAGE_TYPES.get(name)
    if cls is None:
        raise EncodingError(f"unknown message type {name!r} (not registered in this whexar)")
    return codec(cls)


# --------------------------------------------------------------------------- device links


class LinkBytes(NamedTuple):
    """Raw bytes of device link ``link`` (``"bus"``, ``"sensors"``, ``"imu"``), sent
    (``"tx"``) to the device or received (``"rx"``) from it at runtime-clock time ``t``.

    Besides bytes, what a replay needs to play the link back (:data:`LINK_DIRECTIONS`):
    a read that gave up waiting is ``"timeout"`` with no data; the link was opened
    (``"open"``, no data) or went away or could not be opened (``"gone"``, the reason in
    UTF-8); an I/O call failed (``"error"``, ``"ERRNO:message"`` in UTF-8)."""

    link: str
    direction: str
    t: float
    data: bytes


LINK_DIRECTIONS: Final = ("tx", "rx", "timeout", "open", "gone", "error")
"""What a :class:`LinkBytes` record can be (its ``dir``)."""

LINK_SCHEMA_NAME = "whexar.LinkBytes"
"""Schema name of the ``/links/{link}`` topics."""

LINK_SCHEMA: Mapping[str, Any] = {
    "$schema": JSON_SCHEMA_DRAFT,
    "title": LINK_SCHEMA_NAME,
    "description": "Raw bytes of a device link (the topic names the link), in one direction, "
    "at runtime-clock time t (s).",
    "$comment": ENCODING_RULES,
    "type": "object",
    "properties": {
        "t": {"type": "number"},
        "dir": {
            "type": "string",
            "enum": list(LINK_DIRECTIONS),
            "description": "tx: to the device; rx: from it; timeout: a read gave up "
            "waiting (no data), at the time it gave up; open: the link was opened (no "
            "data); gone: it went away or could not be opened (data: the reason, UTF-8); "
            "error: an I/O call failed (data: 'ERRNO:message', UTF-8)",
        },
        "data": {"type": "string", "contentEncoding": "base64"},
    },
    "required": ["t", "dir", "data"],
    "additionalProperties": False,
}


def encode_link(direction: str, t: float, data: bytes) -> bytes:
    """JSON bytes of one chunk of link bytes (base64: Foxglove shows it as bytes)."""
    if direction in _LINK_TEXT and math.isfinite(t):
        # The recorder writes several hundred of these a second: one format, no dict.
        return b'{"t":%b,"dir":%b,"data":"%b"}' % (
            float.__repr__(float(t)).encode(),
            _LINK_TEXT[direction],
            base64.b64encode(data),
        )
    return dumps({"t": t, "dir": direction, "data": _b64encode(data)})


_LINK_TEXT: Final = {d: b'"%b"' % d.encode() for d in LINK_DIRECTIONS}


def decode_link(link: str, data: bytes | str) -> LinkBytes:
    """The :class:`LinkBytes` of one ``/links/{link}`` message."""
    try:
        value = loads(data, "link record")
        return LinkBytes(link, str(value["dir"]), _as_float(value["t"]), _b64decode(value["data"]))
    except (ValueError, KeyError, TypeError) as exc:
        raise EncodingError(f"link bytes on {link!r} that do not fit their schema: {exc}") from None
