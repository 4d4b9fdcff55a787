"""Terrains for the simulated WHexaR: the ground and what lies on it, as MJCF.

Theory of operation
-------------------
A :class:`Terrain` is a value: a :class:`Floor` (a plane, perhaps tilted or cut by
ditches) and a tuple of parts (static boxes and balls, or free light boxes a leg can
push). :func:`whexar.sim.model.build_mjcf` asks it for its assets and its worldbody
elements; nothing here knows the robot. Terrains add up: ``flat() + ramp(15) +
block(...)`` is one course. Obstacles alone (steps, ramp, block, rocks) name no floor
and lie on whatever floor they are added to (the level one by default); the plain
level floor gives way to any other (``flat() + slope(15)`` is the slope); other floors
merge only when they agree (same tilt; the ditches of both are kept). Each part stays
at the world position it was given.

World frame: x along the course (the robot starts at the origin facing +x), y left,
z up, metres. Features of the built-in terrains start at x ≥ 1 m so the robot starts
on the flat; :func:`course` starts its features at x = 2 m.

* The slope is a real tilted plane rising along +x, not a rotated gravity, so an IMU
  reads real accelerations (with a rotated gravity a ``framequat`` sensor stays level).
* Steps are boxes: a step in a heightfield becomes a one-cell ramp.
* A ditch cuts the floor: the floor plane sinks to the ditch's bottom and slabs
  (boxes) with their tops at z = 0 carry the ground on either side.

Contacts: terrain geoms collide with the robot's geoms but not with each other
(:data:`TERRAIN_CONTYPE`, :data:`TERRAIN_CONAFFINITY`; the robot's bits are in
:mod:`whexar.sim.model`); a free block collides with both. The ground's friction is
:data:`GROUND_FRICTION`.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Final

import numpy as np

from whexar.errors import UsageError
from whexar.runtime.checks import non_negative, positive, real

# --------------------------------------------------------------------------- contact constants

TERRAIN_CONTYPE: Final = 1
TERRAIN_CONAFFINITY: Final = 2
"""Static terrain: touches whatever has bit 1 in its conaffinity or bit 2 in its contype
(the robot, free blocks), never other static terrain (MuJoCo: a pair collides when
``contype₁ & conaffinity₂ or contype₂ & conaffinity₁``)."""
FREE_CONTYPE: Final = 1
FREE_CONAFFINITY: Final = 3
"""A free block touches static terrain (1 & 2 via the terrain's conaffinity) and the robot."""

GROUND_FRICTION: Final = (1.3, 0.005, 0.0001)
"""Sliding, torsional and rolling friction of the ground.

The thesis's robot stood on its board tilted to 50° (6.8.1, Table 6.6), so its soft
rubber tyres (5.2, Fig. 5.2) held there: µ ≥ tan 50° = 1.19. Handbook values for rubber
are lower (on concrete µs 1.0, µk 0.8: Serway and Beichner, *Physics for Scientists and
Engineers*, 5th ed., Table 5.2) and none was found for soft tyres on plywood: the
thesis's own result is the measurement. MuJoCo has one coefficient for sticking and
sliding; 1.3 (holding to 52°) leaves a margin over 1.19 for a contact that is not a
static one. The wheels carry the same value with a higher priority
(:mod:`whexar.sim.model`), so a wheel's contact uses the rubber's numbers whatever it
touches. The torsional and
rolling terms only act on contacts with ``condim`` 4 or 6.
"""

ROLLING_TRACTION: Final = 0.9
"""A driven tyre's grip along the ground while it rolls, against :data:`GROUND_FRICTION`'s
static grip. "When driving on wheels on 40° slopes, there was already considerable
slipping" (thesis 6.7.6), and yet the robot climbed there at 0.15 m/s (Table 6.7): its
rolling grip lay just above tan 40° = 0.84, where the same tyres standing held 50°
(µ ≥ 1.19). 0.9 is just above it, the middle of rubber on concrete (µk 0.8, µs 1.0:
Serway and Beichner, Table 5.2). A rolling rubber tyre transmits its traction through a
contact patch that partly slips, and grips less than a still one. The world lowers a
wheel's friction to this while it turns (:class:`whexar.sim.world.SimWorld`)."""
ROLLING_RAD_S: Final = 0.2
"""A wheel turning faster than this (1 cm/s at the rim) rolls, and grips as it rolls."""
BLOCK_FRICTION: Final = (0.6, 0.005, 0.0001)
"""A light block (wood or plastic) sliding on the floor: wood on concrete µ ≈ 0.6
(Engineering ToolBox, "Friction and friction coefficients"); lets a leg push it."""

LARGE: Final = 50.0
"""Half extent (m) of slabs that stand in for an infinite floor around a ditch."""
MAX_SLOPE_DEG: Final = 50.0
"""Steepest slope offered: beyond tan⁻¹ µ = 42° even a braked robot slides (µ = 0.9)."""

_GROUND_RGBA = "0.45 0.45 0.42 1"
_OBSTACLE_RGBA = "0.55 0.45 0.35 1"
_FREE_RGBA = "0.85 0.6 0.2 1"
_ROCK_RGBA = "0.5 0.5 0.5 1"


def _f(value: float) -> str:
    return f"{value:.15g}"


def _v(values: tuple[float, ...] | list[float] | np.ndarray) -> str:
    return " ".join(_f(float(v)) for v in values)


def _quat_y(angle: float) -> tuple[float, float, float, float]:
    """Quaternion (w, x, y, z) of a rotation by ``angle`` rad about +y."""
    return (math.cos(angle / 2), 0.0, math.sin(angle / 2), 0.0)


def _quat_zy(yaw: float, pitch: float) -> tuple[float, float, float, float]:
    """Quaternion of R_z(yaw)·R_y(pitch)."""
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    return (cy * cp, -sy * sp, cy * sp, sy * cp)


# --------------------------------------------------------------------------- parts


@dataclass(frozen=True)
class Floor:
    """The ground plane: tilted by ``slope_deg`` about y (rising along +x), or level and
    cut by ditches ``(x_start, width, depth)`` running across the whole y range."""

    slope_deg: float = 0.0
    ditches: tuple[tuple[float, float, float], ...] = ()

    def merge(self, other: Floor) -> Floor:
        """Both floors as one; a UsageError when they cannot be the same ground.

        The plain level floor is the default ground and gives way to any other (a slope
        added to ``flat()`` is the slope); ditches add up; two different tilts, or a
        ditch in a tilted floor, cannot be one plane.
        """
        if self == Floor():
            return other
        if other == Floor():
            return self
        if (self.ditches and other.slope_deg) or (other.ditches and self.slope_deg):
            raise UsageError("a ditch can only cut a level floor, not a slope")
        if self.slope_deg != other.slope_deg:
            raise UsageError(
                f"cannot combine a {self.slope_deg:g}° floor with a {other.slope_deg:g}° floor: "
                "a terrain has one ground plane; build a finite incline with ramp() instead"
            )
        ditches = tuple(sorted(set(self.ditches) | set(other.ditches)))
        return Floor(self.slope_deg, ditches)

    @property
    def normal(self) -> tuple[float, float, float]:
        """Unit normal of the floor plane (world frame)."""
        theta = math.radians(self.slope_deg)
        return (-math.sin(theta), 0.0, math.cos(theta))

    def xml(self) -> list[str]:
        """Worldbody elements of the floor."""
        common = (
            f'contype="{TERRAIN_CONTYPE}" conaffinity="{TERRAIN_CONAFFINITY}" '
            f'friction="{_v(GROUND_FRICTION)}" material="ground"'
        )
        if not self.ditches:
            # Rising along +x: rotate the plane about +y by −θ, normal (−sin θ, 0, cos θ).
            quat = _quat_y(-math.radians(self.slope_deg))
            return [f'<geom name="floor" type="plane" size="0 0 0.05" quat="{_v(quat)}" {common}/>']
        bottom = max(depth for _, _, depth in self.ditches)
        out = [
            f'<geom name="floor" type="plane" size="0 0 0.05" pos="0 0 {_f(-bottom)}" {common}/>'
        ]
        # Ground slabs between the ditches, their tops at z = 0, down to the floor plane.
        cuts = sorted((x0, x0 + width) for x0, width, _ in self.ditches)
        edges = [-LARGE, *[c for cut in cuts for c in cut], LARGE]
        for k in range(0, len(edges), 2):
            x0, x1 = edges[k], edges[k + 1]
            if x1 <= x0:
                continue
            out.append(
                f'<geom name="ground_{k // 2}" type="box" '
                f'size="{_v(((x1 - x0) / 2, LARGE, bottom / 2))}" '
                f'pos="{_v(((x0 + x1) / 2, 0.0, -bottom / 2))}" {common}/>'
            )
        # A shallower ditch gets a fill from the common bottom up to its own depth.
        for k, (x0, width, depth) in enumerate(sorted(self.ditches)):
            if depth < bottom:
                fill = bottom - depth
                out.append(
                    f'<geom name="ditch_fill_{k}" type="box" '
                    f'size="{_v((width / 2, LARGE, fill / 2))}" '
                    f'pos="{_v((x0 + width / 2, 0.0, -bottom + fill / 2))}" {common}/>'
                )
        return out

    def start_pose(
        self, height: float
    ) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
        """Base position and orientation (w, x, y, z) ``height`` above the floor at the origin,
        the body parallel to the floor (nose up on an upward slope)."""
        nx, ny, nz = self.normal
        for x0, width, _ in self.ditches:
            if x0 <= 0.0 <= x0 + width:
                raise UsageError(
                    f"a ditch spans x = {x0:g}…{x0 + width:g} m under the start at the origin"
                )
        return (height * nx, height * ny, height * nz), _quat_y(-math.radians(self.slope_deg))


@dataclass(frozen=True)
class Box:
    """A box obstacle: full ``size`` (x, y, z) in m, centre ``pos``, turned by ``yaw`` about z
    and then pitched by ``pitch`` about y (rad); static, or a free body of ``mass`` kg."""

    size: tuple[float, float, float]
    pos: tuple[float, float, float]
    yaw: float = 0.0
    pitch: float = 0.0
    mass: float | None = None
    kind: str = "block"

    def xml(self, name: str) -> str:
        """The MJCF element: a static geom, or a body with a free joint."""
        half = _v(tuple(s / 2 for s in self.size))
        quat = _v(_quat_zy(self.yaw, self.pitch))
        if self.mass is None:
            return (
                f'<geom name="{name}" type="box" size="{half}" pos="{_v(self.pos)}" '
                f'quat="{quat}" contype="{TERRAIN_CONTYPE}" conaffinity="{TERRAIN_CONAFFINITY}" '
                f'friction="{_v(GROUND_FRICTION)}" rgba="{_OBSTACLE_RGBA}"/>'
            )
        return (
            f'<body name="{name}" pos="{_v(self.pos)}" quat="{quat}">'
            f'<freejoint name="{name}"/>'
            f'<geom name="{name}" type="box" size="{half}" mass="{_f(self.mass)}" '
            f'contype="{FREE_CONTYPE}" conaffinity="{FREE_CONAFFINITY}" '
            f'friction="{_v(BLOCK_FRICTION)}" rgba="{_FREE_RGBA}"/></body>'
        )


@dataclass(frozen=True)
class Ball:
    """A static sphere (a rounded rock): ``radius`` m, centre ``pos``."""

    radius: float
    pos: tuple[float, float, float]
    kind: str = "rock"

    def xml(self, name: str) -> str:
        """The MJCF element."""
        return (
            f'<geom name="{name}" type="sphere" size="{_f(self.radius)}" pos="{_v(self.pos)}" '
            f'contype="{TERRAIN_CONTYPE}" conaffinity="{TERRAIN_CONAFFINITY}" '
            f'friction="{_v(GROUND_FRICTION)}" rgba="{_ROCK_RGBA}"/>'
        )


Part = Box | Ball


# --------------------------------------------------------------------------- terrain


@dataclass(frozen=True)
class Terrain:
    """A ground and what lies on it; ``+`` combines terrains (see the module docstring)."""

    name: str
    floor: Floor | None = None
    """The ground; None for obstacles alone, which then lie on the level floor."""
    parts: tuple[Part, ...] = ()

    def __add__(self, other: Terrain) -> Terrain:
        if not isinstance(other, Terrain):
            return NotImplemented
        if self.floor is None or other.floor is None:
            floor = self.floor if other.floor is None else other.floor
        else:
            floor = self.floor.merge(other.floor)
        return Terrain(f"{self.name}+{other.name}", floor, self.parts + other.parts)

    @property
    def ground(self) -> Floor:
        """The floor this terrain is built on (level when it names none)."""
        return Floor() if self.floor is None else self.floor

    def named(self, name: str) -> Terrain:
        """The same terrain under another name."""
        return Terrain(name, self.floor, self.parts)

    def asset_xml(self) -> str:
        """Elements for ``<asset>``: the ground's checker texture."""
        return (
            '<texture name="ground" type="2d" builtin="checker" rgb1="0.42 0.44 0.40" '
            'rgb2="0.36 0.38 0.35" width="512" height="512"/>'
            '<material name="ground" texture="ground" texrepeat="2 2" texuniform="true" '
            'reflectance="0"/>'
        )

    def worldbody_xml(self) -> str:
        """Elements for ``<worldbody>``: the floor, then every part, named ``<kind>_<n>``."""
        lines = self.ground.xml()
        counts: dict[str, int] = {}
        for part in self.parts:
            n = counts.get(part.kind, 0)
            counts[part.kind] = n + 1
            lines.append(part.xml(f"{part.kind}_{n}"))
        return "\n".join(lines)

    def start_pose(
        self, height: float
    ) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
        """Where the base starts: ``height`` above the floor at the origin, parallel to it."""
        return self.ground.start_pose(height)


# --------------------------------------------------------------------------- factories


def flat() -> Terrain:
    """A level, endless floor at z = 0."""
    return Terrain("flat", Floor())


def slope(angle_deg: float) -> Terrain:
    """An endless plane through the origin tilted by ``angle_deg`` (0–50°) about y,
    rising along +x: the robot at the start faces uphill."""
    angle = real("angle_deg", angle_deg)
    if not 0.0 <= angle <= MAX_SLOPE_DEG:
        raise UsageError(f"slope angle_deg = {angle_deg!r}; allowed: 0–{MAX_SLOPE_DEG:g}°")
    return Terrain(f"slope{angle:g}", Floor(slope_deg=angle))


def steps(
    height: float,
    depth: float,
    count: int,
    *,
    at: float = 1.0,
    width: float = 2.0,
    landing: float = 1.0,
    down: bool = True,
) -> Terrain:
    """A staircase of ``count`` steps of ``height`` and tread ``depth`` (m) from x = ``at``;
    the top step is ``landing`` m long and, with ``down``, the same stairs lead down again;
    ``width`` across."""
    h = positive("height", height, "m")
    d = positive("depth", depth, "m")
    w = positive("width", width, "m")
    top = positive("landing", landing, "m")
    x0 = real("at", at)
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise UsageError(f"steps count = {count!r}; allowed: an integer ≥ 1")
    # Level k is one slab from its riser on the way up to its riser on the way down:
    # stacked boxes, no gaps, no two top faces at the same place.
    top_end = x0 + (count - 1) * d + top
    parts: list[Part] = []
    for k in range(count):
        start = x0 + k * d
        stop = top_end + (count - 1 - k) * d if down else top_end
        parts.append(
            Box(
                size=(stop - start, w, h),
                pos=((start + stop) / 2, 0.0, k * h + h / 2),
                kind="step",
            )
        )
    return Terrain(f"steps{count}x{1000 * h:g}mm", None, tuple(parts))


def ramp(
    angle_deg: float,
    rise: float,
    *,
    at: float = 2.0,
    plateau: float = 1.0,
    width: float = 2.0,
    thickness: float = 0.05,
) -> Terrain:
    """A finite incline on the flat: up at ``angle_deg`` from x = ``at`` to ``rise`` m, a
    ``plateau`` on top, and down again at the same angle; built from boxes."""
    angle = real("angle_deg", angle_deg)
    if not 0.0 < angle <= MAX_SLOPE_DEG:
        raise UsageError(f"ramp angle_deg = {angle_deg!r}; allowed: above 0, up to 50°")
    h = positive("rise", rise, "m")
    x0 = real("at", at)
    flat_top = non_negative("plateau", plateau, "m")
    w = positive("width", width, "m")
    t = positive("thickness", thickness, "m")
    theta = math.radians(angle)
    run = h / math.tan(theta)
    length = h / math.sin(theta)
    parts: list[Part] = []
    for direction, foot in ((1.0, x0), (-1.0, x0 + 2 * run + flat_top)):
        # The top face runs from the foot (z = 0) to the plateau's edge (z = rise); the box
        # hangs below it by its thickness, partly under the floor, which it does not touch.
        pitch = -direction * theta
        mid_top = np.array([foot + direction * run / 2, 0.0, h / 2])
        normal = np.array([-direction * math.sin(theta), 0.0, math.cos(theta)])
        centre = mid_top - normal * t / 2
        parts.append(
            Box(
                size=(length, w, t),
                pos=(float(centre[0]), float(centre[1]), float(centre[2])),
                pitch=pitch,
                kind="ramp",
            )
        )
    if flat_top > 0:
        parts.append(
            Box(size=(flat_top, w, h), pos=(x0 + run + flat_top / 2, 0.0, h / 2), kind="ramp")
        )
    return Terrain(f"ramp{angle:g}", None, tuple(parts))


def block(
    size: tuple[float, float, float],
    position: tuple[float, float],
    mass: float | None = None,
    *,
    yaw: float = 0.0,
    bottom: float = 0.0,
) -> Terrain:
    """A box of full ``size`` (x, y, z) m resting at ``position`` (x, y) with its bottom at
    z = ``bottom``: static, or, given ``mass`` (kg), free and light enough for a leg to push
    (thesis 6.7.2)."""
    sx, sy, sz = (positive(f"size[{i}]", s, "m") for i, s in enumerate(size))
    x, y = (real(f"position[{i}]", p) for i, p in enumerate(position))
    weight = None if mass is None else positive("mass", mass, "kg")
    z0 = real("bottom", bottom)
    part = Box(size=(sx, sy, sz), pos=(x, y, z0 + sz / 2), yaw=real("yaw", yaw), mass=weight)
    return Terrain("block" if weight is None else "free_block", None, (part,))


def ditch(width: float, depth: float, at: float) -> Terrain:
    """A ditch ``width`` m wide and ``depth`` m deep across the floor, from x = ``at``."""
    w = positive("width", width, "m")
    d = positive("depth", depth, "m")
    return Terrain(f"ditch{1000 * w:g}mm", Floor(ditches=((real("at", at), w, d),)))


def rocks(
    count: int,
    seed: int,
    size: float = 0.04,
    *,
    area: tuple[tuple[float, float], tuple[float, float]] = ((1.0, 3.0), (-0.6, 0.6)),
) -> Terrain:
    """``count`` static rocks, boxes and half-buried balls up to ``size`` m, scattered over
    ``area`` ((x_min, x_max), (y_min, y_max)); the same ``seed`` gives the same rocks."""
    if isinstance(count, bool) or not isinstance(count, int) or count < 0:
        raise UsageError(f"rocks count = {count!r}; allowed: an integer ≥ 0")
    s = positive("size", size, "m")
    (x_lo, x_hi), (y_lo, y_hi) = area
    if not (x_lo < x_hi and y_lo < y_hi):
        raise UsageError(f"rocks area = {area!r}; allowed: ((x_min, x_max), (y_min, y_max))")
    rng = np.random.default_rng(seed)
    parts: list[Part] = []
    for _ in range(count):
        x, y = float(rng.uniform(x_lo, x_hi)), float(rng.uniform(y_lo, y_hi))
        scale = rng.uniform(0.5, 1.0, size=3) * s
        if rng.random() < 0.5:
            # A box lying on the floor, turned at random about z.
            yaw = float(rng.uniform(0.0, math.pi))
            sx, sy, sz = (float(v) for v in scale)
            parts.append(Box(size=(sx, sy, sz), pos=(x, y, sz / 2), yaw=yaw, kind="rock"))
        else:
            # A ball sunk into the floor by up to a third of its radius.
            r = float(scale[0]) / 2
            z = r * float(rng.uniform(-0.33, 0.0))
            parts.append(Ball(radius=r, pos=(x, y, z)))
    return Terrain(f"rocks{count}s{seed}", None, tuple(parts))


def obstacles(at: float = 1.2) -> Terrain:
    """Flat ground with a low sill, a light box a leg can push, a tall block and rocks,
    from x = ``at`` on."""
    x = real("at", at)
    return (
        flat()
        # A 6 cm sill across the path: a step for the legs, a bump for the wheels.
        + block((0.08, 1.0, 0.06), (x, 0.0))
        # 0.3 kg, in the left legs' path (LF's wheel runs at y ≈ 0.25 m): 6.7.2.
        + block((0.12, 0.12, 0.12), (x + 0.8, 0.25), mass=0.3)
        # A 15 cm block in the right legs' path, too tall for a normal step.
        + block((0.15, 0.15, 0.15), (x + 1.4, -0.25))
        + rocks(12, seed=1, size=0.04, area=((x + 2.0, x + 3.0), (-0.5, 0.5)))
    ).named("obstacles")


def course() -> Terrain:
    """A course along +x: flat start, a 15° ramp up and down (x = 2–4.1 m), obstacles
    (x = 5–8 m), flat again."""
    return (flat() + ramp(15.0, 0.15, at=2.0, plateau=1.0) + obstacles(at=5.0)).named("course")


_BUILT_IN: Final = {
    "flat": flat,
    "slope15": lambda: slope(15.0),
    "slope30": lambda: slope(30.0),
    "steps": lambda: (flat() + steps(0.06, 0.35, 3, at=1.0)).named("steps"),
    "obstacles": obstacles,
    "course": course,
}
TERRAIN_NAMES: Final = tuple(_BUILT_IN)
"""The names :func:`terrain_by_name` knows (besides ``slope<degrees>``)."""

_SLOPE_NAME = re.compile(r"slope(\d+(?:\.\d+)?)")


def terrain_by_name(name: str) -> Terrain:
    """A built-in terrain: one of :data:`TERRAIN_NAMES`, or ``slope<deg>`` for 0–50°."""
    make = _BUILT_IN.get(name)
    if make is not None:
        terrain = make()
        return terrain if terrain.name == name else terrain.named(name)
    match = _SLOPE_NAME.fullmatch(name)
    if match and float(match.group(1)) <= MAX_SLOPE_DEG:
        return slope(float(match.group(1))).named(name)
    raise UsageError(
        f"unknown terrain {name!r}; allowed: {', '.join(TERRAIN_NAMES)}, or slope<deg> (0–50)"
    )


__all__ = [
    "GROUND_FRICTION",
    "TERRAIN_NAMES",
    "Ball",
    "Box",
    "Floor",
    "Terrain",
    "block",
    "course",
    "ditch",
    "flat",
    "obstacles",
    "ramp",
    "rocks",
    "slope",
    "steps",
    "terrain_by_name",
]
