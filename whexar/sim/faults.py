"""Faults in a simulated run: the sensors' (what a device's link does wrong) and the
world's (what happens to the robot itself).

The bus has its fault plans (:mod:`whexar.bus.emulator.faults`). A scenario adds two
lists of its own, each fault at a time, applied by :func:`whexar.sim.run.simulate`.

Sensor faults
-------------
``[[sensor_faults]]`` (:class:`SensorFault`):

* ``unplug`` — the board's USB cable or the IMU's I²C link goes away for
  ``duration_s`` (0: for good), then comes back;
* ``corrupt`` / ``drop`` — the board's next ``frames`` frames arrive with a
  flipped bit, or not at all;
* ``freeze`` — the IMU's readings stop changing for ``duration_s`` (a hung chip);
* ``dead_fsr`` — leg ``leg``'s force sensor reads 0 from now on (a broken wire);
* ``dead_ir`` — rangefinder ``sensor`` (0 right, 1 left) reads 0 counts: no reading.

Each becomes what the readers see on the robot: a link down and up again, a
rejected frame, a gap, a stale link, a contact that never comes.

Physical faults
---------------
``[[world_faults]]``: what the world does to the robot, each from ``at_s`` (s of
simulated time) for ``duration_s`` (0: for good, but a push must last). Legs are
0…5 (RF, LF, RM, LM, RR, LR), joints named as in :data:`whexar.robot.JOINT_NAMES`. ::

    [[world_faults]]             # a shove from the side: 60 N toward +y for 0.3 s
    kind = "push"
    at_s = 4.0
    force_n = 60.0
    heading_deg = 90.0           # the world's frame: 0 along +x, 90 along +y
    elevation_deg = 0.0          # optional: + upward, − downward
    duration_s = 0.3

    [[world_faults]]             # an icy patch on the course, for good
    kind = "slippery"
    at_s = 0.0
    friction = 0.1               # the tyre's sliding µ on it (the floor: 1.3)
    x_m = [1.0, 1.5]             # the rectangle in the world; one of x_m, y_m alone
    y_m = [-0.5, 0.5]            # is a strip across the other

    [[world_faults]]             # oil under the left middle wheel for 2 s
    kind = "slippery"
    at_s = 5.0
    friction = 0.2
    leg = 3
    duration_s = 2.0

    [[world_faults]]             # the RF femur's servo loses power for 1.5 s
    kind = "limp"
    at_s = 6.0
    ids = [3]                    # servo IDs, as in bus fault plans; or leg + joint
    duration_s = 1.5

    [[world_faults]]             # the RM tibia caught on something for 1 s
    kind = "snag"
    at_s = 7.0
    leg = 2
    joint = "tibia"
    duration_s = 1.0

* ``push`` (:class:`PushFault`) — ``force_n`` on the body's centre of mass,
  toward ``heading_deg`` and ``elevation_deg``, for ``duration_s``;
* ``slippery`` (:class:`SlipperyFault`) — the ground's sliding friction becomes
  ``friction`` under one wheel (``leg``) or under the wheels whose contact lies
  in the rectangle ``x_m`` × ``y_m``; the spread of real parts scales it as it
  scales the floor's (:meth:`whexar.sim.world.SimWorld.slip`);
* ``limp`` (:class:`LimpFault`) — the servos lose power: no torque (the joint is
  moved only by the load, against its gears' friction) and no reply on the bus;
  when power returns each boots as at power-up, torque off until the bus enables
  it again. A bus fault plan's ``silent`` servo stops answering but keeps
  holding its goal;
* ``snag`` (:class:`SnagFault`) — the joint is held where it is, whatever its servo
  does (the servo stalls against it, its current rising), and free again after.

Every table is checked before the run (:func:`check_world_faults`): the keys of
its kind only, each bad key named with its path, value and what is allowed. Each
beginning and end is a :class:`~whexar.actors.messages.WorldFault` event.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping, Sequence
from typing import Annotated, Any, Final, Literal, TypeAlias

from pydantic import Field, ValidationError

from whexar.bus.protocol import MAX_ID
from whexar.config import RobotConfig
from whexar.errors import UsageError
from whexar.robot import JOINT_NAMES, LEG_NAMES
from whexar.runtime.errors import MISSING, Problem
from whexar.runtime.schema import Finite, NonNegative, Positive, Section, problem_from_error

FaultKind = Literal["unplug", "corrupt", "drop", "freeze", "dead_fsr", "dead_ir"]
Device = Literal["board", "imu"]


class SensorFault(Section):
    """One sensor fault of a scenario (``[[sensor_faults]]``)."""

    at_s: NonNegative
    """When it happens, s of simulated time."""
    kind: FaultKind
    device: Device = "board"
    duration_s: NonNegative = 0.0
    """``unplug`` and ``freeze``: how long (0: for good)."""
    frames: int = Field(default=1, ge=1)
    """``corrupt`` and ``drop``: how many frames."""
    leg: int = Field(default=0, ge=0, le=5)
    """``dead_fsr``: the leg, 0…5 (RF, LF, RM, LM, RR, LR)."""
    sensor: int = Field(default=0, ge=0, le=1)
    """``dead_ir``: the rangefinder, 0 right, 1 left."""

    def problems(self, at: str) -> list[Problem]:
        found = []
        board_only = ("corrupt", "drop", "dead_fsr", "dead_ir")
        if self.kind in board_only and self.device != "board":
            found.append(Problem(f"{at}.device", self.device, f"'board': {self.kind} is its"))
        if self.kind == "freeze" and self.device != "imu":
            found.append(Problem(f"{at}.device", self.device, "'imu': only the IMU freezes"))
        return found


# --------------------------------------------------------------------------- physical faults

MAX_PUSH_N: Final = 1000.0
"""The largest push a scenario may declare: over ten times the robot's weight (8.8 kg,
86 N): anything more is a typo, not a test."""
MAX_FRICTION: Final = 3.0
"""The largest µ of a patch: above any rubber on a dry surface (≤ ~1.5, the floor's 1.3
included, :data:`whexar.sim.terrain.GROUND_FRICTION`); 0 is frictionless."""

Leg = Annotated[int, Field(ge=0, le=5)]
"""A leg, 0…5 in RF, LF, RM, LM, RR, LR order."""
JointName = Literal["coxa", "trochanter", "femur", "tibia", "tarsus", "direction", "wheel"]
"""A joint of a leg, by name (:data:`whexar.robot.JOINT_NAMES`)."""
ServoId = Annotated[int, Field(ge=0, le=MAX_ID)]
Span = tuple[Finite, Finite]
"""(min, max), m."""


class _Physical(Section):
    """What every physical fault has: when it begins and how long it lasts."""

    at_s: NonNegative
    """When it begins, s of simulated time."""
    duration_s: NonNegative = 0.0
    """How long it lasts, s; 0: for good."""

    @property
    def ends_at(self) -> float | None:
        """When it ends, s; ``None``: never."""
        return self.at_s + self.duration_s if self.duration_s > 0 else None

    def _lasting(self) -> str:
        return f"for {self.duration_s:g} s" if self.duration_s > 0 else "for good"


class PushFault(_Physical):
    """A force on the body (``kind = "push"``): a shove, a gust, a collision."""

    kind: Literal["push"]
    force_n: float = Field(gt=0, le=MAX_PUSH_N, allow_inf_nan=False)
    """Its size, N."""
    heading_deg: float = Field(default=0.0, ge=-180, le=180, allow_inf_nan=False)
    """Its horizontal direction in the world's frame, deg: 0 along +x, 90 along +y."""
    elevation_deg: float = Field(default=0.0, ge=-90, le=90, allow_inf_nan=False)
    """Its angle above the horizontal, deg (−90: straight down)."""
    duration_s: Positive
    """How long it pushes, s (a push ends)."""

    def force(self) -> tuple[float, float, float]:
        """The force in the world's frame, N."""
        heading, up = math.radians(self.heading_deg), math.radians(self.elevation_deg)
        across = self.force_n * math.cos(up)
        return across * math.cos(heading), across * math.sin(heading), self.force_n * math.sin(up)

    def describe(self, cfg: RobotConfig) -> tuple[str, str]:
        """(target, detail) of its :class:`~whexar.actors.messages.WorldFault` events."""
        return "body", (
            f"{self.force_n:g} N toward {self.heading_deg:g}°, {self.elevation_deg:g}° up, "
            f"{self._lasting()}"
        )


class SlipperyFault(_Physical):
    """The ground's friction changed (``kind = "slippery"``) under one wheel (``leg``) or
    under an area (``x_m``, ``y_m``, or both): ice, oil, wet tiles, or grit."""

    kind: Literal["slippery"]
    friction: float = Field(ge=0, le=MAX_FRICTION, allow_inf_nan=False)
    """The nominal tyre's sliding µ there (the floor's: 1.3)."""
    leg: Leg | None = None
    """Under this leg's wheel, wherever it goes."""
    x_m: Span | None = None
    """The area's extent along the world's x, m; absent: all of it (a strip along x)."""
    y_m: Span | None = None
    """The area's extent along the world's y, m; absent: all of it (a strip along y)."""

    def problems(self, at: str) -> list[Problem]:
        found = []
        area = self.x_m is not None or self.y_m is not None
        if self.leg is not None and area:
            key = "x_m" if self.x_m is not None else "y_m"
            found.append(
                Problem(f"{at}.{key}", getattr(self, key), "not with leg: under a wheel or an area")
            )
        elif self.leg is None and not area:
            found.append(
                Problem(
                    f"{at}.leg", MISSING, "a leg (0–5), or an area: x_m and/or y_m = [min, max]"
                )
            )
        for key in ("x_m", "y_m"):
            span = getattr(self, key)
            if span is not None and not span[0] < span[1]:
                found.append(Problem(f"{at}.{key}", list(span), "[min, max] with min < max, m"))
        return found

    @property
    def area(self) -> tuple[Span | None, Span | None] | None:
        """(x span, y span) of the area, ``None`` for a wheel's own."""
        return None if self.leg is not None else (self.x_m, self.y_m)

    def describe(self, cfg: RobotConfig) -> tuple[str, str]:
        """(target, detail) of its :class:`~whexar.actors.messages.WorldFault` events."""
        if self.leg is not None:
            target = f"{LEG_NAMES[self.leg]} wheel"
        else:
            spans = [
                f"{axis} {s[0]:g}…{s[1]:g} m"
                for axis, s in (("x", self.x_m), ("y", self.y_m))
                if s is not None
            ]
            target = "area " + ", ".join(spans)
        return target, f"µ {self.friction:g} {self._lasting()}"


class LimpFault(_Physical):
    """Servos lose power (``kind = "limp"``): a broken supply wire, a blown fuse. Named by
    ``ids`` as in bus fault plans, or by ``leg`` and ``joint``."""

    kind: Literal["limp"]
    ids: tuple[ServoId, ...] | None = Field(default=None, min_length=1)
    """The servos, by ID."""
    leg: Leg | None = None
    joint: JointName | None = None

    def problems(self, at: str) -> list[Problem]:
        if self.ids is not None and (self.leg is not None or self.joint is not None):
            key = "leg" if self.leg is not None else "joint"
            return [Problem(f"{at}.{key}", getattr(self, key), "not with ids: ids or leg + joint")]
        if self.ids is None and (self.leg is None or self.joint is None):
            key = "joint" if self.leg is not None else "leg" if self.joint is not None else "ids"
            allowed = {
                "ids": "servo IDs such as [3], or leg (0–5) and joint",
                "leg": "a leg (0–5) with joint",
                "joint": f"a joint with leg: {', '.join(JOINT_NAMES)}",
            }[key]
            return [Problem(f"{at}.{key}", MISSING, allowed)]
        return []

    def servo_ids(self, cfg: RobotConfig) -> tuple[int, ...]:
        """The servos that lose power, by ID."""
        if self.ids is not None:
            return self.ids
        if self.leg is None or self.joint is None:
            raise UsageError("a limp fault names its servos by ids, or by leg and joint")
        return (cfg.legs[self.leg].servo_ids[JOINT_NAMES.index(self.joint)],)

    def describe(self, cfg: RobotConfig) -> tuple[str, str]:
        """(target, detail) of its :class:`~whexar.actors.messages.WorldFault` events."""
        names = {
            sid: (leg, j)
            for leg, spec in enumerate(cfg.legs)
            for j, sid in enumerate(spec.servo_ids)
        }
        parts = []
        for sid in self.servo_ids(cfg):
            leg, j = names[sid]
            parts.append(f"servo {sid} ({LEG_NAMES[leg]} {JOINT_NAMES[j]})")
        return ", ".join(parts), f"no power {self._lasting()}"


class SnagFault(_Physical):
    """A joint blocked where it is (``kind = "snag"``): a leg caught on something."""

    kind: Literal["snag"]
    leg: Leg
    joint: JointName

    def describe(self, cfg: RobotConfig) -> tuple[str, str]:
        """(target, detail) of its :class:`~whexar.actors.messages.WorldFault` events."""
        return f"{LEG_NAMES[self.leg]} {self.joint}", f"blocked {self._lasting()}"


WorldFaultSpec: TypeAlias = PushFault | SlipperyFault | LimpFault | SnagFault
"""One physical fault of a scenario (``[[world_faults]]``)."""
WORLD_FAULT_KINDS: Final[Mapping[str, type[WorldFaultSpec]]] = {
    "push": PushFault,
    "slippery": SlipperyFault,
    "limp": LimpFault,
    "snag": SnagFault,
}


def check_world_faults(
    tables: Sequence[object], servo_ids: Collection[int], problems: list[Problem]
) -> tuple[WorldFaultSpec, ...]:
    """The ``[[world_faults]]`` tables as faults; adds a problem for every bad key.

    Each table is checked against its ``kind``'s keys alone (an unknown key lists the
    kind's keys), then across them (:meth:`~whexar.runtime.schema.Section.problems`);
    a limp's ``ids`` must be among ``servo_ids``, the robot's servos."""
    out: list[WorldFaultSpec] = []
    kinds = ", ".join(repr(k) for k in WORLD_FAULT_KINDS)
    for i, table in enumerate(tables):
        at = f"world_faults[{i}]"
        if not isinstance(table, Mapping):
            problems.append(Problem(at, table, 'a table such as { kind = "push", at_s = 3.0, … }'))
            continue
        kind: Any = table.get("kind", MISSING)
        model = WORLD_FAULT_KINDS.get(kind) if isinstance(kind, str) else None
        if model is None:
            problems.append(Problem(f"{at}.kind", kind, f"one of {kinds}"))
            continue
        try:
            fault = model.model_validate(table)
        except ValidationError as exc:
            problems.extend(
                problem_from_error(e, model, prefix=("world_faults", i))
                for e in exc.errors(include_url=False)
            )
            continue
        found = fault.problems(at)
        if isinstance(fault, LimpFault) and fault.ids is not None:
            found.extend(
                Problem(f"{at}.ids[{k}]", sid, "a servo of the robot (its legs' servo_ids)")
                for k, sid in enumerate(fault.ids)
                if sid not in servo_ids
            )
        problems.extend(found)
        if not found:
            out.append(fault)
    return tuple(out)


__all__ = [
    "MAX_FRICTION",
    "MAX_PUSH_N",
    "WORLD_FAULT_KINDS",
    "Device",
    "FaultKind",
    "JointName",
    "LimpFault",
    "PushFault",
    "SensorFault",
    "SlipperyFault",
    "SnagFault",
    "WorldFaultSpec",
    "check_world_faults",
]
