"""Robot configuration: pydantic models of everything physical or tunable.

Every default is a value of the reference thesis (Žák 2023, *Biology-Inspired
Control of a Walking Robot*), so ``RobotConfig()`` *is* WHexaR; the file
``config/whexar.toml`` spells the same values out, key by key, with sources.

Unit rule: the file names every unit in its keys (``_mm``, ``_deg``, ``_g``,
``_us``, ``_hz``, ``_counts``…); code converts to SI once, at the edge: the
``*_rad`` properties, and :meth:`RobotConfig.leg_geometry` and
:meth:`RobotConfig.stance`, which build what the kinematics takes. The
kinematics never reads the configuration; the configuration calls it to
check that every stance preset is reachable.

A file needs only the keys it changes: :func:`merge_defaults` merges it into
``RobotConfig()`` first — tables key by key, recursively (mapping-valued
sections such as ``stances`` too, so a stance can be added or partly
changed), arrays (``legs``) whole. Then validation runs on the merged
document in two layers, so that one bad key never hides another:

1. per key — types, ranges, allowed values, unknown keys (pydantic);
2. relations — servo IDs unique, limits ordered, DH lengths consistent with
   segment lengths, gait thresholds ordered along the gait ranking, stance
   presets reachable. Checks inside one section run whenever that section is
   valid on its own; checks across sections run once every section is.

:func:`load_config` raises :class:`~whexar.errors.ConfigError` listing every
:class:`~whexar.errors.Problem` found (key path, bad value, what is allowed).

The sections, by module: :mod:`~.parts` (body, servo models, joints, DH, legs),
:mod:`~.links` (bus, sensor board, IR, FSR, IMU), :mod:`~.motion` (gait selector,
stances, locomotion), :mod:`~.gamepad` (the gamepad's mapping), :mod:`~.recording` (the
recordings' budget on the disk), :mod:`~.reflexes` (the reflexes it runs),
:mod:`~.loading` (the whole robot, its cross-checks, loading and the schema);
:mod:`~.common` what they share. Import every name from here.

May import: the device links (:mod:`whexar.bus`, :mod:`whexar.sensors`),
:mod:`whexar.kinematics`, :mod:`whexar.robot`, :mod:`whexar.errors` and
:mod:`whexar.runtime`; never the actors or anything above them.
"""

from whexar.config.common import DH_SEGMENT_TOLERANCE_MM, AdcCounts, ServoModelName
from whexar.config.gamepad import GamepadSpec, StickSpec
from whexar.config.links import (
    AccelerometerSpec,
    BoardBaudrate,
    BusSpec,
    FSRSpec,
    GravityTolerance,
    ImuSpec,
    IRSpec,
    SensorBoardSpec,
    board_baudrate,
)
from whexar.config.loading import (
    ConfigFile,
    RobotConfig,
    config_schema,
    default_geometry,
    load_config,
    merge_defaults,
    parse_config,
)
from whexar.config.motion import (
    ContactSource,
    ContactSpec,
    GaitSelectorSpec,
    GaitThresholds,
    LocomotionSpec,
    StanceSpec,
    TerrainSpec,
    Trajectory,
)
from whexar.config.parts import (
    BodySpec,
    DHRow,
    DHSpec,
    JointSpec,
    JointsSpec,
    LegSpec,
    PositionGains,
    RobotSpec,
    ServoModelSpec,
)
from whexar.config.recording import RecordingSpec
from whexar.config.reflexes import ReflexEntry

__all__ = [
    "DH_SEGMENT_TOLERANCE_MM",
    "AccelerometerSpec",
    "AdcCounts",
    "BoardBaudrate",
    "BodySpec",
    "BusSpec",
    "ConfigFile",
    "ContactSource",
    "ContactSpec",
    "DHRow",
    "DHSpec",
    "FSRSpec",
    "GaitSelectorSpec",
    "GaitThresholds",
    "GamepadSpec",
    "GravityTolerance",
    "IRSpec",
    "ImuSpec",
    "JointSpec",
    "JointsSpec",
    "LegSpec",
    "LocomotionSpec",
    "PositionGains",
    "RecordingSpec",
    "ReflexEntry",
    "RobotConfig",
    "RobotSpec",
    "SensorBoardSpec",
    "ServoModelName",
    "ServoModelSpec",
    "StanceSpec",
    "StickSpec",
    "TerrainSpec",
    "Trajectory",
    "board_baudrate",
    "config_schema",
    "default_geometry",
    "load_config",
    "merge_defaults",
    "parse_config",
]
