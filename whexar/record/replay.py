"""Replay: a recording's device bytes played back through the same actors, on virtual time.

Theory of operation
-------------------
A recording holds the wiring of the run, its robot configuration, every byte of its
device links with its time, and every message every actor published
(:mod:`whexar.record.writer`). :func:`replay` rebuilds the graph from the recorded
wiring with each device-owning actor pointed at its link played back — the bus
scheduler at :class:`~whexar.bus.replay.BusReplay` (through dynamixel-sdk, which
parses the recorded replies again), the sensor reader at
:class:`~whexar.sensors.replay.BoardReplay` (through the frame decoder), the IMU
reader at :class:`~whexar.sensors.replay.I2CReplay` — and feeds the channels no
actor of the graph publishes (the motion commands) with their recorded messages at
their recorded times. A command source (keyboard, script) is such a feed too: its
actor is left out. Every other actor is the one the robot runs, on virtual time, so
the replay is deterministic and runs as fast as the CPU allows, or paced
(``speed``).

Checking (``check=True``): every message an actor publishes is compared, channel by
channel and in order, with the recorded one: its type, then each field, floats
within :data:`FLOAT_TOLERANCE` (relative, at least absolute), everything else
exactly. The first difference stops the replay and is reported as a
:class:`Divergence` naming the channel, the time, the field and both values; so are
a packet the code wrote on a link that differs from the recorded one, and recorded
messages the replay never published. With the code and configuration of the
recording, nothing diverges; with an edited threshold or code, the replay says
where the behaviour first changed on a real log.

Configuration: the recorded one (its file, attached as ``config.toml``, or the
built-in). A recording whose built-in configuration is not this version's (its
``robot-config.json`` differs) is refused, naming the keys, unless ``config``
gives the file to replay with (the ``--config`` override).

Time window: actors carry state from the start, so a replay always starts at the
recording's start. ``start`` is where the check and the pacing begin (before it the
replay runs at full speed); ``stop`` ends the replay early.
"""

from __future__ import annotations

import contextlib
import importlib
import json
import math
import tempfile
import tomllib
from collections.abc import Callable, Generator, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final, Literal, TypeVar

import anyio

from whexar.actors.graph import with_reflexes
from whexar.actors.messages import WorldDiverged, WorldFault
from whexar.bus.emulator.chain import SERVO_CHAIN
from whexar.bus.field import FieldBus
from whexar.bus.replay import REPLAYED_BUS, BusReplay
from whexar.config import RobotConfig, load_config
from whexar.errors import UsageError
from whexar.record.check import FLOAT_TOLERANCE, LATE_S, Checker, Comparison, Divergence, compare
from whexar.record.diff import DEFAULT_TOLERANCES, DiffReport, TimeDiff, Tolerances
from whexar.record.encoding import LinkBytes, RecordingError
from whexar.record.reader import Recording
from whexar.record.writer import (
    CONFIG_ATTACHMENT,
    EFFECTIVE_CONFIG_ATTACHMENT,
    RECORDER_EVENTS,
    URDF_ATTACHMENT,
    Recorder,
)
from whexar.runtime.channels import ChannelStats
from whexar.runtime.clock import monotonic, wait_until
from whexar.runtime.devices import DEVICES
from whexar.runtime.harness import Harness, RunResult, run_actors
from whexar.runtime.messages import Message
from whexar.runtime.schema import read_toml
from whexar.runtime.streams import Dealer
from whexar.runtime.wiring import EVENTS_CHANNEL, set_param
from whexar.sensors.replay import (
    REPLAYED_BOARD,
    REPLAYED_I2C,
    BoardReplay,
    I2CFieldReplay,
    I2CReplay,
)

if TYPE_CHECKING:
    from whexar.record.writer import LiveSink

T = TypeVar("T")

__all__ = [
    "FLOAT_TOLERANCE",
    "Divergence",
    "ReplayResult",
    "compare",
    "replay",
]

DEVICE_PARAMS: Final = {
    "whexar.actors.bus:BusScheduler": ("port", ("faults", "emulator_fast_sync_read")),
    "whexar.actors.sensing:SensorReader": ("port", ()),
    "whexar.actors.sensing:ImuReader": ("device", ()),
}
"""Actors that own a device link: the parameter that names the device, and the
parameters that only an emulator reads (dropped for the replay)."""
MOVED: Final = {
    "whexar.actors.leg:LegActor": "whexar.actors.locomotion:LegActor",
    "whexar.actors.coordinator:Coordinator": "whexar.actors.locomotion:Coordinator",
    "whexar.actors.sensors:SensorReader": "whexar.actors.sensing:SensorReader",
    "whexar.actors.imu:ImuReader": "whexar.actors.sensing:ImuReader",
}
"""Where the actor classes a recording's wiring may name have moved: a recording made
before the move replays with the classes at their new homes."""
FED_ACTORS: Final = frozenset({"whexar.actors.commands:CommandSource"})
"""Actors left out of a replay: their channels are fed from the recording."""
UNPLAYED: Final = frozenset({"recording"})
"""Configuration sections a replay leaves out of its comparison: the recordings' budget
changes nothing the actors do."""
REPLAY_DEVICE: Final = "replay"
"""The name every played-back device is registered under."""
Clock = Literal["virtual", "real"]
"""The clock a recording was made on: virtual time (a simulation, a test, ``whexar run
--virtual``, a replay) replays byte for byte; a real clock (the robot) by time."""


def recorded_clock(rec: Recording) -> Clock:
    """The clock ``rec`` was recorded on: its ``run`` metadata's ``clock``, or, in a
    recording made before it was written, what its kind and command line say."""
    run = rec.metadata.get("run", {})
    clock = run.get("clock")
    if clock in ("virtual", "real"):
        return "real" if clock == "real" else "virtual"
    if run.get("kind") == "run":
        return "virtual" if "--virtual" in run.get("command", "").split() else "real"
    return "virtual"


# --------------------------------------------------------------------------- the replay


@dataclass
class ReplayResult:
    """What a replay did."""

    path: Path
    duration_s: float
    """Runtime seconds replayed."""
    recorded_s: float
    """Seconds the recording holds (readable)."""
    wall_s: float
    """Wall time of the whole replay, reading the recording included."""
    run: RunResult
    fed: dict[str, int]
    """Messages fed from the recording, per channel."""
    checked: bool
    compared: int = 0
    """Messages compared with the recorded ones."""
    divergence: Divergence | None = None
    links: dict[str, str] = field(default_factory=dict)
    """Each played-back link: what it did, in words."""
    damage: str | None = None
    """Where a damaged recording's readable part ends, if it does."""
    config_changes: list[str] = field(default_factory=list)
    """Keys of the configuration replayed with that differ from the recorded one."""
    recording: Path | None = None
    """Where the replay itself was recorded, if it was."""
    clock: Clock = "virtual"
    """The clock the recording was made on: the devices played back byte for byte
    (virtual) or by time (real)."""
    report: DiffReport | None = None
    """The time-aligned comparison (a log of a real clock checked, or ``by_time``)."""
    ended_early: str | None = None
    """Why the replay stopped before the end of the recording (or of ``stop``), if it did."""
    uncompared: list[str] = field(default_factory=list)
    """Channels one side has and the other not: not compared."""

    @property
    def agrees(self) -> bool:
        """Nothing diverged (or everything within tolerance), and the replay reached its end."""
        if self.ended_early is not None or self.divergence is not None:
            return False
        return self.report is None or self.report.agrees

    @property
    def realtime_factor(self) -> float:
        """Replayed seconds per wall second."""
        return self.duration_s / self.wall_s if self.wall_s > 0 else math.inf

    @property
    def channels(self) -> dict[str, ChannelStats]:
        """Each channel's published and dropped counts."""
        return self.run.stats


def _wiring(rec: Recording) -> dict[str, Any]:
    for name, attachment in sorted(rec.attachments.items()):
        if name.startswith("wiring."):
            text = attachment.data.decode("utf-8")
            data: dict[str, Any] = (
                json.loads(text) if name.endswith(".json") else tomllib.loads(text)
            )
            return data
    raise RecordingError(
        f"{rec.path} holds no wiring (attachment wiring.json or wiring.toml): it cannot be replayed"
    )


def _param_fields(class_path: str) -> set[str]:
    module, _, name = class_path.partition(":")
    try:
        cls = getattr(importlib.import_module(module), name)
        return set(cls.Params.model_fields)
    except (ImportError, AttributeError):
        return set()


def config_changes(
    recorded: Mapping[str, Any], now: Mapping[str, Any], prefix: str = ""
) -> list[str]:
    """Keys whose values differ between two configuration dumps: ``key: recorded → now``."""
    out: list[str] = []
    for key in sorted(set(recorded) | set(now)):
        a, b = recorded.get(key, "<absent>"), now.get(key, "<absent>")
        where = f"{prefix}{key}"
        if isinstance(a, Mapping) and isinstance(b, Mapping):
            out.extend(config_changes(a, b, f"{where}."))
        elif a != b:
            out.append(f"{where}: {a!r} → {b!r}")
    return out


def _config(
    rec: Recording, override: Path | None, workdir: Path
) -> tuple[Path | None, RobotConfig, list[str]]:
    """The configuration file to replay with (``None``: the built-in), the configuration,
    and how it differs from the recorded one."""
    recorded_file = rec.attachments.get(CONFIG_ATTACHMENT)
    if override is not None:
        path: Path | None = override
        cfg = load_config(override)
    elif recorded_file is not None:
        path = workdir / CONFIG_ATTACHMENT
        path.write_bytes(recorded_file.data)
        cfg = load_config(path)
    else:
        path, cfg = None, RobotConfig()
    effective = rec.attachments.get(EFFECTIVE_CONFIG_ATTACHMENT)
    if effective is None:
        return path, cfg, []
    recorded = {k: v for k, v in json.loads(effective.data).items() if k not in UNPLAYED}
    now = {k: v for k, v in cfg.model_dump(mode="json").items() if k not in UNPLAYED}
    changes = config_changes(recorded, now)
    if changes and override is None:
        shown = "\n  ".join(changes[:10]) + ("\n  …" if len(changes) > 10 else "")
        raise RecordingError(
            f"{rec.path} was recorded with another robot configuration than this whexar's "
            f"(recorded → now):\n  {shown}\ngive the configuration to replay with: "
            "--config FILE"
        )
    return path, cfg, changes


def _replay_graph(
    wiring: Mapping[str, Any], config: Path | None, cfg: RobotConfig, clock: Clock = "virtual"
) -> tuple[dict[str, Any], list[str], dict[str, str], dict[str, str]]:
    """The recorded wiring with each device link played back: the graph, the channels to
    feed, actor name → the kind of link it owns, and played-back device → recorded one.
    On a log of a real clock the bus scheduler opens the recorded servos by time, an
    emulated chain (``emulator:NAME``)."""
    graph = json.loads(json.dumps(wiring))  # a deep copy
    if "reflexes" in graph:  # a wiring file as written: its [[reflexes]] become actors
        with_reflexes(graph, source="the recorded wiring", config=config)
    actors = []
    owners: dict[str, str] = {}
    aliases: dict[str, str] = {}
    configured = {
        "whexar.actors.bus:BusScheduler": cfg.bus.port,
        "whexar.actors.sensing:SensorReader": cfg.sensor_board.port,
    }
    for actor in graph.get("actors", []):
        cls = actor["class"] = MOVED.get(actor.get("class", ""), actor.get("class", ""))
        if cls in FED_ACTORS:
            continue
        params = actor.setdefault("params", {})
        if "config" in _param_fields(cls) or "config" in params:
            if config is None:
                params.pop("config", None)
            else:
                params["config"] = str(config)
        if cls in DEVICE_PARAMS:
            setting, emulator_only = DEVICE_PARAMS[cls]
            for key in emulator_only:
                params.pop(key, None)
            played = f"{REPLAY_DEVICE}:{actor['name']}"
            if clock == "real" and cls.endswith(":BusScheduler"):
                played = f"{SERVO_CHAIN.scheme}:{actor['name']}"
            recorded = params.get(setting) or configured.get(cls)
            if recorded:
                aliases[played] = str(recorded)
            params[setting] = played
            owners[actor["name"]] = cls
        actors.append(actor)
    graph["actors"] = actors
    published = {ch for a in actors for ch in (a.get("outputs") or {}).values()}
    fed = [ch for ch in graph.get("channels", {}) if ch not in published and ch != EVENTS_CHANNEL]
    return graph, fed, owners, aliases


def _end(rec: Recording) -> tuple[float, bool]:
    """How far the recording goes (s), and whether that is the run's end (its stop
    recorded too): the run's duration, or where a damaged file's readable part ends."""
    meta = rec.metadata.get("run", {}).get("duration_s")
    duration = None if meta is None else float(meta)
    if duration is not None and rec.damage is None:
        return duration, True
    readable = (rec.last_ns or 0) / 1e9
    if duration is None:
        return readable, rec.damage is None
    return min(duration, readable), readable >= duration


def replay(
    path: str | Path,
    *,
    start: float = 0.0,
    stop: float | None = None,
    speed: float | None = None,
    check: bool = False,
    config: str | Path | None = None,
    record: str | Path | None = None,
    live: LiveSink | None = None,
    progress: Callable[[float, float], None] | None = None,
    tolerance: float = FLOAT_TOLERANCE,
    by_time: bool = False,
    tolerances: Tolerances = DEFAULT_TOLERANCES,
    graph: str | Path | None = None,
    sets: Iterable[tuple[str, object]] = (),
) -> ReplayResult:
    """Replay recording ``path`` (module docstring) and return what it did.

    ``speed``: replayed seconds per wall second from ``start`` on (``None``: as fast as
    possible). ``check``: compare the published messages with the recorded ones: on a
    log of virtual time every message exactly, stopping at the first divergence
    (:attr:`ReplayResult.divergence`; floats within ``tolerance``, :func:`compare`); on
    a log of a real clock, or with ``by_time``, by time within ``tolerances``
    (:attr:`ReplayResult.report`, :mod:`whexar.record.diff`). ``config``: the robot
    configuration file to replay with instead of the recorded one; ``graph`` a wiring
    file to replay instead of the recorded wiring (an added reflex); ``sets`` parameters
    to change, ``("ACTOR.PARAM", value)`` as ``whexar run --set``. ``record``: an MCAP
    file to record the replay into; ``live`` a live view fed as a run's.
    ``progress(t, end)`` is called about every replayed second.
    """
    wall = monotonic()  # reading the recording counts: it is part of a replay
    path = Path(path)
    rec = Recording(path)
    rec.check_compatible()
    recorded_wiring = _wiring(rec)
    wiring = recorded_wiring if graph is None else read_toml(graph)
    clock = recorded_clock(rec)
    timed = check and (clock == "real" or by_time)
    recorded_s, to_the_end = _end(rec)
    if start < 0 or (stop is not None and stop <= start):
        raise UsageError(f"--from {start:g} --to {stop}: the window must have 0 ≤ from < to")
    if start >= recorded_s:
        raise UsageError(f"--from {start:g}: the recording ends at {recorded_s:.3f} s")
    end = recorded_s if stop is None else min(stop, recorded_s)
    whole = end >= recorded_s and to_the_end

    with (
        tempfile.TemporaryDirectory(prefix="whexar-replay-") as tmp,
        contextlib.ExitStack() as on_exit,
    ):
        cfg_path, cfg, changes = _config(rec, Path(config) if config else None, Path(tmp))
        graph_doc, fed, owners, aliases = _replay_graph(wiring, cfg_path, cfg, clock)
        for target, value in sets:
            set_param(graph_doc, target, value, source=str(graph or path), option="--set")
        # The device links and the fed commands are read as the replay goes (module doc).
        reading = _Reading()
        dealer = Dealer(reading.guarded(_links(rec, owners, end, whole)))
        on_exit.callback(dealer.close)
        links = {name: dealer.hand(f"/links/{name}") for name in owners}
        # The commands come from a reading of their own: waiting for the next one (they
        # are seconds apart) would make the dealer queue every byte until it.
        feeds = reading.guarded(_feeds(rec, fed, end))
        on_exit.callback(feeds.close)
        missing = [name for name in owners if not links[name]]
        if missing:
            raise RecordingError(
                f"{path} holds no bytes of the device link of {', '.join(missing)} "
                f"({', '.join(f'/links/{n}' for n in missing)}): it cannot be replayed"
            )
        devices = _devices(owners, links, cfg, clock)
        left_out = {a["name"] for a in recorded_wiring.get("actors", [])} - {
            a["name"] for a in graph_doc["actors"]
        }
        recorded_channels = set(recorded_wiring.get("channels", {}))
        replayed_channels = set(graph_doc.get("channels", {}))
        uncompared = sorted((recorded_channels ^ replayed_channels) - set(fed))
        compared_channels = sorted((recorded_channels & replayed_channels) - set(fed))
        checker: Checker | TimeCheck | None = None
        if check:
            expected = reading.guarded(_expected(rec, compared_channels, left_out, by_time=timed))
            # Where a damaged file is cut, the last instants are only partly there.
            cut = not to_the_end and end >= recorded_s
            window = (start, end - LATE_S if cut else end)
            skip = set(fed) | set(uncompared)
            if timed:
                # The replay stops on its own clock, a cycle before the recorded stop (on
                # a real clock a little late) or at the end of a cut log: its last
                # instants are not compared.
                checker = TimeCheck(expected, tolerances, skip, start, end - LATE_S)
            else:
                checker = Checker(expected, skip, *window, whole)
                checker.comparison = Comparison(aliases, tolerance)
        recorder = None
        if record is not None or live is not None:
            recorder = _recorder(record, live, rec, graph_doc, end)
        observers = [o for o in (checker, recorder) if o is not None]

        fed_counts = dict.fromkeys(fed, 0)

        async def scenario(h: Harness) -> None:
            reading.stop = h.stop
            if isinstance(checker, Checker):
                checker.on_divergence = lambda: h.stop("replay diverged")
                checker.now = h.now
            async with anyio.create_task_group() as tg:
                if recorder is not None:
                    tg.start_soon(recorder.run, h.sleep)
                if progress is not None or speed is not None:
                    tg.start_soon(_clock, h, start, end, speed, progress)
                for t, channel, msg in feeds:
                    if t > h.now():
                        await h.sleep_until(t)
                    await h.feed(channel, msg)
                    fed_counts[channel] += 1
                await h.sleep(math.inf)

        try:
            with _registered(devices):
                result = run_actors(
                    graph_doc,
                    duration=end,
                    scenario=scenario,
                    feeds=fed,
                    observers=observers,
                    link_observer=None if recorder is None else recorder.link_bytes,
                    keep_log=False,  # the checker and the recorder see every message
                )
        finally:
            if recorder is not None:
                recorder.close()
        report = checker.finish() if isinstance(checker, TimeCheck) else None
        wall_s = monotonic() - wall
        if reading.error is not None:
            raise reading.error
        # Stopped at a divergence, the rest of a long recording is not read to count it.
        stopped = isinstance(checker, Checker) and checker.divergence is not None
        if stopped:
            dealer.close()
        described = {name: _describe(device, not stopped) for name, device in devices.items()}
    divergence = None
    if isinstance(checker, Checker):
        divergence = checker.divergence
        if divergence is None:
            divergence = checker.left_over()
        for name, device in devices.items():
            mismatch = _first_mismatch(name, device, start, end, whole)
            if mismatch is not None and (divergence is None or mismatch.t < divergence.t):
                divergence = mismatch
    stopped_at = checker.stopped_at if isinstance(checker, Checker) else math.inf
    replayed = min(result.end_time, end, stopped_at)
    ended_early = None
    if divergence is None and (result.exit_code != 0 or result.end_time < end - 1e-9):
        why = result.stop_reason or f"exit status {result.exit_code}"
        ended_early = f"stopped at t = {result.end_time:.3f} s of {end:.3f} s: {why}"
    return ReplayResult(
        path=path,
        duration_s=replayed,
        recorded_s=recorded_s,
        wall_s=wall_s,
        run=result,
        fed=fed_counts,
        checked=check,
        compared=(
            0 if checker is None else report.compared if report is not None else checker.compared  # type: ignore[union-attr]
        ),
        divergence=divergence,
        links=described,
        damage=None if rec.damage is None else rec.describe_end(),
        config_changes=changes,
        recording=None if recorder is None or record is None else recorder.path,
        clock=clock,
        report=report,
        ended_early=ended_early,
        uncompared=uncompared if check else [],
    )


class TimeCheck:
    """The runtime observer that compares what is published with the recording by time
    (:class:`~whexar.record.diff.TimeDiff`): the recorded messages are read a window
    ahead of what is published, and compared once both runs are past them."""

    def __init__(
        self,
        expected: Iterator[tuple[str, Message]],
        tolerances: Tolerances,
        skip: set[str],
        start: float,
        stop: float,
    ) -> None:
        self._source = expected
        self._next: tuple[str, Message] | None = next(expected, None)
        self._skip = skip
        self._start = start
        self._stop = stop
        self._lead = 2 * tolerances.window_s
        self._advanced = -math.inf
        self.diff = TimeDiff(tolerances)

    def __call__(self, channel: str, msg: Message) -> None:
        if channel in self._skip or not self._start - 1e-12 <= msg.t <= self._stop:
            return
        self.diff.second(channel, msg)
        t = msg.t
        if t > self._advanced + self._lead:
            self._read_to(t + self._lead)
            self.diff.advance(t - self._lead)
            self._advanced = t

    def _read_to(self, t: float) -> None:
        nxt = self._next
        while nxt is not None and nxt[1].t <= t:
            channel, msg = nxt
            if self._start - 1e-12 <= msg.t <= self._stop:
                self.diff.first(channel, msg)
            nxt = next(self._source, None)
        self._next = nxt

    def finish(self) -> DiffReport:
        """Read the rest of the recording's window and compare everything left."""
        self._read_to(self._stop)
        return self.diff.report()


def _expected(
    rec: Recording, channels: Iterable[str], left_out: set[str], *, by_time: bool = False
) -> Iterator[tuple[str, Message]]:
    """The recorded messages of ``channels`` and the events to compare with: in publish
    order (an actor may stamp a message earlier than one published before it), or in
    time order ``by_time``; none from or about an actor the replay leaves out
    (``left_out``: a command source)."""
    topics = [f"/{ch}" for ch in (*channels, EVENTS_CHANNEL)]
    for r in rec.records(topics, file_order=not by_time):
        msg = r.value
        if not isinstance(msg, Message) or isinstance(
            msg, (*RECORDER_EVENTS, WorldFault, WorldDiverged)
        ):
            # The recorder's own events are the disk's, not the actors'; a world fault or
            # divergence is the simulated world's (its effects are in the recorded bytes).
            continue
        if left_out and (
            getattr(msg, "source", None) in left_out or getattr(msg, "actor", None) in left_out
        ):
            continue
        yield r.topic[1:], msg


Device = BusReplay | BoardReplay | I2CReplay | I2CFieldReplay | FieldBus


class _Reading:
    """Keeps what went wrong reading the recording while the replay runs.

    The recording is read inside the actors' calls (a device asking for its next
    bytes, the checker for the next message): an error raised there would be taken for
    the device's or the actor's own, and the replay would go on past it. So the first
    :class:`RecordingError` ends the reading, stops the run, and :func:`replay` raises it.
    """

    def __init__(self) -> None:
        self.error: RecordingError | None = None
        self.stop: Callable[[str], None] = lambda _: None
        """Stops the run (the harness's, once it runs)."""

    def guarded(self, items: Iterator[T]) -> Generator[T]:
        """``items``, ending at a :class:`RecordingError`, which is kept and stops the run."""
        try:
            yield from items
        except RecordingError as exc:
            if self.error is None:
                self.error = exc
            self.stop(f"the recording cannot be read on: {exc}")


def _links(
    rec: Recording, owners: Mapping[str, str], end: float, whole: bool
) -> Iterator[tuple[str, tuple[str, float, bytes]]]:
    """The device-link events of the recording (``(dir, t, bytes)`` keyed by topic), in
    time order, up to where the replay ends."""
    for r in rec.records([f"/links/{n}" for n in owners]):
        value = r.value
        if not isinstance(value, LinkBytes):
            continue
        if not whole and value.t > end + LATE_S:
            # Ended early, the replay stops its own way: past the end (and the cycle in
            # flight at it) nothing answers.
            if r.t > end + 2 * LATE_S:
                return  # time order: nothing later is wanted
            continue
        yield r.topic, (value.direction, value.t, value.data)


def _feeds(rec: Recording, fed: list[str], end: float) -> Generator[tuple[float, str, Message]]:
    """The recorded messages of the fed channels (``(t, channel, message)``), in time
    order, up to where the replay ends."""
    topics = {f"/{ch}": ch for ch in fed}
    for r in rec.records(topics):
        if isinstance(r.value, Message):
            if r.value.t > end:
                return
            yield r.value.t, topics[r.topic], r.value


def _devices(
    owners: Mapping[str, str],
    links: Mapping[str, Iterable[tuple[str, float, bytes]]],
    cfg: RobotConfig,
    clock: Clock = "virtual",
) -> dict[str, Device]:
    """The played-back devices: byte for byte (virtual time), or by time (a real clock)."""
    devices: dict[str, Device] = {}
    for name, cls in owners.items():
        events = links.get(name, ())
        if cls.endswith(":BusScheduler"):
            if clock == "real":
                devices[name] = FieldBus(events, models=cfg.servos(), baudrate=cfg.bus.baudrate)
            else:
                devices[name] = BusReplay(events, baudrate=cfg.bus.baudrate)
        elif cls.endswith(":SensorReader"):
            devices[name] = BoardReplay(events)
        elif clock == "real":
            devices[name] = I2CFieldReplay(events)
        else:
            devices[name] = I2CReplay(events)
    return devices


@contextlib.contextmanager
def _registered(devices: Mapping[str, Device]) -> Iterator[None]:
    """Each played-back device registered under its actor's name for the run."""
    with contextlib.ExitStack() as stack:
        for name, device in devices.items():
            entry: contextlib.AbstractContextManager[Any]
            if isinstance(device, FieldBus):
                entry = DEVICES.registered(SERVO_CHAIN, name, device.chain)
            elif isinstance(device, BusReplay):
                entry = DEVICES.registered(REPLAYED_BUS, name, device)
            elif isinstance(device, BoardReplay):
                entry = DEVICES.registered(REPLAYED_BOARD, name, device)
            else:
                entry = DEVICES.registered(REPLAYED_I2C, name, device)
            stack.enter_context(entry)
        yield


def _first_mismatch(
    name: str, device: Device, start: float, end: float, whole: bool
) -> Divergence | None:
    if isinstance(device, FieldBus):
        return None  # by time: its writes are reported, not a divergence of bytes
    if isinstance(device, BusReplay):
        port = device.port
        m = None if port is None else port.first_mismatch
    else:
        m = device.first_mismatch  # type: ignore[assignment]
    if m is None or m.t < start or (m.t >= end and not whole):
        return None  # outside the window: after --to, the stop is not the recorded one
    return Divergence(
        "link", f"links/{name}", m.t, "packet", m.recorded.hex(" "), m.written.hex(" ")
    )


def _describe(device: Device, count: bool) -> str:
    """What a played-back device did; ``count``: read the rest of the recording to count
    what the replay left (not when it stopped at a divergence)."""
    if isinstance(device, BusReplay):
        port = device.port
        if port is None:
            return f"{device.left()} recorded packets, never opened"
        of = f"/{port.next + device.left()}" if count else ""
        return (
            f"{port.next}{of} recorded packets written, "
            f"{port.mismatches} differing, {port.unrecorded_timeouts} waits not recorded"
        )
    if isinstance(device, FieldBus):
        return device.describe()
    if isinstance(device, BoardReplay):
        left = f"{device.incoming.left()} recorded chunks left, " if count else ""
        return f"{left}{device.mismatches} sends differing"
    if isinstance(device, I2CFieldReplay):
        return (
            f"by time: {device.held_calls} calls answered with the last value held, "
            f"{device.skipped_calls} recorded calls not made, "
            f"{device.mismatches} calls differing"
        )
    left = f"{device.events.left()} recorded calls left, " if count else ""
    return f"{left}{device.mismatches} calls differing"


async def _clock(
    h: Harness,
    start: float,
    end: float,
    speed: float | None,
    progress: Callable[[float, float], None] | None,
) -> None:
    """Pace the replay (``speed`` from ``start`` on) and report progress every second."""
    step = 1.0 if speed is None else min(1.0, 0.05 * speed)
    t = 0.0
    wall0: float | None = None
    while t < end:
        t = min(end, t + step)
        await h.sleep_until(t)
        if speed is not None and t >= start:
            if wall0 is None:
                wall0 = monotonic() - (t - start) / speed
            wait_until(wall0 + (t - start) / speed)
        if progress is not None:
            progress(t, end)


def _recorder(
    record: str | Path | None,
    live: LiveSink | None,
    rec: Recording,
    graph: Mapping[str, Any],
    end: float,
) -> Recorder:
    import os

    attachments: dict[str, str | bytes] = {"wiring.json": json.dumps(graph, indent=1)}
    for name in (URDF_ATTACHMENT, CONFIG_ATTACHMENT, EFFECTIVE_CONFIG_ATTACHMENT):
        if name in rec.attachments:
            attachments[name] = rec.attachments[name].data
    recorder = Recorder(
        record if record is not None else os.devnull,
        # Where this replay stops is its run's duration: a replay of it stops there too.
        metadata={
            "kind": "replay",
            "clock": "virtual",
            "replayed": str(rec.path),
            "duration_s": repr(end),
        },
        attachments=attachments,
        live=live,
    )
    urdf = rec.attachments.get(URDF_ATTACHMENT)
    if urdf is not None:
        recorder.robot_description(urdf.data.decode("utf-8"))
    return recorder
