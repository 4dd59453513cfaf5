"""The Baxter reach-grasp-align task in MuJoCo, behind the Gymnasium and PettingZoo APIs."""

from dualarm.envs.config import CONDITIONS, GOALS, TaskConfig
from dualarm.envs.scene import SceneConfig

__all__ = ["CONDITIONS", "GOALS", "SceneConfig", "TaskConfig", "make_core"]

RENDER_MODES = (None, "rgb_array")


class CoreView:
    """What the Gymnasium and PettingZoo environments share: a core, rendering, closing."""

    core = None
    render_mode = None

    def _attach_core(self, render_mode, config, constraints, overrides) -> None:
        if render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        self.core = make_core(config, constraints, **overrides)

    def render(self):
        """The current frame (480, 640, 3) uint8 with render_mode "rgb_array", else None."""
        if self.render_mode == "rgb_array":
            return self.core.render()
        return None

    def close(self):
        """Release the renderer."""
        self.core.close()


def make_core(config: TaskConfig | None = None, constraints=None, **overrides):
    """The simulation core ``BaxterReachGraspAlign`` for ``config`` with some fields overridden.

    ``constraints`` may be a ``ConstraintSet`` or the path of a constraints file.
    """
    from dualarm.constraints.constraint_set import ConstraintSet
    from dualarm.envs.baxter import BaxterReachGraspAlign

    config = (config or TaskConfig()).with_(**overrides)
    if constraints is not None and not isinstance(constraints, ConstraintSet):
        constraints = ConstraintSet.load(constraints)
    return BaxterReachGraspAlign(config, constraints)
