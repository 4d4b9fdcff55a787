"""Headless rendering: a frame of the robot and a short video, through EGL or OSMesa."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from whexar.bus.emulator.chain import ServoChain
from whexar.config import RobotConfig
from whexar.sim.model import load_model
from whexar.sim.run import seated_angles
from whexar.sim.video import VideoRecorder, render, select_gl, still
from whexar.sim.world import SimWorld

CFG = RobotConfig()


def _world() -> SimWorld:
    world = SimWorld(load_model(CFG), ServoChain.for_models(CFG.servos()), cfg=CFG)
    world.set_pose(seated_angles(CFG), base_xyz=(0.0, 0.0, 0.082))
    return world


@pytest.mark.slow
def test_a_frame_shows_the_robot_on_the_floor(tmp_path: Path) -> None:
    assert select_gl() in ("egl", "osmesa")  # `make test` installs them (make gl)
    world = _world()
    image = render(world, size=(320, 240))
    assert image.shape == (240, 320, 3)
    # Not a blank frame: the robot (grey and black) and the checkered floor differ.
    assert float(np.std(image)) > 10.0
    centre = image[90:150, 110:210].reshape(-1, 3).mean(axis=0)
    corner = image[200:240, 0:40].reshape(-1, 3).mean(axis=0)
    assert float(np.abs(centre - corner).sum()) > 10.0
    path = still(world, tmp_path / "still.png", size=(320, 240))
    assert path.stat().st_size > 1000


@pytest.mark.slow
def test_a_video_has_a_frame_per_period(tmp_path: Path) -> None:
    world = _world()
    path = tmp_path / "run.mp4"
    with VideoRecorder(path, size=(160, 128), fps=10) as video:
        from whexar.sim.run import Sample

        for k in range(10):
            t = k * 0.05
            video(Sample(t, 0.0, 0.0, 0.08, 0.0, 0.0, 0.0, 0.0), world)
    assert video.frames == 5  # 0.5 s at 10 frames/s, from samples every 0.05 s
    assert path.stat().st_size > 500
