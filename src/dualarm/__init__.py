"""dualarm: human joint-angle constraints from IMU demonstrations guiding dual-agent DDPG."""

import os as _os
import sys as _sys

__version__ = "0.1.0"

# Headless Linux: MuJoCo's default OpenGL backend (GLFW) needs a display. Choose EGL
# unless the user chose a backend or has a display; must happen before mujoco is imported.
#: Whether MuJoCo was imported before dualarm (then our backend choice came too late).
MUJOCO_IMPORTED_FIRST = "mujoco" in _sys.modules

if _sys.platform.startswith("linux") and "MUJOCO_GL" not in _os.environ \
        and not _os.environ.get("DISPLAY") and not _os.environ.get("WAYLAND_DISPLAY"):
    _os.environ["MUJOCO_GL"] = "egl"
    _os.environ.setdefault("PYOPENGL_PLATFORM", "egl")


def _register_environments() -> None:
    """Register the Gymnasium id ``dualarm/BaxterReachGraspAlign-v0`` (lazy: nothing heavy loads)."""
    import gymnasium

    env_id = "dualarm/BaxterReachGraspAlign-v0"
    if env_id not in gymnasium.registry:
        gymnasium.register(id=env_id, entry_point="dualarm.envs.gym_env:BaxterReachGraspAlignEnv",
                           max_episode_steps=None)


_register_environments()
