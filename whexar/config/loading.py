"""The whole robot (:class:`RobotConfig`), its checks across sections, and loading: the
merge with the defaults, parsing, the editor schema."""

from __future__ import annotations

import copy
import functools
import math
import typing
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Annotated, Any, Final, Literal

import numpy as np
from pydantic import (
    AfterValidator,
    Field,
    TypeAdapter,
    ValidationError,
)

from whexar.config.common import DH_SEGMENT_TOLERANCE_MM, ServoModelName
from whexar.config.gamepad import GamepadSpec, stance_problems
from whexar.config.links import BusSpec, FSRSpec, ImuSpec, IRSpec, SensorBoardSpec
from whexar.config.motion import (
    ContactSpec,
    GaitSelectorSpec,
    LocomotionSpec,
    StanceSpec,
    TerrainSpec,
    default_stances,
)
from whexar.config.parts import (
    BodySpec,
    DHSpec,
    JointsSpec,
    LegSpec,
    RobotSpec,
    ServoModelSpec,
    check_legs,
    default_legs,
    default_servo_models,
)
from whexar.config.recording import RecordingSpec
from whexar.config.reflexes import ReflexEntry
from whexar.errors import ConfigError, KinematicsError, Problem
from whexar.kinematics.body import Stance, stance_feet
from whexar.kinematics.geometry import LegGeometry
from whexar.kinematics.leg import ik
from whexar.robot import JOINT_NAMES, POSITIONING_JOINTS
from whexar.runtime.schema import (
    CheckedSection,
    Section,
    format_path,
    loads,
    problem_from_error,
    read_toml,
)

# --------------------------------------------------------------------------- the whole robot


class RobotConfig(CheckedSection):
    """Everything physical or tunable about WHexaR. ``RobotConfig()`` is the thesis robot."""

    schema_version: Literal[1] = 1
    robot: RobotSpec = RobotSpec()
    body: BodySpec = BodySpec()
    servo_models: dict[ServoModelName, ServoModelSpec] = Field(default_factory=default_servo_models)
    joints: JointsSpec = JointsSpec()
    dh: DHSpec = DHSpec()
    legs: tuple[LegSpec, ...] = Field(default_factory=default_legs)
    bus: BusSpec = BusSpec()
    sensor_board: SensorBoardSpec = SensorBoardSpec()
    ir: IRSpec = IRSpec()
    fsr: FSRSpec = FSRSpec()
    imu: ImuSpec = ImuSpec()
    gait_selector: GaitSelectorSpec = GaitSelectorSpec()
    terrain: TerrainSpec = TerrainSpec()
    stances: dict[str, StanceSpec] = Field(default_factory=default_stances)
    locomotion: LocomotionSpec = LocomotionSpec()
    contact: ContactSpec = ContactSpec()
    gamepad: GamepadSpec = GamepadSpec()
    recording: RecordingSpec = RecordingSpec()
    reflexes: tuple[ReflexEntry, ...] = ()
    """The reflexes the robot runs, beside those its graph names (``[[reflexes]]``)."""

    def problems(self, at: str = "") -> list[Problem]:
        """Every relational problem of the whole configuration."""
        found: list[Problem] = []
        for name in type(self).model_fields:
            found.extend(_section_problems(name, getattr(self, name)))
        for check in _CROSS_CHECKS:
            found.extend(check(self))
        return found

    def stance(self, name: str) -> Stance:
        """The stance preset called ``name``, in SI; a ConfigError names the known ones."""
        try:
            return self.stances[name].to_stance()
        except KeyError:
            allowed = ", ".join(sorted(self.stances))
            raise ConfigError("stances", [Problem("stances", name, f"one of {allowed}")]) from None

    def leg_geometry(self) -> LegGeometry:
        """The legs' geometry in SI, as the kinematics takes it (Tables 5.2, 5.3)."""
        rows = self.dh.rows()
        limits = []
        for name in POSITIONING_JOINTS:
            rad = self.joints.by_name(name).limits_rad
            limits.append(rad if rad is not None else (-math.inf, math.inf))
        return LegGeometry(
            dh_d=np.array([r.d_mm / 1000 for r in rows]),
            dh_a=np.array([r.a_mm / 1000 for r in rows]),
            dh_alpha=np.array([math.radians(r.alpha_deg) for r in rows]),
            theta_offset=np.array([math.radians(r.theta_offset_deg) for r in rows]),
            theta_sign=np.array([float(r.theta_sign) for r in rows]),
            limits=np.array(limits),
            direction_length=self.joints.direction.length_mm / 1000,
            wheel_radius=self.joints.wheel.length_mm / 1000,
            mounts=np.array([[c / 1000 for c in leg.mount_mm] for leg in self.legs]),
        )

    def servos(self) -> dict[int, ServoModelName]:
        """Every servo's ID and model, legs in order and coxa to wheel within each."""
        return {
            sid: self.joints.by_name(JOINT_NAMES[j]).model
            for leg in self.legs
            for j, sid in enumerate(leg.servo_ids)
        }


def _section_problems(name: str, value: object) -> list[Problem]:
    """Relational problems inside one top-level section."""
    if name == "legs":
        return check_legs(typing.cast(Sequence[LegSpec], value), name)
    if isinstance(value, Section):
        return value.problems(name)
    if isinstance(value, Mapping):
        return [
            p
            for key, item in value.items()
            if isinstance(item, Section)
            for p in item.problems(format_path((name, key)))
        ]
    return []


def _check_dh_lengths(cfg: RobotConfig) -> list[Problem]:
    # Each DH length against the measured segment it stands for (Tables 5.2–5.3).
    pairs = (
        ("trochanter", "d_mm"),
        ("femur", "a_mm"),
        ("tibia", "a_mm"),
        ("tarsus", "a_mm"),
    )
    found: list[Problem] = []
    for joint, key in pairs:
        value = getattr(getattr(cfg.dh, joint), key)
        segment = cfg.joints.by_name(joint).length_mm
        if abs(value - segment) > DH_SEGMENT_TOLERANCE_MM:
            found.append(
                Problem(
                    f"dh.{joint}.{key}",
                    value,
                    f"within {DH_SEGMENT_TOLERANCE_MM:g} mm of joints.{joint}.length_mm "
                    f"({segment:g} mm, the measured segment)",
                )
            )
    return found


def _check_servo_models(cfg: RobotConfig) -> list[Problem]:
    return [
        Problem(f"joints.{name}.model", cfg.joints.by_name(name).model, msg)
        for name in JOINT_NAMES
        if cfg.joints.by_name(name).model not in cfg.servo_models
        for msg in [f"a model described under servo_models ({', '.join(cfg.servo_models)})"]
    ]


def _check_stances(cfg: RobotConfig) -> list[Problem]:
    # Each preset must be reachable by every leg within the joint limits, or
    # the robot could be commanded into a posture it cannot take.
    if _check_servo_models(cfg) or cfg.joints.problems("joints") or cfg.dh.problems("dh"):
        return []
    geometry = cfg.leg_geometry()
    found: list[Problem] = []
    for name, stance in cfg.stances.items():
        try:
            ik(stance_feet(stance.to_stance()), geometry, target="contact")
        except KinematicsError as exc:
            found.append(
                Problem(
                    format_path(("stances", name)),
                    {"reach_mm": stance.reach_mm, "height_mm": stance.height_mm},
                    f"a stance every leg can reach within its joint limits ({exc})",
                )
            )
    return found


def _check_locomotion_stances(cfg: RobotConfig) -> list[Problem]:
    found: list[Problem] = []
    allowed = ", ".join(sorted(cfg.stances))
    for key in ("stance", "ride_stance"):
        name = getattr(cfg.locomotion, key)
        if name not in cfg.stances:
            found.append(Problem(f"locomotion.{key}", name, f"a stance preset: {allowed}"))
    sit = cfg.locomotion.sit_height_mm
    if any(sit >= s.height_mm for s in cfg.stances.values()):
        low = min(s.height_mm for s in cfg.stances.values())
        found.append(
            Problem("locomotion.sit_height_mm", sit, f"below every stance height ({low:g})")
        )
    return found


def _check_gamepad_stances(cfg: RobotConfig) -> list[Problem]:
    return stance_problems(cfg.gamepad, cfg.stances)


_CROSS_CHECKS: Final[tuple[Callable[[RobotConfig], list[Problem]], ...]] = (
    _check_locomotion_stances,
    _check_gamepad_stances,
    _check_dh_lengths,
    _check_servo_models,
    _check_stances,
)


# --------------------------------------------------------------------------- loading


@functools.cache
def _defaults() -> dict[str, Any]:
    """``RobotConfig()`` as a document: what a file's keys are merged into."""
    return RobotConfig().model_dump(mode="python")


def _merge(default: object, given: object) -> object:
    """``given`` over ``default``: tables merge key by key, recursively; anything else replaces."""
    if isinstance(default, Mapping) and isinstance(given, Mapping):
        merged = {key: copy.deepcopy(value) for key, value in default.items()}
        for key, value in given.items():
            merged[key] = _merge(default[key], value) if key in default else value
        return merged
    return given


def merge_defaults(data: Mapping[str, Any]) -> dict[str, Any]:
    """A configuration document completed with the defaults of ``RobotConfig()``.

    The merge rule: a table merges with the default table key by key,
    recursively, so a file names only the keys it changes
    (``[joints.femur]`` with ``min_deg = -100`` keeps the femur's model, limit
    and length). Mapping-valued sections are tables too: ``[stances.crouch]``
    adds a stance next to the presets, ``[stances.high]`` with one key changes
    that key of the preset, and likewise ``[servo_models."MX-64"]``. An array —
    ``legs``, ``mount_mm``, ``zero_g_counts`` — replaces the default whole, as
    does a value whose type differs from the default's (``bus.plan``: a preset
    name or a table). Nothing can be deleted: a key the defaults have stays.
    An unknown key stays unknown and is reported as such.
    """
    merged = _merge(_defaults(), data)
    assert isinstance(merged, dict)
    return merged


def parse_config(data: Mapping[str, Any], source: str = "<config>") -> RobotConfig:
    """Validate a configuration document (as parsed from TOML) into a :class:`RobotConfig`.

    The document needs only the keys it changes: it is merged with the
    defaults first (:func:`merge_defaults`). Raises
    :class:`~whexar.errors.ConfigError` listing every problem found.
    """
    data = merge_defaults(data)
    try:
        cfg = RobotConfig.model_validate(data, context={"defer_relations": True})
    except ValidationError as exc:
        errors = exc.errors(include_url=False)
    else:
        found = cfg.problems()
        if found:
            raise ConfigError(source, found)
        return cfg
    problems = [problem_from_error(error, RobotConfig) for error in errors]
    # Sections that validated on their own still get their relational checks,
    # so a bad key in one section does not hide a duplicate ID in another.
    failed = {e["loc"][0] for e in errors if e["loc"]}
    for name, field in RobotConfig.model_fields.items():
        if name in failed or name not in data or field.annotation is None:
            continue
        try:
            section = TypeAdapter(field.annotation).validate_python(data[name])
        except ValidationError:
            continue
        problems.extend(_section_problems(name, section))
    raise ConfigError(source, problems)


def load_config(path: str | Path) -> RobotConfig:
    """Read and validate a TOML robot configuration.

    Raises :class:`~whexar.errors.ConfigError` listing every problem: the key
    path, the value found and what is allowed.
    """
    return parse_config(read_toml(path), str(path))


def config_schema() -> dict[str, Any]:
    """JSON Schema of the configuration file, for editors.

    It follows the merge rule (:func:`merge_defaults`): inside a table that
    has a default no key is required, and so on down; the presets of a
    mapping-valued section (``stances``, ``servo_models``) are listed with
    nothing required, while a new entry (a new stance) and an array item (a
    leg) must be complete.
    """
    schema = RobotConfig.model_json_schema()
    defs: dict[str, Any] = schema.get("$defs", {})
    partial = _partial(schema, _defaults(), defs)
    partial["title"] = "WHexaR robot configuration"
    # Keep only the definitions still referred to (a section's full form is
    # not, once its relaxed form took its place).
    used: set[str] = set()
    todo: list[object] = [{k: v for k, v in partial.items() if k != "$defs"}]
    while todo:
        item = todo.pop()
        if isinstance(item, dict):
            ref = item.get("$ref")
            if isinstance(ref, str) and (name := ref.rsplit("/", 1)[-1]) not in used:
                used.add(name)
                todo.append(defs[name])
            todo.extend(item.values())
        elif isinstance(item, list):
            todo.extend(item)
    partial["$defs"] = {name: value for name, value in defs.items() if name in used}
    return partial


def _partial(node: dict[str, Any], default: object, defs: dict[str, Any]) -> dict[str, Any]:
    """``node``'s schema for a value merged into ``default``: see :func:`config_schema`."""
    if not isinstance(default, Mapping):
        return node
    ref = node.get("$ref")
    target = defs[ref.rsplit("/", 1)[-1]] if isinstance(ref, str) else node
    if "properties" in target:
        relaxed = {key: value for key, value in target.items() if key != "required"}
        relaxed["properties"] = {
            key: _partial(value, default.get(key), defs)
            for key, value in target["properties"].items()
        }
    elif isinstance(target.get("additionalProperties"), dict):
        item = target["additionalProperties"]
        relaxed = dict(target)
        relaxed["properties"] = {key: _partial(item, value, defs) for key, value in default.items()}
    else:
        return node
    if not isinstance(ref, str):
        return relaxed
    name = f"{ref.rsplit('/', 1)[-1]}Partial"
    defs[name] = relaxed
    return {**{k: v for k, v in node.items() if k != "$ref"}, "$ref": f"#/$defs/{name}"}


@functools.cache
def default_geometry() -> LegGeometry:
    """The leg geometry of the thesis robot, ``RobotConfig().leg_geometry()``, made once."""
    return RobotConfig().leg_geometry()


ConfigFile = Annotated[str, AfterValidator(loads(load_config, "a robot configuration"))]
"""An actor parameter naming a robot configuration file, checked with the wiring."""
