"""Offscreen rendering of the Baxter scene (headless through EGL or OSMesa) and video files.

Physics runs on a model without the robot's visual meshes; frames come from a twin
model with them, into which the physics state is copied (same bodies and joints, so the
same qpos layout).
"""

from __future__ import annotations

import os
from pathlib import Path

import mujoco
import numpy as np

from dualarm.atomic import atomic_path
from dualarm.envs.scene import SceneConfig, compiled_model
from dualarm.errors import DualarmError

CAMERAS = ("front", "side")


def make_renderer(model: mujoco.MjModel, height: int, width: int) -> mujoco.Renderer:
    """A ``mujoco.Renderer``, with a clear error when no OpenGL backend can start.

    Headless Linux needs ``MUJOCO_GL=egl`` (or ``osmesa``) set before MuJoCo is imported;
    ``import dualarm`` sets ``egl`` when no display and no choice are present.
    """
    try:
        return mujoco.Renderer(model, height=height, width=width)
    except Exception as error:  # the GL backends raise assorted types
        import dualarm

        backend = os.environ.get("MUJOCO_GL", "(unset: GLFW, needs a display)")
        if dualarm.MUJOCO_IMPORTED_FIRST:
            raise DualarmError(
                f"cannot start MuJoCo's renderer ({error}): mujoco was imported before dualarm "
                "and picked its OpenGL backend then. Set MUJOCO_GL=egl (or osmesa) in the "
                "environment, or import dualarm first") from error
        raise DualarmError(
            f"cannot start MuJoCo's renderer with MUJOCO_GL={backend}: {error}. On a headless "
            "machine install EGL (apt-get install libegl1 libgl1 libgles2) and run with "
            "MUJOCO_GL=egl, or OSMesa (libosmesa6) with MUJOCO_GL=osmesa") from error


class SceneRenderer:
    """Renders the physics state of a scene through its visual twin.

    Args:
        scene: the scene configuration of the physics model.
        control: its control mode (the cartesian scene has the hand-target bodies).
        height, width: frame size in pixels.
    """

    def __init__(self, scene: SceneConfig, control: str, height: int = 480, width: int = 640):
        self.model = compiled_model(scene, True, control)
        self.data = mujoco.MjData(self.model)
        self.renderer = make_renderer(self.model, height, width)
        self.options = mujoco.MjvOption()
        self.options.sitegroup[:] = 0   # hide robosuite's helper sites (a 20 m grip axis among them)

    def render(self, physics: mujoco.MjData, camera: str = "front") -> np.ndarray:
        """RGB frame (height, width, 3) uint8 of ``physics`` seen from ``camera``."""
        if camera not in CAMERAS:
            raise ValueError(f"camera must be one of {CAMERAS}, got {camera!r}")
        self.data.qpos[:] = physics.qpos
        self.data.mocap_pos[:] = physics.mocap_pos
        self.data.mocap_quat[:] = physics.mocap_quat
        mujoco.mj_forward(self.model, self.data)   # kinematics and the cameras' poses
        self.renderer.update_scene(self.data, camera=camera, scene_option=self.options)
        return self.renderer.render()

    def close(self) -> None:
        """Release the GL context."""
        self.renderer.close()


def write_video(path: str | Path, frames: list[np.ndarray], fps: float) -> Path:
    """Write RGB frames (each (H, W, 3) uint8) as an H.264 MP4 (or a GIF by extension), atomically.

    Args:
        path: output file, ``.mp4`` or ``.gif``.
        frames: the frames, all the same size.
        fps: frames per second.
    """
    import imageio.v3 as iio

    path = Path(path)
    if not frames:
        raise ValueError("no frames to write")
    suffix = path.suffix.lower()
    if suffix not in (".mp4", ".gif"):
        raise ValueError(f"{path}: video must end in .mp4 or .gif")
    with atomic_path(path) as tmp:
        if suffix == ".mp4":
            iio.imwrite(tmp, np.stack(frames), fps=fps, codec="libx264", macro_block_size=8,
                        plugin="FFMPEG")
        else:
            iio.imwrite(tmp, np.stack(frames), duration=1000.0 / fps, loop=0)
    return path
