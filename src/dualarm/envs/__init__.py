"""The Baxter reach-grasp-align task in MuJoCo, behind the Gymnasium and PettingZoo APIs."""

from dualarm.envs.config import CONDITIONS, GOALS, TaskConfig
from dualarm.envs.scene import SceneConfig

__all__ = ["CONDITIONS", "GOALS", "SceneConfig", "TaskConfig", "make_core"]


def make_core(config: TaskConfig | None = None, constraints=None, **overrides):
    """The simulation core ``BaxterReachGraspAlign`` for ``config`` with some fields overridden.

    ``constraints`` may be a ``ConstraintSet`` or the path of a constraints file.
    """
    from dualarm.constraints import ConstraintSet
    from dualarm.envs.baxter import BaxterReachGraspAlign

    config = (config or TaskConfig()).with_(**overrides)
    if constraints is not None and not isinstance(constraints, ConstraintSet):
        constraints = ConstraintSet.load(constraints)
    return BaxterReachGraspAlign(config, constraints)
