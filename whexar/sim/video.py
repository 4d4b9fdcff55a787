"""Headless video of a simulated run: MuJoCo's offscreen renderer, a following camera, H.264.

Theory of operation
-------------------
*OpenGL without a display.* MuJoCo chooses its OpenGL back end from the
environment variable ``MUJOCO_GL`` when it is first imported: ``egl``
(``libegl1``, works on this kind of machine as is) or ``osmesa`` (software,
``libosmesa6``). :func:`select_gl` picks one that works before anything
renders: the one already set, else EGL, else OSMesa, each tried in a child
process (a back end that fails can take the process down with it, and one
cannot be unloaded). When mujoco was imported before the choice, the chosen
back end's context class is put in the place mujoco's renderer looks it up.
Importing this module sets ``MUJOCO_GL=egl`` when nothing is set and mujoco is
not imported yet, so a plain ``import whexar.sim.video`` first is enough on
most machines.

*Frames.* :class:`VideoRecorder` is an ``on_sample`` callback of
:func:`~whexar.sim.run.simulate`: the run samples the world every 0.05 s of
simulated time, and the recorder renders a frame whenever the next frame of
its ``fps`` is due (every sample at 20 fps), so the video plays in simulated
real time. A frame is rendered from a free camera tracking the robot's base
body (``mjCAMERA_TRACKING``) from behind and to the left. The robot's geoms
live in geom group 3 (:class:`~whexar.sim.world.SimWorld` moves them there so
the IR rays skip them), which MuJoCo hides by default: the scene option shows
every group. Frames go straight to ffmpeg (``imageio-ffmpeg`` ships its own)
as H.264 in ``yuv420p``, which every player plays; nothing is kept in memory.

*Cost.* Frames are drawn without shadows and without multisampling: the sun's
shadow map took most of a frame's time on a machine without a GPU and drew acne
over the floor (docs/sim.md, "Video", has the times). A 60 s run at 20 fps is
1200 frames: rendering, not physics, sets the pace of ``--video``.

:func:`still` saves one frame as PNG (the README's picture).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from whexar.errors import UsageError

if "mujoco" not in sys.modules:
    # The back end is read once, at mujoco's import: choose a headless one early.
    os.environ.setdefault("MUJOCO_GL", "egl")

if TYPE_CHECKING:
    import numpy as np

    from whexar.sim.run import Sample
    from whexar.sim.world import SimWorld

BACKENDS: Final = ("egl", "osmesa")
"""Headless OpenGL back ends, in the order tried."""
DEFAULT_SIZE: Final = (640, 480)
"""Video frame (width, height): a multiple of 16 both ways, as H.264 encoders like."""
DEFAULT_FPS: Final = 20
CAMERA_DISTANCE_M: Final = 1.6
CAMERA_AZIMUTH_DEG: Final = -55.0
"""Looking forward and to the right: the camera stands behind the robot, on its left."""
CAMERA_ELEVATION_DEG: Final = -22.0

_PROBE = (
    "import mujoco\n"
    'm = mujoco.MjModel.from_xml_string(\'<mujoco><worldbody><geom size="1"/></worldbody>'
    "</mujoco>')\n"
    "r = mujoco.Renderer(m, 16, 16)\n"
    "r.update_scene(mujoco.MjData(m))\n"
    "r.render()\n"
)
_chosen: str | None = None


def _works(backend: str) -> bool:
    """Whether a child process renders a frame with ``backend``."""
    env = {**os.environ, "MUJOCO_GL": backend}
    env.pop("PYOPENGL_PLATFORM", None)
    try:
        done = subprocess.run(
            [sys.executable, "-c", _PROBE], env=env, capture_output=True, timeout=60, check=False
        )
    except (OSError, subprocess.TimeoutExpired):
        return False
    return done.returncode == 0


def select_gl() -> str:
    """Choose MuJoCo's headless OpenGL back end and return its name (see the module docstring).

    Raises :class:`~whexar.errors.UsageError` when none works, naming the
    Debian packages that provide them.
    """
    global _chosen
    if _chosen is not None:
        return _chosen
    wanted = os.environ.get("MUJOCO_GL", "").lower()
    candidates = [wanted] if wanted and wanted not in BACKENDS else []
    candidates += [wanted] if wanted in BACKENDS else []
    candidates += [b for b in BACKENDS if b != wanted]
    for backend in candidates:
        if _works(backend):
            break
    else:
        raise UsageError(
            "no headless OpenGL for MuJoCo: neither EGL nor OSMesa renders here. "
            "Install them (Debian: apt-get install libegl1 libgl1 libosmesa6; `make sim` does) "
            "or run on a machine with a display and MUJOCO_GL=glfw"
        )
    os.environ["MUJOCO_GL"] = backend
    if "mujoco" in sys.modules:
        _install_context(backend)
    _chosen = backend
    return backend


def _install_context(backend: str) -> None:
    """Make an already imported mujoco's renderer use ``backend``'s OpenGL context."""
    import importlib

    from mujoco.rendering.classic import gl_context

    if getattr(gl_context, "_MUJOCO_GL", None) == backend:
        return
    os.environ.pop("PYOPENGL_PLATFORM", None)
    module = importlib.import_module(f"mujoco.{backend}")
    gl_context.GLContext = module.GLContext


def _camera(world: SimWorld) -> Any:
    import mujoco

    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
    cam.trackbodyid = mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_BODY, "base")
    cam.distance = CAMERA_DISTANCE_M
    cam.azimuth = CAMERA_AZIMUTH_DEG
    cam.elevation = CAMERA_ELEVATION_DEG
    return cam


def _scene_option() -> Any:
    import mujoco

    opt = mujoco.MjvOption()
    opt.geomgroup[:] = 1  # the robot's geoms are in group 3, hidden by default
    opt.sitegroup[:] = 0  # sites (IMU, contact points, IR) are markers, not parts
    return opt


def _renderer(world: SimWorld, width: int, height: int) -> Any:
    """A renderer for ``world``'s model, its framebuffer grown when too small."""
    import mujoco

    select_gl()
    vis = world.model.vis
    vis.global_.offwidth = max(int(vis.global_.offwidth), width)
    vis.global_.offheight = max(int(vis.global_.offheight), height)
    vis.quality.offsamples = 0  # no multisampling: a good part of a frame's time
    renderer = mujoco.Renderer(world.model, height, width)
    # No shadows: the sun's shadow map cost most of a frame's time without a GPU and
    # drew acne (moiré) over the floor (docs/sim.md, "Video").
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
    return renderer


class VideoRecorder:
    """An ``on_sample`` callback writing a video of the run to ``path`` (H.264 mp4).

    Use as a context manager, or call :meth:`close` after the run::

        with VideoRecorder("run.mp4") as video:
            simulate(..., on_sample=video)
    """

    def __init__(
        self,
        path: str | Path,
        *,
        size: tuple[int, int] = DEFAULT_SIZE,
        fps: int = DEFAULT_FPS,
    ) -> None:
        width, height = size
        if width % 16 or height % 16 or width <= 0 or height <= 0:
            raise UsageError(f"video size {size!r}: width and height multiples of 16")
        if fps <= 0:
            raise UsageError(f"video fps {fps!r}: expected > 0")
        self.path = Path(path)
        self.size = (width, height)
        self.fps = fps
        self.frames = 0
        self._next_t = 0.0
        self._renderer: Any = None
        self._camera: Any = None
        self._option: Any = None
        self._writer: Any = None

    def __call__(self, sample: Sample, world: SimWorld) -> None:
        """Render a frame if one is due at ``sample.t``."""
        if self._renderer is None:
            self._open(world)
            self._next_t = sample.t
        if sample.t + 1e-9 < self._next_t:
            return
        frame = self._render(world)
        # Every frame due by now shows this sample: the video keeps simulated time even
        # when frames come faster than samples.
        while self._next_t <= sample.t + 1e-9:
            self._writer.append_data(frame)
            self.frames += 1
            self._next_t += 1 / self.fps

    def _open(self, world: SimWorld) -> None:
        import imageio.v2 as imageio

        width, height = self.size
        self._renderer = _renderer(world, width, height)
        self._camera = _camera(world)
        self._option = _scene_option()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._writer = imageio.get_writer(
            self.path,
            fps=self.fps,
            codec="libx264",
            pixelformat="yuv420p",
            quality=7,
            macro_block_size=16,
            ffmpeg_log_level="error",
        )

    def _render(self, world: SimWorld) -> np.ndarray:
        self._renderer.update_scene(world.data, camera=self._camera, scene_option=self._option)
        frame: np.ndarray = self._renderer.render()
        return frame

    def close(self) -> None:
        """Finish the file and free the renderer."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __enter__(self) -> VideoRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def render(world: SimWorld, *, size: tuple[int, int] = (1280, 720)) -> np.ndarray:
    """One frame of ``world`` as it is now, from the following camera (height × width × 3)."""
    width, height = size
    renderer = _renderer(world, width, height)
    try:
        renderer.update_scene(world.data, camera=_camera(world), scene_option=_scene_option())
        frame: np.ndarray = renderer.render()
        return frame
    finally:
        renderer.close()


def still(world: SimWorld, path: str | Path, *, size: tuple[int, int] = (1280, 720)) -> Path:
    """Save one frame of ``world`` as it is now as a PNG; its path."""
    import imageio.v2 as imageio

    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    imageio.imwrite(out, render(world, size=size))
    return out


__all__ = [
    "BACKENDS",
    "DEFAULT_FPS",
    "DEFAULT_SIZE",
    "VideoRecorder",
    "render",
    "select_gl",
    "still",
]
