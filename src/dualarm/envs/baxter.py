"""The reach-grasp-align task on the MuJoCo Baxter scene: physics, sub-task states, rewards.

``BaxterReachGraspAlign`` is the simulation core with plain numpy input and output for
both arms at once (rows: left, right). The Gymnasium and PettingZoo environments in
``dualarm.envs.gym_env`` and ``dualarm.envs.pettingzoo_env`` wrap it.

Sub-task of each arm, evaluated from the physical state at every step (paper Eq. 16,
"the first goal not yet reached"):

* reach (0) until the grip site is within ``reach_threshold`` of its box's centre;
* grasp (1) until the box is between the closed fingers and lifted ``lift_height``;
* align (2) while the box is held; it is at its target within ``align_threshold``.

A dropped box sends the arm back to reach. The task succeeds when both boxes are at
their targets at the same step. Reward of arm i (Eqs. 16-18):
``R_i = -|grip_i - goal_i| + r_guide,i + r_goal,i + r_coordinate``, every term in
``info["reward_terms"]``; rg1, rg2 are paid once per episode per arm, rc once to both.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import mujoco
import numpy as np

from dualarm.constraints import SUBTASKS, ConstraintSet
from dualarm.envs.config import TaskConfig
from dualarm.envs.scene import GRIP_DOWN_QUAT, REST_POSTURE, compiled_model
from dualarm.kinematics import ARMS, BAXTER_JOINT_LIMITS, BAXTER_JOINT_NAMES

#: Finger joint targets (m) fully open and fully closed, columns r_finger, l_finger.
FINGER_OPEN = np.array([-0.020833, 0.020833])
FINGER_CLOSED = np.array([0.0115, -0.0115])
_FINGER_TRAVEL = FINGER_CLOSED - FINGER_OPEN
#: Finger-pad gap (m) at finger joints (0, 0): the gap is this + l - r.
_GAP_AT_ZERO = 2 * (0.01 + 0.01725 - 0.0047 - 0.0035)

#: Per-arm observation layout (paper Section 3.2.1.2): name -> size. "joint_angles" is
#: present only when the configuration asks for it.
OBS_LAYOUT = (
    ("grip_pos", 3),         # grip-site position, m (world)
    ("joint_angles", 7),     # s0..w2, rad
    ("object_pos", 3),       # box centre, m
    ("object_rel_pos", 3),   # box centre - grip site, m
    ("fingers", 2),          # finger joint positions (r, l), m
    ("object_quat", 4),      # box orientation (w, x, y, z), w >= 0
    ("object_linvel", 3),    # box linear velocity, m/s (world)
    ("object_angvel", 3),    # box angular velocity, rad/s (box frame)
    ("grip_linvel", 3),      # grip-site mean velocity over the last step, m/s
    ("finger_vel", 2),       # finger joint velocities, m/s
    ("target_pos", 3),       # the arm's target, m
)


def observation_layout(joint_angles: bool) -> dict[str, slice]:
    """Slices of each field in one arm's observation vector."""
    layout, start = {}, 0
    for name, size in OBS_LAYOUT:
        if name == "joint_angles" and not joint_angles:
            continue
        layout[name] = slice(start, start + size)
        start += size
    return layout


@dataclass
class StepResult:
    """One environment step for both arms (rows left, right).

    Attributes:
        obs: (2, obs_size) observations.
        reward: (2,) rewards.
        terminated: success or a physics failure ended the episode.
        truncated: the step limit ended it.
        info: ``is_success``, ``subtask`` (2,) int, ``reward_terms`` (name -> (2,)),
            ``physics_error`` and the per-arm predicates ``reached``, ``grasped``, ``aligned``.
    """

    obs: np.ndarray
    reward: np.ndarray
    terminated: bool
    truncated: bool
    info: dict


@functools.lru_cache(maxsize=8)
def home_posture(config: TaskConfig) -> np.ndarray:
    """Arm joint angles (2, 7) rad with the grip sites at ``config.home_grip``, gripper down.

    Found once by letting the cartesian controller settle from ``REST_POSTURE``.
    """
    model = compiled_model(config.scene, False, "cartesian")
    data = mujoco.MjData(model)
    task = _Indices(model)
    for arm in range(2):
        data.qpos[task.arm_qpos[arm]] = REST_POSTURE[arm]
    hx, hy, hz = config.home_grip
    data.mocap_pos[task.hand_mocap] = [[hx, hy, hz], [hx, -hy, hz]]
    data.ctrl[task.finger_ctrl] = FINGER_OPEN
    mujoco.mj_step(model, data, nstep=600)
    return data.qpos[task.arm_qpos].copy()


class _Indices:
    """Addresses of the task's joints, bodies and actuators in a compiled scene."""

    def __init__(self, model: mujoco.MjModel):
        def jid(name):
            i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
            if i < 0:
                raise ValueError(f"model has no joint {name!r}: build it with dualarm.envs.scene")
            return i

        def aid(name):
            return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name)

        def mocap(name):
            return int(model.body_mocapid[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)])

        self.arm_qpos = np.array([[model.jnt_qposadr[jid(f"{a}_{j}")] for j in BAXTER_JOINT_NAMES]
                                  for a in ARMS])
        self.arm_ctrl = np.array([[aid(f"{a}_{j}_servo") for j in BAXTER_JOINT_NAMES] for a in ARMS])
        fingers = [[f"{a}_gripper_r_finger_joint", f"{a}_gripper_l_finger_joint"] for a in ARMS]
        self.finger_qpos = np.array([[model.jnt_qposadr[jid(n)] for n in pair] for pair in fingers])
        self.finger_dof = np.array([[model.jnt_dofadr[jid(n)] for n in pair] for pair in fingers])
        self.finger_ctrl = np.array([[aid(f"{a}_gripper_gripper_{f}_finger_joint") for f in "rl"]
                                     for a in ARMS])
        box_q = [model.jnt_qposadr[jid(f"{a}_box_joint")] for a in ARMS]
        box_v = [model.jnt_dofadr[jid(f"{a}_box_joint")] for a in ARMS]
        self.box_pos = np.array([[q, q + 1, q + 2] for q in box_q])
        self.box_quat = np.array([[q + 3, q + 4, q + 5, q + 6] for q in box_q])
        self.box_linvel = np.array([[v, v + 1, v + 2] for v in box_v])
        self.box_angvel = np.array([[v + 3, v + 4, v + 5] for v in box_v])
        # One gather per step instead of one per field: per arm, qpos entries
        # [7 joints, 2 fingers, 3 box position, 4 box quaternion] and qvel entries
        # [3 box linear, 3 box angular, 2 fingers].
        self.qpos_gather = np.concatenate([self.arm_qpos, self.finger_qpos, self.box_pos,
                                           self.box_quat], axis=1)
        self.qvel_gather = np.concatenate([self.box_linvel, self.box_angvel, self.finger_dof], axis=1)
        self.grip_site = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE,
                                                     f"{a}_gripper_grip_site") for a in ARMS])
        self.target_mocap = np.array([mocap(f"{a}_target") for a in ARMS])
        self.hand_mocap = (np.array([mocap(f"{a}_hand_target") for a in ARMS])
                           if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "left_hand_target") >= 0
                           else None)


class BaxterReachGraspAlign:
    """Baxter reach-grasp-align with both arms: reset, step, render.

    Args:
        config: the task configuration.
        constraints: the joint-angle constraints of the guide term; required for the
            "single" and "multi" conditions, ignored (must be None) for "none".
        render_size: (height, width) of rendered frames in pixels.

    Actions are (2, 4) in cartesian mode (dx, dy, dz, grip) and (2, 8) in joint mode
    (7 joint deltas, grip), rows left, right, each in [-1, 1]; values outside are
    clipped. grip -1 opens the fingers fully, +1 closes them (a position target).
    """

    def __init__(self, config: TaskConfig = TaskConfig(), constraints: ConstraintSet | None = None,
                 render_size: tuple[int, int] = (480, 640)):
        self.config = config
        if config.condition == "none":
            if constraints is not None:
                raise ValueError("condition 'none' has no guide term: pass constraints=None")
        elif constraints is None:
            raise ValueError(f"condition {config.condition!r} needs constraints=ConstraintSet(...)")
        elif config.condition == "single" and len(constraints.segments) != 1:
            raise ValueError(f"condition 'single' needs a one-segment ConstraintSet, "
                             f"got {len(constraints.segments)} segments")
        self.constraints = constraints
        self.model = compiled_model(config.scene, False, config.control)
        self.data = mujoco.MjData(self.model)
        self.ix = _Indices(self.model)
        self.cartesian = config.control == "cartesian"
        self.action_size = 4 if self.cartesian else 8
        self.layout = observation_layout(config.observes_joint_angles)
        self.obs_size = sum(s.stop - s.start for s in self.layout.values())
        self.home = home_posture(config.with_(control="cartesian"))
        self.render_size = render_size
        self._renderer = None
        self._c0 = np.asarray(config.guide_c0, dtype=float)
        scene = config.scene
        self.table_top = scene.table_height
        self.box_rest_z = scene.table_height + scene.box_half_size
        self._closed_gap = 2 * scene.box_half_size + config.grasp_gap_margin
        self._lifted_z = self.box_rest_z + config.lift_height
        self._align_sq = config.align_threshold ** 2
        self._goal_is_subtask = config.goal == "subtask"
        self._observe_joints = config.observes_joint_angles
        self._workspace_low = np.array([0.25, -0.7, scene.table_height + config.min_grip_height])
        self._workspace_high = np.array([1.1, 0.7, 1.4])
        self._lower = BAXTER_JOINT_LIMITS[:, 0]
        self._upper = BAXTER_JOINT_LIMITS[:, 1]
        self._instability = [int(w) for w in (mujoco.mjtWarning.mjWARN_BADQPOS,
                                               mujoco.mjtWarning.mjWARN_BADQVEL,
                                               mujoco.mjtWarning.mjWARN_BADQACC)]
        self.rng = np.random.default_rng()
        self._needs_reset = True

    # ------------------------------------------------------------------ reset
    def reset(self, seed: int | None = None) -> tuple[np.ndarray, dict]:
        """Start an episode: arms at home, fingers open, boxes and targets drawn at random.

        Args:
            seed: seeds the episode's random placement (None: continue the current stream).

        Returns:
            (obs (2, obs_size), info) as after a step with no reward.
        """
        if seed is not None:
            self.rng = np.random.default_rng(seed)
        c, m, d, ix = self.config, self.model, self.data, self.ix
        mujoco.mj_resetData(m, d)
        d.qpos[ix.arm_qpos] = self.home
        d.qpos[ix.finger_qpos] = FINGER_OPEN
        d.ctrl[ix.finger_ctrl] = FINGER_OPEN
        if not self.cartesian:
            d.ctrl[ix.arm_ctrl] = self.home
        self._joint_command = self.home.copy()

        r = self.rng
        box_x = r.uniform(*c.box_x_range, size=2)
        box_y = r.uniform(*c.box_y_range, size=2) * np.array([1.0, -1.0])
        self.box_start = np.stack([box_x, box_y, np.full(2, self.box_rest_z)], axis=1)
        d.qpos[ix.box_pos] = self.box_start
        d.qpos[ix.box_quat] = [1.0, 0.0, 0.0, 0.0]
        tx = r.uniform(*c.target_x_range)
        ty = r.uniform(*c.target_center_y_range)
        tz = self.box_rest_z + r.uniform(*c.target_height_range)
        s = c.target_half_separation
        self.targets = np.array([[tx, ty + s, tz], [tx, ty - s, tz]])
        d.mocap_pos[ix.target_mocap] = self.targets
        mujoco.mj_kinematics(m, d)
        if self.cartesian:
            d.mocap_pos[ix.hand_mocap] = d.site_xpos[ix.grip_site]
            d.mocap_quat[ix.hand_mocap] = GRIP_DOWN_QUAT
        mujoco.mj_forward(m, d)

        self.steps = 0
        self.reached_once = np.zeros(2, dtype=bool)
        self.grasped_once = np.zeros(2, dtype=bool)
        self.success_paid = False
        self._prev_grip = d.site_xpos[ix.grip_site]
        self._needs_reset = False
        state = self._evaluate(self._prev_grip)
        obs = self._observe(state, np.zeros((2, 3)))
        info = self._info(state, {k: np.zeros(2) for k in ("distance", "guide", "goal", "coordinate")},
                          False)
        return obs, info

    # ------------------------------------------------------------------- step
    def check_action(self, action) -> np.ndarray:
        """Validate and clip an action to (2, action_size) in [-1, 1].

        Raises:
            ValueError: wrong shape, or a NaN/inf value (naming the arm and the index).
        """
        a = np.asarray(action, dtype=np.float64)
        if a.shape != (2, self.action_size):
            raise ValueError(f"action must have shape (2, {self.action_size}) (rows left, right; "
                             f"columns {', '.join(self.action_names())}), got {a.shape}")
        if not math.isfinite(a.sum()):  # cheap test first: NaN and inf propagate through the sum
            bad = np.argwhere(~np.isfinite(a))
            if len(bad):               # (a sum of huge finite values can overflow: those clip)
                arm, index = bad[0]
                raise ValueError(f"action of the {ARMS[arm]} arm has a non-finite value "
                                 f"{a[arm, index]} at index {index} ({self.action_names()[index]})")
        return np.minimum(np.maximum(a, -1.0), 1.0)

    def action_names(self) -> tuple[str, ...]:
        """Names of one arm's action components."""
        if self.cartesian:
            return ("dx", "dy", "dz", "grip")
        return tuple(f"d{j}" for j in BAXTER_JOINT_NAMES) + ("grip",)

    def step(self, action) -> StepResult:
        """Advance one control step (``config.substeps`` physics steps).

        Args:
            action: (2, action_size) in [-1, 1] (clipped), rows left, right.
        """
        if self._needs_reset:
            raise RuntimeError("call reset() before step() (the episode has ended or not begun)")
        a = self.check_action(action)
        c, m, d, ix = self.config, self.model, self.data, self.ix
        grip = self._prev_grip
        if self.cartesian:
            target = grip + c.max_cartesian_step * a[:, :3]
            d.mocap_pos[ix.hand_mocap] = np.minimum(np.maximum(target, self._workspace_low),
                                                    self._workspace_high)
        else:
            command = self._joint_command + c.max_joint_step * a[:, :7]
            self._joint_command = np.minimum(np.maximum(command, self._lower), self._upper)
            d.ctrl[ix.arm_ctrl] = self._joint_command
        d.ctrl[ix.finger_ctrl] = FINGER_OPEN + (0.5 * (a[:, -1:] + 1.0)) * _FINGER_TRAVEL

        warnings_before = self._instability_warnings()
        mujoco.mj_step(m, d, nstep=c.substeps)
        mujoco.mj_kinematics(m, d)  # site positions of the new state (mj_step leaves the old)
        self.steps += 1
        # MuJoCo resets the state itself after a bad qpos/qvel/qacc and warns: count them.
        physics_error = (self._instability_warnings() != warnings_before
                         or not math.isfinite(d.qpos.sum()))

        new_grip = d.site_xpos[ix.grip_site]
        grip_vel = (new_grip - grip) * (1.0 / c.control_period)
        self._prev_grip = new_grip
        state = self._evaluate(new_grip)
        obs = self._observe(state, grip_vel)
        terms = self._reward_terms(state)
        reward = terms["distance"] + terms["guide"] + terms["goal"] + terms["coordinate"]
        if physics_error:
            obs = np.nan_to_num(obs, nan=0.0, posinf=0.0, neginf=0.0)
            reward = np.nan_to_num(reward, nan=0.0)
            terms = {k: np.nan_to_num(v, nan=0.0) for k, v in terms.items()}
        terminated = physics_error or (state["success"] and c.terminate_on_success)
        truncated = (not terminated) and self.steps >= c.max_episode_steps
        if terminated or truncated:
            self._needs_reset = True
        return StepResult(obs, reward, terminated, truncated, self._info(state, terms, physics_error))

    # -------------------------------------------------------------- internals
    def _instability_warnings(self) -> int:
        """How many times MuJoCo has found a bad qpos, qvel or qacc (and reset the state)."""
        w = self.data.warning
        return w[self._instability[0]].number + w[self._instability[1]].number \
            + w[self._instability[2]].number

    def _evaluate(self, grip: np.ndarray) -> dict:
        """Sub-task predicates of both arms from the current state (one gather of qpos)."""
        c, d = self.config, self.data
        qpos = d.qpos[self.ix.qpos_gather]                    # (2, 16)
        box = qpos[:, 9:12]
        rel = box - grip
        to_box = np.sqrt((rel * rel).sum(axis=1))
        gap = _GAP_AT_ZERO + qpos[:, 8] - qpos[:, 7]
        grasped = (to_box < c.grasp_tolerance) & (gap <= self._closed_gap) & (box[:, 2] > self._lifted_z)
        reached = grasped | (to_box < c.reach_threshold)
        off = box - self.targets
        aligned = grasped & ((off * off).sum(axis=1) < self._align_sq)
        subtask = reached.astype(np.int64) + grasped
        return {"grip": grip, "qpos": qpos, "rel": rel, "reached": reached, "grasped": grasped,
                "aligned": aligned, "subtask": subtask, "success": bool(aligned[0] and aligned[1])}

    def _reward_terms(self, state: dict) -> dict[str, np.ndarray]:
        """Eq. 16-18 terms, each (2,): distance, guide, goal (rg1/rg2) and coordinate (rc)."""
        c = self.config
        subtask = state["subtask"]
        if self._goal_is_subtask:
            to_goal = np.where((subtask == 2)[:, None], self.targets - state["grip"], state["rel"])
        else:
            to_goal = self.targets - state["grip"]
        distance = -np.sqrt((to_goal * to_goal).sum(axis=1))
        if self.constraints is not None:
            guide = self.constraints.guide_reward(state["qpos"][:, :7].reshape(14),
                                                  int(subtask[0]), int(subtask[1]), self._c0)
        else:
            guide = np.zeros(2)
        new_reach = state["reached"] & ~self.reached_once
        new_grasp = state["grasped"] & ~self.grasped_once
        self.reached_once |= state["reached"]
        self.grasped_once |= state["grasped"]
        goal_bonus = c.reach_bonus * new_reach + c.grasp_bonus * new_grasp
        if state["success"] and not self.success_paid:
            self.success_paid = True
            coordinate = np.full(2, c.coordinate_bonus)
        else:
            coordinate = np.zeros(2)
        return {"distance": distance, "guide": guide, "goal": goal_bonus, "coordinate": coordinate}

    def _observe(self, state: dict, grip_vel: np.ndarray) -> np.ndarray:
        """Observations (2, obs_size) in the order of ``OBS_LAYOUT``."""
        qpos = state["qpos"]
        qvel = self.data.qvel[self.ix.qvel_gather]             # (2, 8)
        quat = qpos[:, 12:16]
        if quat[0, 0] < 0 or quat[1, 0] < 0:                   # one sign per orientation
            quat = quat * np.where(quat[:, :1] < 0, -1.0, 1.0)
        parts = [state["grip"], qpos[:, :7], qpos[:, 9:12], state["rel"], qpos[:, 7:9], quat,
                 qvel[:, :6], grip_vel, qvel[:, 6:8], self.targets]
        if not self._observe_joints:
            del parts[1]
        return np.concatenate(parts, axis=1)

    def _info(self, state: dict, terms: dict, physics_error: bool) -> dict:
        return {"is_success": state["success"], "subtask": state["subtask"],
                "reached": state["reached"], "grasped": state["grasped"],
                "aligned": state["aligned"], "reward_terms": terms,
                "physics_error": physics_error}

    # ----------------------------------------------------------------- render
    def render(self, camera: str = "front") -> np.ndarray:
        """An RGB frame (height, width, 3) uint8 of the current state from a scene camera."""
        if self._renderer is None:
            from dualarm.envs.rendering import SceneRenderer
            self._renderer = SceneRenderer(self.config.scene, self.config.control, *self.render_size)
        return self._renderer.render(self.data, camera)

    def joint_angles(self) -> np.ndarray:
        """Current Baxter joint angles (14,) rad, left s0..w2 then right s0..w2."""
        return self.data.qpos[self.ix.arm_qpos].reshape(14).copy()

    def close(self) -> None:
        """Free the renderer's GL context, if any."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


SUBTASK_NAMES = SUBTASKS
