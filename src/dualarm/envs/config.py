"""One configuration of the reach-grasp-align task: every threshold, range and weight by name.

Values the paper gives are marked (paper); the rest were chosen so that the scripted
expert solves the task with margin (``dualarm env expert`` measures it).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

from dualarm.envs.scene import SceneConfig
from dualarm.errors import InputError
from dualarm.task import (CONDITIONS, PAPER_C0, PAPER_COORDINATE_BONUS, PAPER_GRASP_BONUS,
                          PAPER_REACH_BONUS, SUBTASKS)
from dualarm.typed_fields import check_field_types

GOALS = ("subtask", "final")


@dataclass(frozen=True)
class TaskConfig:
    """The reach-grasp-align task of paper Section 3.2.1 (lengths in m, times in s).

    Attributes:
        control: "cartesian" (per arm dx, dy, dz, grip) or "joint" (7 joint deltas, grip).
        condition: guidance by human joint-angle constraints: "none", "single" (C1) or
            "multi" (C2 for reach+grasp, C3 for align).
        goal: what ``goal_i`` in the distance term is. "subtask" (default): the box's grasp
            point during reach and grasp, the arm's target during align. "final": the
            arm's target throughout, as Eq. 17 is printed (pos_finalgoal).
        joint_angles_in_obs: put each arm's 7 joint angles in its observation; None means
            "only when guided" (the paper adds them for the constrained conditions).
        reach_funnel: slope of the approach funnel of the distance term during reach: its
            goal sits above the box centre by this many metres per metre of horizontal
            offset (capped at ``reach_funnel_height``), so that descending before the
            gripper is over the box no longer pays and the fingers stop sweeping the box
            away. 0 is the box centre itself, as in the paper (docs/env.md).
        reach_funnel_height: the highest the funnel's goal sits above the box centre.
        max_episode_steps: steps before truncation.
        substeps: physics steps per control step (control period = substeps * timestep).
        max_cartesian_step: the target's lead over the grip site per step at action 1 (the
            paper's gym: 5 cm; the weld covers about 40 % of it per step, so a full action
            moves the grip 2 cm per step, docs/env.md).
        max_joint_step: joint-target change per step at action 1 in joint mode (rad).
        min_grip_height: lowest grip-site height above the table top (keeps fingers off it).
        grip_x_range, grip_y_range: the box of world x and y (m) that Cartesian grip-site
            commands are clipped to.
        grip_max_z: the highest world z (m) of a Cartesian grip-site command (the lowest is
            the table top plus ``min_grip_height``).
        reach_threshold: reach is complete when the grip site is this close to the box centre.
        grasp_tolerance: the box counts as between the fingers within this of the grip site.
        grasp_gap_margin: fingers count as closed on the box when their gap is at most the
            box width plus this.
        lift_height: grasp is complete when the held box is this far above its start height.
        align_threshold: a box is at its target when its centre is this close to it.
        reach_bonus: rg1, given once when reach completes (paper: 1).
        grasp_bonus: rg2, given once when grasp completes (paper: 20).
        coordinate_bonus: rc, given once to both agents on success (paper: 4000).
        guide_c0: c0 per sub-task (reach, grasp, align) of the guide term (paper: 0.01, 0.01, 0.05).
        box_x_range: x range of both boxes' start positions.
        box_y_range: |y| range of the boxes' start positions (left box at +y, right at -y).
        target_x_range: x range of the two targets (shared: the boxes end aligned).
        target_center_y_range: y range of the midpoint between the two targets.
        target_height_range: height of the targets above the boxes' resting height.
        target_half_separation: half the distance between the two targets along y.
        home_grip: (x, |y|, z) of the grip sites at reset (left at +y).
        terminate_on_success: end the episode when both boxes are at their targets.
        success_at: the sub-task whose completion by both arms is success (and pays rc):
            "align" is the full task; "reach" or "grasp" give shorter curricula and tests.
        scene: geometry and physics of the scene.
    """

    control: str = "cartesian"
    condition: str = "none"
    goal: str = "subtask"
    joint_angles_in_obs: bool | None = None
    reach_funnel: float = 0.0
    reach_funnel_height: float = 0.1
    max_episode_steps: int = 50
    substeps: int = 10
    max_cartesian_step: float = 0.05
    max_joint_step: float = 0.1
    min_grip_height: float = 0.02
    grip_x_range: tuple[float, float] = (0.25, 1.1)
    grip_y_range: tuple[float, float] = (-0.7, 0.7)
    grip_max_z: float = 1.4
    reach_threshold: float = 0.02
    grasp_tolerance: float = 0.02
    grasp_gap_margin: float = 0.006
    lift_height: float = 0.02
    align_threshold: float = 0.03
    reach_bonus: float = PAPER_REACH_BONUS
    grasp_bonus: float = PAPER_GRASP_BONUS
    coordinate_bonus: float = PAPER_COORDINATE_BONUS
    guide_c0: tuple[float, float, float] = PAPER_C0
    box_x_range: tuple[float, float] = (0.55, 0.75)
    box_y_range: tuple[float, float] = (0.1, 0.3)
    target_x_range: tuple[float, float] = (0.6, 0.75)
    target_center_y_range: tuple[float, float] = (-0.05, 0.05)
    target_height_range: tuple[float, float] = (0.1, 0.22)
    target_half_separation: float = 0.1
    home_grip: tuple[float, float, float] = (0.5, 0.25, 0.95)
    terminate_on_success: bool = True
    success_at: str = "align"
    scene: SceneConfig = field(default_factory=SceneConfig)

    def __post_init__(self):
        check_field_types(self)
        from dualarm.envs.scene import CONTROL_MODES
        if self.control not in CONTROL_MODES:
            raise InputError(f"control must be one of {CONTROL_MODES}, got {self.control!r}")
        if self.condition not in CONDITIONS:
            raise InputError(f"condition must be one of {CONDITIONS}, got {self.condition!r}")
        if self.goal not in GOALS:
            raise InputError(f"goal must be one of {GOALS}, got {self.goal!r}")
        if self.success_at not in SUBTASKS:
            raise InputError(f"success_at must be one of {SUBTASKS}, got {self.success_at!r}")
        if self.max_episode_steps < 1 or self.substeps < 1:
            raise InputError("max_episode_steps and substeps must be at least 1")
        if self.grip_max_z <= self.scene.table_height + self.min_grip_height:
            raise InputError(f"grip_max_z ({self.grip_max_z} m) must be above the table top plus "
                             f"min_grip_height ({self.scene.table_height + self.min_grip_height} m)")
        if self.reach_funnel < 0 or self.reach_funnel_height < 0:
            raise InputError("reach_funnel and reach_funnel_height must be non-negative, got "
                             f"{self.reach_funnel} and {self.reach_funnel_height}")
        if len(self.guide_c0) != 3 or min(self.guide_c0) < 0:
            raise InputError(f"guide_c0 must be 3 non-negative numbers, got {self.guide_c0}")
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name.endswith("_range") and not (len(value) == 2 and value[0] <= value[1]):
                raise InputError(f"{f.name} must be (low, high) with low <= high, got {value}")

    @property
    def observes_joint_angles(self) -> bool:
        """Whether observations carry the joint angles (resolves ``joint_angles_in_obs=None``)."""
        if self.joint_angles_in_obs is None:
            return self.condition != "none"
        return self.joint_angles_in_obs

    def workspace(self):
        """Where a demonstration's scene may place the boxes and targets
        (``dualarm.demos.scene.Workspace``): x and y within the grip sites' command box, boxes
        resting on the table, targets between the table top and ``grip_max_z``."""
        from dualarm.demos.scene import Workspace

        return Workspace(self.grip_x_range, self.grip_y_range,
                         self.scene.table_height + self.scene.box_half_size, 0.01,
                         self.scene.table_height, self.grip_max_z)

    @property
    def control_period(self) -> float:
        """Seconds of simulated time per environment step."""
        return self.substeps * self.scene.timestep

    def with_(self, **changes) -> "TaskConfig":
        """A copy with some fields changed."""
        return replace(self, **changes)
