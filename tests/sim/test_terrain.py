"""Terrains: the built-ins load under the robot, slopes tilt, steps rise, rocks repeat."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from whexar.errors import UsageError
from whexar.sim.model import STANCE_KEY, load_model
from whexar.sim.terrain import (
    TERRAIN_NAMES,
    block,
    course,
    ditch,
    flat,
    ramp,
    rocks,
    slope,
    steps,
    terrain_by_name,
)


def _ground_height(m: mujoco.MjModel, d: mujoco.MjData, x: float, y: float = 0.0) -> float:
    """Height of the terrain at (x, y): a ray cast down that sees terrain geoms only."""
    groups = np.array([1, 0, 0, 0, 0, 0], dtype=np.uint8)  # group 0: the terrain
    geom = np.zeros(1, dtype=np.int32)
    top = 5.0
    dist = mujoco.mj_ray(
        m, d, np.array([x, y, top]), np.array([0.0, 0.0, -1.0]), groups, 1, -1, geom
    )
    assert dist >= 0, f"no terrain under ({x}, {y})"
    return float(top - dist)


@pytest.mark.parametrize("name", TERRAIN_NAMES)
def test_every_built_in_terrain_loads_under_the_robot(name: str) -> None:
    terrain = terrain_by_name(name)
    assert terrain.name == name
    m = load_model(terrain=terrain)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key(STANCE_KEY).id)
    mujoco.mj_forward(m, d)
    # The robot starts clear of the terrain: nothing touches until it drops.
    base = m.body("base").id
    robot = {b for b in range(m.nbody) if m.body_rootid[b] == base}
    for c in d.contact[: d.ncon]:
        bodies = {int(m.geom_bodyid[c.geom1]), int(m.geom_bodyid[c.geom2])}
        assert not bodies & robot, f"the robot starts inside the terrain ({name})"


def test_the_robot_starts_on_the_flat_before_every_feature() -> None:
    for name in ("steps", "obstacles", "course"):
        m = load_model(terrain=terrain_by_name(name))
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        for x in np.linspace(-0.6, 0.8, 15):
            for y in (-0.4, 0.0, 0.4):
                assert _ground_height(m, d, x, y) == pytest.approx(0.0, abs=1e-9), (name, x, y)
    m = load_model(terrain=course())
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    for x in np.linspace(-1.0, 1.95, 30):
        assert _ground_height(m, d, x) == pytest.approx(0.0, abs=1e-9)
    assert _ground_height(m, d, 9.0) == pytest.approx(0.0, abs=1e-9)  # flat again


@pytest.mark.parametrize("angle", [0.0, 15.0, 30.0, 50.0])
def test_the_slope_is_a_plane_tilted_by_the_commanded_angle(angle: float) -> None:
    m = load_model(terrain=slope(angle))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key(STANCE_KEY).id)
    mujoco.mj_forward(m, d)
    floor = m.geom("floor")
    assert floor.type[0] == mujoco.mjtGeom.mjGEOM_PLANE
    normal = d.geom_xmat[floor.id].reshape(3, 3)[:, 2]
    assert math.degrees(math.acos(normal[2])) == pytest.approx(angle, abs=1e-9)
    assert normal[0] <= 0.0
    assert normal[1] == pytest.approx(0.0)
    # The body starts parallel to the slope: the IMU sees the tilt as real gravity would.
    up = d.xmat[m.body("base").id].reshape(3, 3)[:, 2]
    np.testing.assert_allclose(up, normal, atol=1e-12)
    assert m.opt.gravity[2] == pytest.approx(-9.81)
    assert m.opt.gravity[0] == 0.0
    if angle:
        assert _ground_height(m, d, 1.0) == pytest.approx(math.tan(math.radians(angle)))


def test_a_slope_is_refused_outside_0_to_50_degrees() -> None:
    with pytest.raises(UsageError, match="0–50"):
        slope(55.0)
    with pytest.raises(UsageError):
        slope(-1.0)
    assert terrain_by_name("slope20").ground.slope_deg == 20.0


def test_rocks_are_the_same_for_a_seed_and_differ_between_seeds() -> None:
    first = rocks(10, seed=5, size=0.05)
    assert first == rocks(10, seed=5, size=0.05)
    assert first.parts != rocks(10, seed=6, size=0.05).parts
    assert len(first.parts) == 10
    for part in first.parts:
        x, y, _ = part.pos
        assert 1.0 <= x <= 3.0
        assert -0.6 <= y <= 0.6


def test_steps_rise_by_their_height() -> None:
    m = load_model(terrain=flat() + steps(0.05, 0.3, 3, at=1.0, landing=0.5))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    # Up at x = 1.0, 1.3, 1.6; the top step is 0.5 m long; down at 2.1, 2.4, 2.7.
    expected = {1.15: 0.05, 1.45: 0.10, 1.75: 0.15, 2.0: 0.15, 2.25: 0.10, 2.55: 0.05, 2.8: 0.0}
    for x, z in expected.items():
        assert _ground_height(m, d, x) == pytest.approx(z, abs=1e-9), x


def test_a_ramp_rises_at_its_angle_and_comes_down_again() -> None:
    m = load_model(terrain=flat() + ramp(15.0, 0.15, at=2.0, plateau=1.0))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    tan = math.tan(math.radians(15.0))
    run = 0.15 / tan
    for dx in (0.1, 0.3, 0.5):
        assert _ground_height(m, d, 2.0 + dx) == pytest.approx(dx * tan, abs=1e-9)
    assert _ground_height(m, d, 2.0 + run + 0.5) == pytest.approx(0.15)
    assert _ground_height(m, d, 2.0 + 2 * run + 1.0 - 0.1) == pytest.approx(0.1 * tan, abs=1e-9)


def test_a_ditch_cuts_the_floor() -> None:
    m = load_model(terrain=flat() + ditch(0.2, 0.1, at=1.5))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    assert _ground_height(m, d, 1.4) == pytest.approx(0.0)
    assert _ground_height(m, d, 1.6) == pytest.approx(-0.1)
    assert _ground_height(m, d, 1.8) == pytest.approx(0.0)
    with pytest.raises(UsageError, match="ditch"):
        load_model(terrain=ditch(0.4, 0.1, at=-0.2))  # under the start


def test_a_block_with_a_mass_is_free_and_light() -> None:
    terrain = (
        flat() + block((0.1, 0.1, 0.1), (1.0, 0.2), mass=0.3) + block((0.1, 0.1, 0.2), (1.5, 0))
    )
    m = load_model(terrain=terrain)
    free = m.body("block_0")
    assert m.jnt_type[free.jntadr[0]] == mujoco.mjtJoint.mjJNT_FREE
    assert free.mass[0] == pytest.approx(0.3)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key(STANCE_KEY).id)
    for _ in range(200):
        mujoco.mj_step(m, d)
    assert d.xpos[free.id][2] == pytest.approx(0.05, abs=1e-3)  # resting on the floor
    assert m.geom("block_1").bodyid[0] == 0  # static


def test_terrains_combine_only_with_a_common_floor() -> None:
    combined = flat() + ditch(0.2, 0.1, at=1.0) + ditch(0.3, 0.2, at=2.0)
    assert len(combined.ground.ditches) == 2
    with pytest.raises(UsageError, match="ramp"):
        slope(10.0) + slope(20.0)
    assert (slope(10.0) + block((0.1, 0.1, 0.1), (1.0, 0.0))).ground.slope_deg == 10.0
    assert (flat() + slope(10.0)).ground.slope_deg == 10.0  # the level floor gives way
    with pytest.raises(UsageError, match="level floor"):
        slope(10.0) + ditch(0.2, 0.1, at=1.0)


def test_an_unknown_terrain_name_lists_the_known_ones() -> None:
    with pytest.raises(UsageError) as info:
        terrain_by_name("moon")
    for name in TERRAIN_NAMES:
        assert name in str(info.value)


def test_the_tyres_grip_as_the_thesis_implies() -> None:
    """The thesis's robot stood on its board at 50° (6.8.1): µ ≥ tan 50° = 1.19."""
    import math

    from whexar.sim.terrain import GROUND_FRICTION

    assert GROUND_FRICTION[0] >= math.tan(math.radians(50.0))
