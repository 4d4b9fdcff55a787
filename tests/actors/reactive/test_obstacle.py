"""The obstacle reflex's policy, called directly on a ray-cast world: a profile sorted
into clear ground, a slope or an obstacle; the walk stopped, the obstacle measured by the
trochanter sweep, then climbed with a higher step or kept off until the way is clear."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import pytest

from whexar.actors.locomotion.asks import Asks
from whexar.actors.messages import ObstacleRanges, ReflexRequest
from whexar.actors.reactive import check_params
from whexar.actors.reactive.obstacle import RAY_DOWN_PER_TROCHANTER, ObstacleReflex
from whexar.actors.reactive.profile import profile, ray_point
from whexar.config import RobotConfig
from whexar.testing.reflexes import body_motion, leg_state, locomotion_state

CFG = RobotConfig()
H = CFG.stances["default"].height_mm / 1000  # the rays' height: the coxa joints'
DT = 0.02  # the board's frames at 50 Hz
MAX_M = CFG.ir.max_distance_mm / 1000


def reflex(**params: object) -> ObstacleReflex:
    return ObstacleReflex(check_params(ObstacleReflex, params), name="obstacle", cfg=CFG)


@dataclass
class World:
    """Flat ground with a box from ``near`` to ``far`` (m along the rays) ``height`` high."""

    near: float
    far: float
    height: float

    def range(self, down: float) -> float:
        """What a ray from H pitched ``down`` meets, m (inf: nothing within range)."""
        tan = math.tan(down)
        z_face = H - self.near * tan
        if 0.0 <= z_face <= self.height:
            r = self.near / math.cos(down)
        elif z_face > self.height and tan > 0 and (H - self.height) / tan <= self.far:
            r = (H - self.height) / tan / math.cos(down)
        elif tan > 0:
            r = H / tan / math.cos(down)
        else:
            r = math.inf
        return r if r <= MAX_M else math.inf


def sweep(world: World, downs: list[float]) -> list[tuple[float, float]]:
    return [ray_point(world.range(d), d, H) for d in downs]


def test_a_box_is_an_obstacle_with_its_height_and_depth() -> None:
    world = World(0.5, 0.8, 0.08)
    downs = [math.radians(a) for a in range(8, 33)]
    seen = profile(sweep(world, downs), min_height=0.05, tolerance=0.02, max_face_deg=50, origin=H)
    assert seen.kind == "obstacle"
    assert seen.height == pytest.approx(0.08, abs=1e-6)
    assert seen.front == pytest.approx(0.5, abs=1e-6)
    assert seen.depth == pytest.approx(0.3, abs=0.03)
    assert seen.top_seen
    assert seen.back_seen


def test_a_wall_above_every_ray_has_no_top_seen() -> None:
    world = World(0.5, 0.8, 0.6)
    downs = [math.radians(a) for a in range(8, 33)]
    seen = profile(sweep(world, downs), min_height=0.05, tolerance=0.02, max_face_deg=50)
    assert seen.kind == "obstacle"
    assert not seen.top_seen
    assert seen.height > 0.2  # a lower bound: the highest ray's point on the face


def test_a_ramp_is_a_slope_and_flat_ground_is_clear() -> None:
    rise = math.radians(15)  # from 0.4 m on
    points = []
    for a in range(8, 33):
        d = math.radians(a)
        x_flat = H / math.tan(d)
        x = x_flat if x_flat <= 0.4 else (H + 0.4 * math.tan(rise)) / (math.tan(d) + math.tan(rise))
        points.append(ray_point(x / math.cos(d), d, H))
    seen = profile(points, min_height=0.05, tolerance=0.02, max_face_deg=50)
    assert seen.kind == "slope"
    assert seen.face_deg == pytest.approx(15, abs=1)
    flat = [ray_point(H / math.sin(d), d, H) for d in (0.3, 0.35, 0.4)]
    assert profile(flat, min_height=0.05, tolerance=0.02, max_face_deg=50).kind == "clear"


def test_a_rise_whose_foot_no_ray_saw_is_measured_from_where_the_front_feet_stand() -> None:
    # The robot rode to a 15° ramp's foot, which lies under its sensors; the ramp levels
    # off 10 cm up. Every ray meets it within the top's tolerance: no face seen. Its face
    # runs from the front feet's ground, not straight up.
    rise, top = math.radians(15), 0.1
    points = []
    for a in range(18, 31, 2):
        d = math.radians(a)
        x = H / (math.tan(d) + math.tan(rise))  # on the ramp, from 0 m along the rays
        if x * math.tan(rise) > top:
            x = (H - top) / math.tan(d)  # on its plateau
        points.append(ray_point(x / math.cos(d), d, H))
    assert all(z >= top - 0.02 for _, z in points)
    unseen = profile(points, min_height=0.05, tolerance=0.02, max_face_deg=50)
    assert unseen.kind == "obstacle"  # nothing known about the ground before it
    seen = profile(points, min_height=0.05, tolerance=0.02, max_face_deg=50, ground=0.08)
    assert seen.kind == "slope"
    # A wall as near is still an obstacle: its face rises steeply from the feet.
    wall = World(0.25, 0.6, 0.4)
    near = [ray_point(wall.range(math.radians(a)), math.radians(a), H) for a in range(18, 31, 2)]
    assert profile(near, min_height=0.05, tolerance=0.02, max_face_deg=50, ground=0.08).kind == (
        "obstacle"
    )


class Drive:
    """The coordinator and the world around one reflex: the trochanter angle it asks is
    the one every ray then has; the body goes forward at ``vx`` unless halted or blocked."""

    def __init__(self, r: ObstacleReflex, world: World, vx: float = 0.1) -> None:
        self.r, self.world, self.vx = r, world, vx
        self.asks = Asks(CFG.locomotion.max_step_height_mm / 1000)
        self.t = 0.0
        self.said: list[ReflexRequest] = []

    def run(self, seconds: float, *, vy: float = 0.0) -> None:
        for _ in range(round(seconds / DT)):
            self.t += DT
            twist = self.asks.twist((self.vx, vy, 0.0))
            activity = "walking" if any(twist) else "standing"
            troch = self.asks.trochanter() or 0.0
            self._take(self.r.react(self.t, locomotion_state(self.t, activity, twist=twist)))
            self._take(self.r.react(self.t, body_motion(self.t, troch)))
            down = self.r.mount + RAY_DOWN_PER_TROCHANTER * troch
            r = self.world.range(down)
            self._take(
                self.r.react(
                    self.t,
                    ObstacleRanges(
                        t=self.t, source="board", seq=None, counts=(0, 0), distances_m=(r, r)
                    ),
                )
            )
            # The body moves toward the box (the rays' distances shrink with it).
            self.world.near -= twist[0] * DT
            self.world.far -= twist[0] * DT

    def _take(self, commands: object) -> None:
        for c in commands:  # type: ignore[attr-defined]
            assert isinstance(c, ReflexRequest)
            self.asks.take(c)
            self.said.append(c)


def test_a_low_box_stops_the_walk_is_measured_then_climbed_with_a_higher_step() -> None:
    r = reflex()
    d = Drive(r, World(1.2, 1.5, 0.08))
    d.run(6.0)
    halts = [q for q in d.said if q.halt]
    assert halts, "stopped before the box"
    assert 0.5 < d.world.near < 0.75  # a 5 cm rise shows 0.66 m ahead
    d.run(8.0)
    climb = [q for q in d.said if q.step_height_m]
    assert len(climb) == 1
    assert climb[0].step_height_m == pytest.approx(0.08 + 0.03, abs=0.01)
    assert "8 cm high" in climb[0].reason
    assert r.seen is not None
    # The depth within a sweep step: where the rays graze the top, 2° is 15 cm of ground.
    assert r.seen.depth == pytest.approx(0.3, abs=0.05)
    angles = [q.trochanter_rad for q in d.said if q.trochanter_rad]
    assert max(angles) - min(angles) == pytest.approx(math.radians(24), abs=0.01)
    assert d.asks.trochanter() is None
    assert not d.asks.halts
    assert not r.active  # it decided: the legs' reflexes are free again
    assert r.phase == "climbing"
    d.run(20.0)  # 2 m at 0.1 m/s: past the box and the body's length
    assert d.said[-1].step_height_m == 0.0
    assert not r.active


def test_a_box_whose_face_no_ray_saw_is_climbed_not_taken_for_a_slope() -> None:
    # The walk stops late (a gait's swings land first) with the box's face nearer than any
    # ray reaches: every ray meets its top 9 cm up, the front feet stand 8 cm along the
    # rays, 7 cm before the face. A face run from the feet (20°) would make it a slope.
    r = reflex()
    for leg, (mx, my) in r.mounts.items():
        foot = (mx + r.femur_reach + 0.08, my, -H)
        r.react(0.0, replace(leg_state(0.0, leg, "stance"), measured_foot=foot))
    d = Drive(r, World(0.2, 0.65, 0.09))
    d.run(10.0)
    assert r.seen is not None
    assert not r.seen.face_seen
    assert (r.seen.kind, r.phase) == ("obstacle", "climbing")
    (climb,) = [q for q in d.said if q.step_height_m]
    assert climb.step_height_m == pytest.approx(0.09 + 0.03, abs=0.01)


def test_a_wall_stops_the_robot_until_the_operator_steers_clear() -> None:
    r = reflex()
    d = Drive(r, World(1.0, 1.4, 0.5))
    d.run(14.0)
    block = [q for q in d.said if q.block_ahead]
    assert block
    assert "keeping off" in block[0].reason
    near = d.world.near
    d.run(3.0)
    assert d.world.near == near  # nothing goes forward
    assert d.asks.twist((0.1, 0.05, 0.0)) == (0.0, 0.05, 0.0)  # sidestepping does
    d.world = World(math.inf, math.inf, 0.0)  # stepped aside: the rays see the floor
    d.run(1.5)
    assert d.said[-1].block_ahead is False
    assert not r.active
    assert not d.asks.blocks


def test_its_parameters_are_checked() -> None:
    with pytest.raises(ValueError, match=r"params\.see_m"):
        reflex(see_m=0.01)
    with pytest.raises(ValueError, match=r"params\.scan_deg"):
        reflex(scan_deg=45)
