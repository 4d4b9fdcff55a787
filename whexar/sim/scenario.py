"""Scenario files: a terrain, a start pose, a command timeline, faults, a duration and a seed.

Theory of operation
-------------------
A scenario is a TOML file (``config/scenarios/*.toml``; :func:`load_scenario`
takes a bare name for those) validated like the robot configuration: strict
pydantic sections (:mod:`whexar.runtime.schema`), and every problem listed at
once with its key path, the value found and what is allowed, before anything
runs. ::

    name = "slope"
    description = "Walk up a 15° plane in the tetrapod gait."
    duration_s = 30.0
    seed = 0
    terrain = "slope15"          # a built-in terrain, or a table (below)
    faults = "../faults/noisy-bus.toml"   # optional: a bus fault plan
    config = "../whexar.toml"             # optional: a robot configuration

    [start]
    x_m = 0.0
    y_m = 0.0
    yaw_deg = 0.0

    [[commands]]
    t = 3.0
    vx_m_s = 0.06
    gait = "tetrapod"

*Terrain.* A built-in name (:data:`~whexar.sim.terrain.TERRAIN_NAMES`, or
``slope<deg>``), or a table of features added onto a built-in ``base``
(default ``flat``), each mapped onto one builder of :mod:`whexar.sim.terrain`:
``slope_deg`` (an endless tilted plane, 0–50°), ``[terrain.ramp]``,
``[terrain.steps]``, ``[[terrain.blocks]]`` (static, or free with a
``mass_kg``), ``[terrain.ditch]``, ``[terrain.rocks]`` (placed by the rocks'
``seed``, else the scenario's). Lengths carry their unit in the key, as in
the configuration. A feature its builder refuses (a ditch in a slope) is a
problem of its own key (``terrain.ditch``); a ditch under the start, of ``terrain``.

*Commands.* Each table is one :class:`~whexar.actors.messages.MotionCommand`
at time ``t`` (seconds from the start; times never go backwards). The keys and
their types are those of command scripts (:data:`whexar.actors.commands.MOTION_FIELDS`
is the one list); beyond that, a command the coordinator would refuse is an
error here, before the run starts: an unknown gait, mode or stance (the
stances of the scenario's configuration), a turn radius inside the body,
riding upside down. Speeds beyond the robot's are not errors: the coordinator
clamps them and says so with an event, as on the robot.

*Tilt.* ``[tilt]`` raises the board under the robot as the thesis's slope
experiments did (6.7.6): gravity turns about y from ``start_s`` at ``rate_deg_s``
up to ``max_deg`` (:mod:`whexar.sim.tilt`).

*Paths* (``faults``, ``config``) are relative to the scenario file's folder;
:func:`load_scenario` can take another configuration in place of ``config``
(``whexar sim --config``).

*Supply and motors.* ``[supply]`` picks what feeds the servos
(:mod:`whexar.sim.power`): ``kind = "bench"`` (the default: the experiments'
12 V bench supply, ``volts`` to change it) or ``kind = "lipo"``, the robot's
3S Li-Po (5.3.1) with ``capacity_ah`` (6), ``charge`` (the state of charge at
the start, 0–1) and ``cell_resistance_ohm``. A Li-Po's voltage is the
world's to set, so a bus fault plan with a ``voltage_sag`` is refused with
it. ``motors`` is ``"bam"`` (the default) or ``"datasheet"``
(:func:`whexar.sim.motors.motors`). ::

    motors = "datasheet"

    [supply]
    kind = "lipo"
    capacity_ah = 6.0
    charge = 0.8

*Seed.* The world is deterministic on virtual time; the seed places the
random features of a table terrain (rocks without a seed of their own) and, with
``spread = true`` (default false: the nominal robot), draws the robot's parts
within their datasheets' spread (:mod:`whexar.sim.spread`): sensor gains and
offsets, wheel friction, masses, backlash, reply delays. A
fault plan keeps its own seed.

*Faults.* Besides a bus fault plan (``faults``), sensor faults are ``[[sensor_faults]]``
tables (:class:`~whexar.sim.faults.SensorFault`: a board or IMU unplugged, corrupted or
dropped frames, a frozen IMU, a dead force sensor or rangefinder, at a time), and the
world's physical faults ``[[world_faults]]`` tables, each of a ``kind`` with its own
keys (:mod:`whexar.sim.faults` has them all): ``push`` (a force on the body),
``slippery`` (the ground's friction under a wheel or an area), ``limp`` (servos without
power: no torque, no reply) and ``snag`` (a joint held), each from ``at_s`` for
``duration_s``. ::

    [[world_faults]]
    kind = "push"
    at_s = 4.0
    force_n = 60.0
    heading_deg = 90.0
    duration_s = 0.3

    [[world_faults]]
    kind = "snag"
    at_s = 7.0
    leg = 2
    joint = "tibia"
    duration_s = 1.0
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Final, Literal

from pydantic import AfterValidator, Discriminator, Field, Tag, ValidationError

from whexar.actors.commands import motion_fields
from whexar.actors.messages import MotionCommand
from whexar.config import RobotConfig, load_config
from whexar.errors import MISSING, ConfigError, Problem, UsageError
from whexar.runtime.schema import (
    CheckedSection,
    Finite,
    NonNegative,
    Positive,
    Section,
    builtin_names,
    builtin_path,
    problem_from_error,
    read_toml,
)
from whexar.sim import terrain as tr
from whexar.sim.faults import SensorFault, WorldFaultSpec, check_world_faults
from whexar.sim.motors import DEFAULT_MOTORS, MotorSource
from whexar.sim.power import (
    BENCH_VOLTS,
    LIPO_CAPACITY_AH,
    LIPO_CELL_RESISTANCE_OHM,
    BenchSupply,
    LiPoBattery,
    Supply,
)
from whexar.sim.tilt import BoardTilt

if TYPE_CHECKING:
    from whexar.record.writer import LiveSink
    from whexar.sim.run import Sample, SimResult
    from whexar.sim.world import SimWorld

SCENARIO_DIR: Final = Path(__file__).resolve().parents[2] / "config" / "scenarios"
"""The built-in scenarios: the repository's ``config/scenarios`` folder."""
DEFAULT_SCENARIO: Final = "course"
COMMAND_SOURCE: Final = "scenario"
"""The ``source`` of every command a scenario sends."""

# --------------------------------------------------------------------------- the document


def _known_terrain(name: str) -> str:
    try:
        tr.terrain_by_name(name)
    except UsageError:
        raise ValueError(
            f"a built-in terrain: {', '.join(tr.TERRAIN_NAMES)}, or slope<deg> (0–50)"
        ) from None
    return name


TerrainName = Annotated[str, AfterValidator(_known_terrain)]
Degrees = Annotated[float, Field(ge=-180, le=180, allow_inf_nan=False)]


class RampSpec(Section):
    """A finite incline on the flat, up and down again (:func:`whexar.sim.terrain.ramp`)."""

    angle_deg: float = Field(gt=0, le=tr.MAX_SLOPE_DEG, allow_inf_nan=False)
    rise_mm: Positive
    at_m: Finite = 2.0
    plateau_m: NonNegative = 1.0
    width_m: Positive = 2.0


class StepsSpec(Section):
    """A staircase (:func:`whexar.sim.terrain.steps`)."""

    height_mm: Positive
    depth_mm: Positive
    count: int = Field(ge=1, le=50)
    at_m: Finite = 1.0
    width_m: Positive = 2.0
    landing_m: NonNegative = 1.0
    down: bool = True


class BlockSpec(Section):
    """A box on the floor (:func:`whexar.sim.terrain.block`): static, or free with a mass."""

    size_mm: tuple[Positive, Positive, Positive]
    """Full size along x, y, z."""
    at_m: tuple[Finite, Finite]
    """Centre (x, y) on the floor."""
    mass_kg: Positive | None = None
    """A free, pushable block (thesis 6.7.2); absent: static."""
    yaw_deg: Degrees = 0.0


class DitchSpec(Section):
    """A ditch across the floor (:func:`whexar.sim.terrain.ditch`)."""

    width_mm: Positive
    depth_mm: Positive
    at_m: Finite


class RocksSpec(Section):
    """Scattered rocks (:func:`whexar.sim.terrain.rocks`)."""

    count: int = Field(ge=0, le=500)
    size_mm: Positive = 40.0
    seed: int | None = Field(default=None, ge=0)
    """Their placement; absent: the scenario's seed."""
    area_m: tuple[tuple[Finite, Finite], tuple[Finite, Finite]] = ((1.0, 3.0), (-0.6, 0.6))
    """((x_min, x_max), (y_min, y_max))."""

    def problems(self, at: str) -> list[Problem]:
        (x0, x1), (y0, y1) = self.area_m
        if x0 < x1 and y0 < y1:
            return []
        return [Problem(f"{at}.area_m", self.area_m, "((x_min, x_max), (y_min, y_max)), min < max")]


class TerrainSpec(Section):
    """A terrain described by its features, added onto a built-in ``base``."""

    base: TerrainName = "flat"
    slope_deg: float | None = Field(default=None, ge=0, le=tr.MAX_SLOPE_DEG, allow_inf_nan=False)
    """An endless plane tilted about y, rising along +x (the robot starts facing uphill)."""
    ramp: RampSpec | None = None
    steps: StepsSpec | None = None
    blocks: tuple[BlockSpec, ...] = ()
    ditch: DitchSpec | None = None
    rocks: RocksSpec | None = None

    def problems(self, at: str) -> list[Problem]:
        return self.rocks.problems(f"{at}.rocks") if self.rocks is not None else []


class TiltSpec(Section):
    """The board raised under the robot (:class:`whexar.sim.tilt.BoardTilt`), as the thesis
    found its steepest slopes (6.7.6): rising along +x from ``start_s`` at ``rate_deg_s``
    up to ``max_deg``."""

    start_s: NonNegative = 6.0
    rate_deg_s: float = Field(default=1.0, gt=0, le=10, allow_inf_nan=False)
    max_deg: float = Field(default=55.0, gt=0, lt=90, allow_inf_nan=False)

    def board(self) -> BoardTilt:
        return BoardTilt(self.start_s, self.rate_deg_s, self.max_deg)


_LIPO_KEYS: Final = ("capacity_ah", "charge", "cell_resistance_ohm")


class SupplySpec(Section):
    """What feeds the servos (see the module docstring)."""

    kind: Literal["bench", "lipo"] = "bench"
    volts: Positive | None = None
    """bench: its voltage (default 12 V, 5.3.1)."""
    capacity_ah: Positive | None = None
    """lipo: its capacity (default 6 Ah, 5.3.1)."""
    charge: float | None = Field(default=None, ge=0, le=1, allow_inf_nan=False)
    """lipo: its state of charge at the start, 0–1 (default 1: full)."""
    cell_resistance_ohm: NonNegative | None = None
    """lipo: internal resistance per cell (default :data:`LIPO_CELL_RESISTANCE_OHM`)."""

    def problems(self, at: str) -> list[Problem]:
        found: list[Problem] = []
        if self.kind == "bench":
            for key in _LIPO_KEYS:
                if getattr(self, key) is not None:
                    found.append(
                        Problem(f"{at}.{key}", getattr(self, key), 'only with kind = "lipo"')
                    )
        elif self.volts is not None:
            found.append(
                Problem(
                    f"{at}.volts",
                    self.volts,
                    'only with kind = "bench": a Li-Po\'s voltage follows its charge',
                )
            )
        return found

    def build(self) -> Supply:
        """A fresh supply for one run."""
        if self.kind == "bench":
            return BenchSupply(self.volts if self.volts is not None else BENCH_VOLTS)
        return LiPoBattery(
            capacity_ah=self.capacity_ah if self.capacity_ah is not None else LIPO_CAPACITY_AH,
            initial_charge=self.charge if self.charge is not None else 1.0,
            cell_resistance_ohm=(
                self.cell_resistance_ohm
                if self.cell_resistance_ohm is not None
                else LIPO_CELL_RESISTANCE_OHM
            ),
        )


class StartSpec(Section):
    """Where the robot starts, seated: the body centre over the floor and its heading."""

    x_m: Finite = 0.0
    y_m: Finite = 0.0
    yaw_deg: Degrees = 0.0


class ScenarioFile(CheckedSection):
    """The TOML document of a scenario (see the module docstring)."""

    name: str | None = Field(default=None, min_length=1)
    """Absent: the file's name without ``.toml``."""
    description: str = ""
    duration_s: Positive
    seed: int = Field(default=0, ge=0)
    spread: bool = False
    """Draw the robot's parts from the seed (:mod:`whexar.sim.spread`); off: the
    datasheets' nominal robot, the same run for every seed but the terrain's."""
    terrain: Annotated[
        Annotated[TerrainName, Tag("<name>")] | Annotated[TerrainSpec, Tag("<table>")],
        # Tagged as in the configuration's bus.plan: a bad table is reported as a table.
        Discriminator(lambda v: "<name>" if isinstance(v, str) else "<table>"),
    ] = "flat"
    start: StartSpec = StartSpec()
    commands: tuple[dict[str, Any], ...] = ()
    """Tables ``{t = …, <MotionCommand fields>}``, checked by :func:`check_commands`."""
    faults: str | None = Field(default=None, min_length=1)
    """A bus fault plan (``config/faults/*.toml``), relative to the scenario's folder."""
    sensor_faults: tuple[SensorFault, ...] = ()
    """The sensors' faults (:mod:`whexar.sim.faults`), ``[[sensor_faults]]`` tables."""
    world_faults: tuple[Any, ...] = ()
    """The world's physical faults, ``[[world_faults]]`` tables, checked by
    :func:`~whexar.sim.faults.check_world_faults` (each by the keys of its kind)."""
    config: str | None = Field(default=None, min_length=1)
    """A robot configuration file, relative to the scenario's folder; absent: the defaults."""
    tilt: TiltSpec | None = None
    """The board raised under the robot, ``[tilt]``; absent: the floor stays as it is."""
    supply: SupplySpec = SupplySpec()
    """What feeds the servos: the bench supply (default) or the Li-Po."""
    motors: MotorSource = DEFAULT_MOTORS
    """The servos' motors: BAM's identification or their datasheets' lines."""

    def problems(self, at: str = "") -> list[Problem]:
        found: list[Problem] = self.supply.problems("supply")
        if isinstance(self.terrain, TerrainSpec):
            found.extend(self.terrain.problems("terrain"))
        for k, fault in enumerate(self.sensor_faults):
            found.extend(fault.problems(f"sensor_faults[{k}]"))
        return found


# --------------------------------------------------------------------------- the scenario


@dataclass(frozen=True)
class Scenario:
    """A checked scenario, ready to run: everything resolved, nothing left to fail on."""

    name: str
    description: str
    duration_s: float
    seed: int
    terrain: tr.Terrain
    start: tuple[float, float, float]
    """(x m, y m, yaw rad) of the body, seated."""
    commands: tuple[tuple[float, MotionCommand], ...]
    faults: Path | None
    config: RobotConfig
    config_path: Path | None
    """The configuration file the run reads (``None``: the built-in defaults)."""
    source: str
    """The file it came from (or ``<scenario>``)."""
    spec: ScenarioFile
    """The document, kept so that :meth:`with_overrides` can rebuild a seeded terrain."""
    spread: bool = False
    """Whether the seed draws the robot's parts too (:mod:`whexar.sim.spread`)."""
    world_faults: tuple[WorldFaultSpec, ...] = ()
    """The world's physical faults (:mod:`whexar.sim.faults`)."""

    def with_overrides(
        self,
        *,
        duration_s: float | None = None,
        seed: int | None = None,
        spread: bool | None = None,
    ) -> Scenario:
        """The same scenario for another duration, seed or spread (the command line's
        options)."""
        if duration_s is not None and not (math.isfinite(duration_s) and duration_s > 0):
            raise UsageError(f"duration {duration_s!r}: expected a number of seconds > 0")
        if seed is not None and seed < 0:
            raise UsageError(f"seed {seed!r}: expected an integer ≥ 0")
        out = self
        if seed is not None and seed != self.seed:
            problems: list[Problem] = []
            terrain = _terrain(self.spec.terrain, seed, problems)
            if problems or terrain is None:
                raise ConfigError(self.source, problems)
            out = replace(out, seed=seed, terrain=terrain)
        if duration_s is not None:
            out = replace(out, duration_s=duration_s)
        if spread is not None:
            out = replace(out, spread=spread)
        return out

    def run(
        self,
        *,
        on_sample: Callable[[Sample, SimWorld], None] | None = None,
        record: str | Path | None = None,
        live: LiveSink | None = None,
        keep_log: bool = False,
    ) -> SimResult:
        """Run it (:func:`whexar.sim.run.simulate`); ``on_sample`` sees every sample,
        ``record`` is an MCAP file to record the run into, ``live`` a live view;
        ``keep_log`` keeps every message in the result's log too."""
        from whexar.sim.run import simulate

        return simulate(
            terrain=self.terrain,
            commands=self.commands,
            duration=self.duration_s,
            config=self.config_path,
            faults=self.faults,
            sensor_faults=self.spec.sensor_faults,
            start=self.start,
            on_sample=on_sample,
            record=record,
            live=live,
            tilt=self.spec.tilt.board() if self.spec.tilt is not None else None,
            keep_log=keep_log,
            record_metadata={
                "scenario": self.name,
                "seed": str(self.seed),
                "spread": str(self.spread).lower(),
            },
            supply=self.spec.supply.build(),
            motor_source=self.spec.motors,
            spread=self.seed if self.spread else None,
            world_faults=self.world_faults,
        )


def scenario_names() -> tuple[str, ...]:
    """The built-in scenarios, by name."""
    return builtin_names(SCENARIO_DIR)


def scenario_path(name_or_path: str | Path) -> Path:
    """A scenario's file: a bare name (no folder, no ``.toml``) is a built-in scenario."""
    return builtin_path(name_or_path, SCENARIO_DIR, "scenario")


def load_scenario(
    name_or_path: str | Path = DEFAULT_SCENARIO, *, config: str | Path | None = None
) -> Scenario:
    """Read and check a scenario: a built-in name (``"course"``) or a TOML file;
    ``config``, a robot configuration file, replaces the scenario's own (``config``).

    Raises :class:`~whexar.errors.ConfigError` naming the file and listing
    every problem (key path, value, what is allowed), before anything runs; the
    commands are checked against the configuration the run will read.
    """
    path = scenario_path(name_or_path)
    data = read_toml(path)
    if config is not None:
        data = {**data, "config": str(Path(config).resolve())}
    return parse_scenario(data, str(path), base=path.parent, stem=path.stem)


def parse_scenario(
    data: Mapping[str, Any],
    source: str = "<scenario>",
    *,
    base: Path | None = None,
    stem: str = "scenario",
) -> Scenario:
    """Check a scenario document (as parsed from TOML); relative paths start at ``base``.

    Raises :class:`~whexar.errors.ConfigError` listing every problem.
    """
    folder = base if base is not None else Path.cwd()
    try:
        spec = ScenarioFile.model_validate(data, context={"defer_relations": True})
    except ValidationError as exc:
        problems = [problem_from_error(e, ScenarioFile) for e in exc.errors(include_url=False)]
        # The commands are checked even when another key is bad: one bad key hides none.
        commands = data.get("commands")
        if isinstance(commands, list) and not any(
            e["loc"] and e["loc"][0] == "commands" for e in exc.errors()
        ):
            check_commands(commands, RobotConfig(), problems)
        world = data.get("world_faults")
        if isinstance(world, list) and not any(
            e["loc"] and e["loc"][0] == "world_faults" for e in exc.errors()
        ):
            check_world_faults(world, RobotConfig().servos(), problems)
        raise ConfigError(source, problems) from None
    problems = spec.problems()
    cfg = robot_config(spec.config, folder, problems)
    faults = _faults(spec.faults, folder, problems)
    if faults is not None and spec.supply.kind == "lipo" and _sags(faults):
        problems.append(
            Problem(
                "faults",
                spec.faults,
                'a plan without voltage_sag faults with supply.kind = "lipo": the battery '
                "sets the servos' voltage",
            )
        )
    commands = check_commands(spec.commands, cfg or RobotConfig(), problems)
    world_faults = check_world_faults(spec.world_faults, (cfg or RobotConfig()).servos(), problems)
    terrain = _terrain(spec.terrain, spec.seed, problems)
    if terrain is not None:
        x = spec.start.x_m
        for x0, width, _ in terrain.ground.ditches:
            if x0 <= x <= x0 + width:
                problems.append(
                    Problem(
                        "terrain",
                        _shown_terrain(spec.terrain),
                        f"ground under the start (start.x_m = {x:g}): a ditch spans "
                        f"x = {x0:g}…{x0 + width:g} m",
                    )
                )
    if problems or cfg is None or terrain is None:
        raise ConfigError(source, problems)
    return Scenario(
        name=spec.name or stem,
        description=spec.description,
        duration_s=spec.duration_s,
        seed=spec.seed,
        terrain=terrain,
        start=(spec.start.x_m, spec.start.y_m, math.radians(spec.start.yaw_deg)),
        commands=commands,
        faults=faults,
        config=cfg,
        config_path=folder / spec.config if spec.config is not None else None,
        source=source,
        spec=spec,
        spread=spec.spread,
        world_faults=world_faults,
    )


# --------------------------------------------------------------------------- the parts


def robot_config(name: str | None, folder: Path, problems: list[Problem]) -> RobotConfig | None:
    """The robot configuration file ``name`` (from ``folder``; ``None``: the defaults), or
    ``None`` with its problems added as one of the key ``config``."""
    if name is None:
        return RobotConfig()
    try:
        return load_config(folder / name)
    except ConfigError as exc:
        found = "; ".join(str(p) for p in exc.problems)
        problems.append(Problem("config", name, f"a robot configuration without problems; {found}"))
        return None


def _faults(name: str | None, folder: Path, problems: list[Problem]) -> Path | None:
    if name is None:
        return None
    from whexar.bus.emulator.faults import load_fault_plan

    path = folder / name
    try:
        load_fault_plan(path)
    except ConfigError as exc:
        found = "; ".join(str(p) for p in exc.problems)
        problems.append(Problem("faults", name, f"a bus fault plan without problems; {found}"))
        return None
    return path


def _sags(path: Path) -> bool:
    from whexar.bus.emulator.faults import load_fault_plan

    return any(f.kind == "voltage_sag" for f in load_fault_plan(path).faults)


def _shown_terrain(value: str | TerrainSpec) -> object:
    return value if isinstance(value, str) else value.model_dump(exclude_defaults=True)


def _terrain(value: str | TerrainSpec, seed: int, problems: list[Problem]) -> tr.Terrain | None:
    """The terrain a scenario describes; a feature its builder refuses is a problem."""
    if isinstance(value, str):
        return tr.terrain_by_name(value)
    parts: list[tuple[str, Callable[[], tr.Terrain]]] = []
    if value.slope_deg is not None:
        angle = value.slope_deg
        parts.append(("slope_deg", lambda: tr.slope(angle)))
    if value.ramp is not None:
        r = value.ramp
        parts.append(
            (
                "ramp",
                lambda: tr.ramp(
                    r.angle_deg, r.rise_mm / 1000, at=r.at_m, plateau=r.plateau_m, width=r.width_m
                ),
            )
        )
    if value.steps is not None:
        s = value.steps
        parts.append(
            (
                "steps",
                lambda: tr.steps(
                    s.height_mm / 1000,
                    s.depth_mm / 1000,
                    s.count,
                    at=s.at_m,
                    width=s.width_m,
                    landing=s.landing_m,
                    down=s.down,
                ),
            )
        )
    for i, b in enumerate(value.blocks):
        parts.append((f"blocks[{i}]", _block_builder(b)))
    if value.ditch is not None:
        d = value.ditch
        parts.append(("ditch", lambda: tr.ditch(d.width_mm / 1000, d.depth_mm / 1000, d.at_m)))
    if value.rocks is not None and not value.rocks.problems("rocks"):  # else reported already
        k = value.rocks
        rock_seed = k.seed if k.seed is not None else seed
        parts.append(
            ("rocks", lambda: tr.rocks(k.count, rock_seed, k.size_mm / 1000, area=k.area_m))
        )
    terrain = tr.terrain_by_name(value.base)
    for key, build in parts:
        # Each feature is built and added on its own, so every refused one is reported.
        try:
            terrain = terrain + build()
        except UsageError as exc:
            problems.append(Problem(f"terrain.{key}", _feature(value, key), str(exc)))
    return terrain.named(value.base if not parts else f"{value.base}+features")


def _feature(value: TerrainSpec, key: str) -> object:
    if key.startswith("blocks["):
        return value.blocks[int(key[7:-1])].model_dump()
    found = getattr(value, key)
    return found.model_dump() if isinstance(found, Section) else found


def _block_builder(b: BlockSpec) -> Callable[[], tr.Terrain]:
    size = (b.size_mm[0] / 1000, b.size_mm[1] / 1000, b.size_mm[2] / 1000)
    return lambda: tr.block(size, b.at_m, b.mass_kg, yaw=math.radians(b.yaw_deg))


def check_commands(
    tables: Sequence[object], cfg: RobotConfig, problems: list[Problem]
) -> tuple[tuple[float, MotionCommand], ...]:
    """The command timeline: each table a :class:`MotionCommand` at its ``t``.

    Adds a problem for every key the command scripts would refuse (an unknown
    key, a value of the wrong type or outside its choices: the same
    :data:`~whexar.actors.commands.MOTION_FIELDS`), for a missing or bad
    ``t`` or one earlier than the one before, and for a command the
    coordinator would refuse (an unknown stance, a turn radius inside the
    body, riding upside down).
    """
    loco = cfg.locomotion
    inner = loco.min_turn_radius_mm / 1000
    mode, upside = "walk", False  # what the coordinator starts in
    latest: float | None = None
    out: list[tuple[float, MotionCommand]] = []
    for i, table in enumerate(tables):
        at = f"commands[{i}]"
        if not isinstance(table, Mapping):
            problems.append(Problem(at, table, "a table such as { t = 3.0, vx_m_s = 0.1 }"))
            continue
        found: list[Problem] = []
        t = table.get("t", MISSING)
        if t is MISSING:
            found.append(
                Problem(f"{at}.t", MISSING, "required key is missing: seconds from the start")
            )
        elif isinstance(t, bool) or not isinstance(t, int | float) or not math.isfinite(t) or t < 0:
            found.append(Problem(f"{at}.t", t, "a finite number of seconds ≥ 0 from the start"))
        elif latest is not None and t < latest:
            found.append(
                Problem(f"{at}.t", t, f"at least {latest:g}, the t before it: times never go back")
            )
        else:
            latest = float(t)
        fields = motion_fields(table, at, found, sep=".")
        stance = fields.get("stance")
        if stance is not None and stance not in cfg.stances:
            found.append(
                Problem(
                    f"{at}.stance", stance, f"a stance preset: {', '.join(sorted(cfg.stances))}"
                )
            )
        radius = fields.get("turn_radius_m")
        if radius is not None and abs(radius) < inner:
            found.append(
                Problem(
                    f"{at}.turn_radius_m",
                    radius,
                    f"|R| ≥ {inner:g} m (locomotion.min_turn_radius_mm): a smaller circle's "
                    "centre lies inside the body; spin with yaw_rate_rad_s instead",
                )
            )
        new_mode = fields.get("mode") or mode
        new_upside = upside if fields.get("upside_down") is None else bool(fields["upside_down"])
        if new_upside and new_mode != "walk" and not found:
            key = "mode" if "mode" in fields else "upside_down"
            found.append(
                Problem(
                    f"{at}.{key}",
                    fields.get(key),
                    "walk while upside down: the wheels face the sky (6.8.1)",
                )
            )
        problems.extend(found)
        if not found:
            mode, upside = new_mode, new_upside
            time = float(t)
            out.append((time, MotionCommand(t=time, source=COMMAND_SOURCE, **fields)))
    return tuple(out)


def describe_command(cmd: MotionCommand) -> str:
    """A short label of what a command changes (``ride vx 0.15``), for plots and progress."""
    parts: list[str] = []
    if cmd.stop:
        parts.append("stop")
    for key, label in (("mode", ""), ("gait", ""), ("stance", "stance ")):
        value = getattr(cmd, key)
        if value is not None:
            parts.append(f"{label}{value}")
    for key, label in (
        ("vx_m_s", "vx"),
        ("vy_m_s", "vy"),
        ("yaw_rate_rad_s", "ω"),
        ("turn_radius_m", "R"),
        ("step_height_m", "step h"),
        ("body_height_m", "height"),
    ):
        value = getattr(cmd, key)
        if value is not None:
            parts.append(f"{label} {value:g}")
    if cmd.upside_down is not None:
        parts.append("flip" if cmd.upside_down else "upright")
    return " ".join(parts) or "(no change)"


__all__ = [
    "DEFAULT_SCENARIO",
    "SCENARIO_DIR",
    "Scenario",
    "ScenarioFile",
    "SupplySpec",
    "check_commands",
    "describe_command",
    "load_scenario",
    "parse_scenario",
    "robot_config",
    "scenario_names",
    "scenario_path",
]
