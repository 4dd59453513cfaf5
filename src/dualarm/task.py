"""The task's vocabulary, written once: arms, joints, sub-tasks, conditions and the paper's
constants. Every other module imports these names from here; this module imports nothing
of the project's, so any stage may use it.
"""

from __future__ import annotations

#: The two arms, in the order of every pair (s = (s_l, s_r)).
ARMS = ("left", "right")
#: Baxter's 7 joints per arm, q1..q7 of the paper.
BAXTER_JOINT_NAMES = ("s0", "s1", "e0", "e1", "w0", "w1", "w2")
#: Joints per arm.
JOINTS_PER_ARM = len(BAXTER_JOINT_NAMES)
#: The 14 joint columns of a dual-arm joint vector: left arm s0..w2, then right arm s0..w2.
JOINT_COLUMNS = tuple(f"{arm}_{joint}" for arm in ARMS for joint in BAXTER_JOINT_NAMES)
#: Sub-tasks of the dual-arm task, in the order they are done.
SUBTASKS = ("reach", "grasp", "align")

#: Guidance conditions of the paper's experiment, in the order of every table and figure:
#: no constraint, one constraint for the whole task (C1), one per sub-task (C2, C3).
CONDITIONS = ("none", "single", "multi")
#: The conditions guided by joint-angle constraints.
GUIDED_CONDITIONS = ("single", "multi")
#: Beyond the paper: the recordings themselves as the learner's demonstrations, on top of the
#: multi-segment constraints (its guide condition).
DEMOS_CONDITION = "demos"
#: The conditions a comparison may hold: the paper's three, then ``DEMOS_CONDITION``.
COMPARED_CONDITIONS = CONDITIONS + (DEMOS_CONDITION,)
#: How tables and figures name the conditions.
CONDITION_NAMES = {"none": "no constraint", "single": "single-segment C1",
                   "multi": "multi-segment C2&C3", "demos": "recordings as demonstrations + C2&C3"}


def guide_condition(condition: str) -> str:
    """The guide term's condition (one of ``CONDITIONS``) of a compared condition."""
    return "multi" if condition == DEMOS_CONDITION else condition

#: Paper constants (Section 3.2.1.3): rg1, rg2 (once per arm), rc (once, to both arms) and
#: the guide reward's c0 per sub-task (reach, grasp, align).
PAPER_REACH_BONUS = 1.0
PAPER_GRASP_BONUS = 20.0
PAPER_COORDINATE_BONUS = 4000.0
PAPER_C0 = (0.01, 0.01, 0.05)
#: The largest seed of a run or an episode: numpy's seeds are unsigned 32-bit here.
MAX_SEED = 2 ** 32 - 1
#: The success rate of the paper's "episodes to 0.85" (Section 3.2.2).
TARGET_SUCCESS = 0.85
