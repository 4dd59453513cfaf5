"""The reach-grasp-align task on the MuJoCo Baxter scene: physics, sub-task states, rewards.

``BaxterBatch`` steps n copies of the task together with plain numpy input and output
(axes: env, arm left/right, ...); ``BaxterReachGraspAlign`` is one copy without the env
axis, which the Gymnasium and PettingZoo environments in ``dualarm.envs.gym_env`` and
``dualarm.envs.pettingzoo_env`` wrap.

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

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from dualarm.constraints.constraint_set import ConstraintSet
from dualarm.envs.config import TaskConfig
from dualarm.envs.model_ids import SceneIndices, home_posture, solve_grip_ik
from dualarm.envs.rules import (FINGER_CLOSED, FINGER_OPEN, GAP_AT_ZERO, GraspRule, UP,
                                finger_targets, observation_layout)
from dualarm.errors import InputError
from dualarm.envs.scene import GRIP_DOWN_QUAT, compiled_model
from dualarm.envs.starts import NORMAL_START, StartDistribution
from dualarm.kinematics import ARMS, BAXTER_JOINT_LIMITS, BAXTER_JOINT_NAMES

#: Height (m) above its box at which the longest approach start ends (``StartDistribution.approach``).
APPROACH_HEIGHT = 0.05


#: Per-arm layout of the state gathered from MuJoCo each step (``qpos_gather``, 16 entries, and
#: ``qvel_gather``, 8): the arm's 7 joints (rad), its 2 finger joints (m), its box's position
#: (m) and orientation (w, x, y, z); the box's linear and angular velocity, the fingers' velocity.
QPOS_JOINTS, QPOS_FINGERS, QPOS_BOX_POS, QPOS_BOX_QUAT = slice(0, 7), slice(7, 9), slice(9, 12), slice(12, 16)
QVEL_BOX, QVEL_FINGERS = slice(0, 6), slice(6, 8)

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


def _one_info(info: dict, i: int) -> dict:
    """Copy ``i``'s entries of a batched info dict (flags as Python bools)."""
    return {"is_success": bool(info["is_success"][i]), "subtask": info["subtask"][i],
            "reached": info["reached"][i], "grasped": info["grasped"][i],
            "aligned": info["aligned"][i],
            "reward_terms": {k: v[i] for k, v in info["reward_terms"].items()},
            "physics_error": bool(info["physics_error"][i])}


class BaxterBatch:
    """``num_envs`` independent copies of the task, stepped together (leading axis: env).

    The physics of each copy runs in its own ``MjData``; everything else (sub-task
    states, rewards, observations) is computed for all copies at once, so the Python cost
    per environment step falls with the batch size (``benchmarks/env_speed.py``).

    Args:
        config: the task configuration.
        constraints: the joint-angle constraints of the guide term; required for the
            "single" and "multi" conditions, must be None for "none".
        num_envs: number of copies.
        render_size: (height, width) of rendered frames in pixels.

        starts: where each arm begins an episode (``dualarm.envs.starts``); the default is the
            task's normal reset, every arm at home. Training curricula only; evaluations use
            the normal reset.

    Actions are (num_envs, 2, 4) in cartesian mode (dx, dy, dz, grip) and (num_envs, 2, 8)
    in joint mode (7 joint deltas, grip), arms in the order left, right, each value in
    [-1, 1]; values outside are clipped. grip -1 opens the fingers fully, +1 closes them.
    """

    def __init__(self, config: TaskConfig = TaskConfig(), constraints: ConstraintSet | None = None,
                 num_envs: int = 1, render_size: tuple[int, int] = (480, 640),
                 starts: StartDistribution = NORMAL_START):
        if num_envs < 1:
            raise ValueError(f"num_envs must be at least 1, got {num_envs}")
        self.config = config
        self.starts = starts
        if config.condition == "none":
            if constraints is not None:
                raise ValueError("condition 'none' has no guide term: pass constraints=None")
        elif constraints is None:
            raise ValueError(f"condition {config.condition!r} needs constraints=ConstraintSet(...)")
        elif config.condition == "single" and len(constraints.segments) != 1:
            raise InputError(f"condition 'single' needs a one-segment ConstraintSet, "
                             f"got {len(constraints.segments)} segments")
        self.constraints = constraints
        self.num_envs = num_envs
        self.model = compiled_model(config.scene, False, config.control)
        self.datas = [mujoco.MjData(self.model) for _ in range(num_envs)]
        self.ix = SceneIndices(self.model)
        self.cartesian = config.control == "cartesian"
        self.action_size = 4 if self.cartesian else 8
        self.layout = observation_layout(config.observes_joint_angles)
        self.obs_size = sum(s.stop - s.start for s in self.layout.values())
        self.home = home_posture(config)
        self.render_size = render_size
        self._renderer = None
        self._c0 = np.asarray(config.guide_c0, dtype=float)
        scene = config.scene
        self.box_rest_z = scene.table_height + scene.box_half_size
        self._rule = GraspRule(config)
        self._goal_is_subtask = config.goal == "subtask"
        self._success_key = {"reach": "reached", "grasp": "grasped", "align": "aligned"}[config.success_at]
        self._observe_joints = config.observes_joint_angles
        self._workspace_low = np.array([config.grip_x_range[0], config.grip_y_range[0],
                                        scene.table_height + config.min_grip_height])
        self._workspace_high = np.array([config.grip_x_range[1], config.grip_y_range[1],
                                         config.grip_max_z])
        self._lower = BAXTER_JOINT_LIMITS[:, 0]
        self._upper = BAXTER_JOINT_LIMITS[:, 1]
        self._instability = [int(w) for w in (mujoco.mjtWarning.mjWARN_BADQPOS,
                                               mujoco.mjtWarning.mjWARN_BADQVEL,
                                               mujoco.mjtWarning.mjWARN_BADQACC)]
        n = num_envs
        self.rngs = [np.random.default_rng() for _ in range(n)]
        self.target_pos = np.zeros((n, 2, 3))       # each arm's target, m
        self.box_start_pos = np.zeros((n, 2, 3))    # each box's start position, m
        self.step_count = np.zeros(n, dtype=np.int64)
        self.reached_once = np.zeros((n, 2), dtype=bool)
        self.grasped_once = np.zeros((n, 2), dtype=bool)
        self.success_paid = np.zeros(n, dtype=bool)
        self.grip_pos = np.zeros((n, 2, 3))         # grip sites after the last step, m
        self.joint_command = np.zeros((n, 2, 7))    # joint mode: servo targets, rad
        self.needs_reset = np.ones(n, dtype=bool)
        self.start_kind = np.zeros((n, 2), dtype=np.int64)  # each arm's start sub-task (0 reach)
        self._qpos = np.zeros((n, 2, 16))
        self._qvel = np.zeros((n, 2, 8))

    # ------------------------------------------------------------------ reset
    def reset_env(self, i: int, seed: int | None = None, placement=None) -> tuple[np.ndarray, dict]:
        """Start an episode in copy ``i``: arms at home, fingers open, boxes and targets at random.

        Args:
            i: which copy.
            seed: seeds the episode's random placement (None: continue the copy's stream).
            placement: boxes and targets to use instead of random ones: anything with
                ``boxes`` and ``targets``, each (2, 3) m, rows left, right (a demonstration's
                ``dualarm.demos.scene.Scene``); the boxes rest on the table at their x, y.

        Returns:
            (obs (2, obs_size), info) of that copy, as after a step with no reward.
        """
        if seed is not None:
            self.rngs[i] = np.random.default_rng(seed)
        c, m, d, ix = self.config, self.model, self.datas[i], self.ix
        mujoco.mj_resetData(m, d)
        d.qpos[ix.arm_qpos] = self.home
        d.qpos[ix.finger_qpos] = FINGER_OPEN
        d.ctrl[ix.finger_ctrl] = FINGER_OPEN
        if not self.cartesian:
            d.ctrl[ix.arm_ctrl] = self.home
        self.joint_command[i] = self.home

        r = self.rngs[i]
        if placement is None:
            box_x = r.uniform(*c.box_x_range, size=2)
            box_y = r.uniform(*c.box_y_range, size=2) * np.array([1.0, -1.0])
            self.box_start_pos[i] = np.stack([box_x, box_y, np.full(2, self.box_rest_z)], axis=1)
            tx = r.uniform(*c.target_x_range)
            ty = r.uniform(*c.target_center_y_range)
            tz = self.box_rest_z + r.uniform(*c.target_height_range)
            s = c.target_half_separation
            self.target_pos[i] = [[tx, ty + s, tz], [tx, ty - s, tz]]
        else:
            boxes = np.array(placement.boxes, dtype=float).reshape(2, 3)
            self.box_start_pos[i] = np.column_stack([boxes[:, :2], np.full(2, self.box_rest_z)])
            self.target_pos[i] = np.array(placement.targets, dtype=float).reshape(2, 3)
        d.qpos[ix.box_pos] = self.box_start_pos[i]
        d.qpos[ix.box_quat] = [1.0, 0.0, 0.0, 0.0]
        d.mocap_pos[ix.target_mocap] = self.target_pos[i]
        mujoco.mj_kinematics(m, d)
        if self.cartesian:
            d.mocap_pos[ix.hand_mocap] = d.site_xpos[ix.grip_site]
            d.mocap_quat[ix.hand_mocap] = GRIP_DOWN_QUAT
        mujoco.mj_forward(m, d)
        # Drawn after the placement, so a seed places boxes and targets the same either way.
        starts = self.starts.draw(r)
        if self.starts.states is not None:
            if starts.any():
                self._start_recorded(i, starts, r)
        elif starts.any() or self.starts.approach:
            self._start_later(i, starts, r)
        self.start_kind[i] = starts

        self.step_count[i] = 0
        self.success_paid[i] = False
        self.grip_pos[i] = d.site_xpos[ix.grip_site]
        self._qpos[i] = d.qpos[ix.qpos_gather]
        self._qvel[i] = d.qvel[ix.qvel_gather]
        self.needs_reset[i] = False
        state = self._evaluate(self.grip_pos[i:i + 1], self._qpos[i:i + 1], self.target_pos[i:i + 1])
        # What an arm holds at the start counts as earned before the episode: rg1 and rg2
        # are not paid for it (at the normal reset neither predicate holds).
        self.reached_once[i] = state["reached"][0]
        self.grasped_once[i] = state["grasped"][0]
        obs = self._observe(state, self._qvel[i:i + 1], np.zeros((1, 2, 3)), self.target_pos[i:i + 1])
        zeros = {k: np.zeros((1, 2)) for k in ("distance", "guide", "goal", "coordinate")}
        return obs[0], _one_info(self._info(state, zeros, np.zeros(1, dtype=bool)), 0)

    def set_start_probs(self, probs) -> None:
        """Change the start probabilities (reach, grasp, align) of the next resets."""
        self.starts = self.starts.with_probs(probs)

    def set_start_states(self, states) -> None:
        """Take later starts from ``states`` (``RecordedStates``; None: placed ones)."""
        self.starts = self.starts.with_states(states)

    def arm_states(self, i: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Copy ``i``'s state as ``RecordedStates`` keeps it: each arm's joints, fingers and box
        pose (2, 16) and finger commands (2, 2)."""
        d, ix = self.datas[i], self.ix
        return d.qpos[ix.qpos_gather].copy(), d.ctrl[ix.finger_ctrl].copy()

    def _start_recorded(self, i: int, starts: np.ndarray, rng: np.random.Generator) -> None:
        """Begin copy ``i`` at a recorded demonstration episode's scene, each arm at a step of it
        where that arm was at its ``starts`` sub-task (``StartDistribution.states``), at rest;
        then the same short settle as placed starts."""
        d, ix = self.datas[i], self.ix
        bank = self.starts.states
        e, steps = bank.draw(rng, starts, self.starts.approach)
        self.box_start_pos[i] = bank.boxes[e]
        self.target_pos[i] = bank.targets[e]
        d.mocap_pos[ix.target_mocap] = self.target_pos[i]
        for arm in range(2):
            d.qpos[ix.qpos_gather[arm]] = bank.qpos[e, steps[arm], arm]
            d.ctrl[ix.finger_ctrl[arm]] = bank.fingers[e, steps[arm], arm]
        d.qvel[:] = 0.0
        self._settle_at_posture(i)

    def _settle_at_posture(self, i: int) -> None:
        """Point copy ``i``'s controllers at its arms' present posture (the hand targets in
        cartesian control, the joint servos' targets in joint control) and run two control
        periods, so that fingers closing on a box take hold before the episode begins."""
        c, m, d, ix = self.config, self.model, self.datas[i], self.ix
        mujoco.mj_kinematics(m, d)
        if self.cartesian:
            d.mocap_pos[ix.hand_mocap] = d.site_xpos[ix.grip_site]
        else:
            d.ctrl[ix.arm_ctrl] = d.qpos[ix.arm_qpos]
            self.joint_command[i] = d.qpos[ix.arm_qpos]
        mujoco.mj_forward(m, d)
        mujoco.mj_step(m, d, nstep=2 * c.substeps)
        mujoco.mj_kinematics(m, d)

    def _start_later(self, i: int, starts: np.ndarray, rng: np.random.Generator) -> None:
        """Put the arms of copy ``i`` whose ``starts`` entry is 1 or 2 at that sub-task.

        grasp (1): the grip site at the resting box's centre, fingers open (reach done).
        align (2): the box lifted to a point a uniform fraction of the way from its start to
        its target (at least ``lift_height`` + 1 cm above its resting height), between
        fingers closing on it (reach and grasp done). The arm's joints come from inverse
        kinematics with the gripper pointing down; a short settle (two control periods)
        lets the fingers take hold. Arms at reach (0) stay at home, or with
        ``starts.approach`` begin a uniform fraction of the way to above their box.
        """
        c, m, d, ix = self.config, self.model, self.datas[i], self.ix
        grip = d.site_xpos[ix.grip_site].copy()               # (2, 3) home grip sites
        box = self.box_start_pos[i].copy()
        for arm in range(2):
            if starts[arm] == 0:
                if self.starts.approach:
                    above = box[arm] + APPROACH_HEIGHT * UP
                    grip[arm] = grip[arm] + rng.uniform() * (above - grip[arm])
                continue
            if starts[arm] == 2:
                p = box[arm] + rng.uniform() * (self.target_pos[i, arm] - box[arm])
                p[2] = max(p[2], self._rule.lifted_z + 0.01)
                box[arm] = p
            grip[arm] = box[arm]
        solve_grip_ik(m, d, ix, grip)
        d.qpos[ix.box_pos] = box
        d.qvel[:] = 0.0
        held = starts == 2
        touching = 0.5 * (2 * c.scene.box_half_size + 0.001 - GAP_AT_ZERO)  # l = -r at contact
        d.qpos[ix.finger_qpos[held]] = np.array([-touching, touching])
        d.ctrl[ix.finger_ctrl[held]] = FINGER_CLOSED
        self._settle_at_posture(i)

    # ------------------------------------------------------------------- step
    def check_actions(self, action) -> np.ndarray:
        """Validate and clip actions to (num_envs, 2, action_size) in [-1, 1].

        Raises:
            ValueError: wrong shape, or a NaN/inf value (naming the arm and the index).
        """
        a = np.asarray(action, dtype=np.float64)
        if a.shape != (self.num_envs, 2, self.action_size):
            raise ValueError(f"actions must have shape ({self.num_envs}, 2, {self.action_size}) "
                             f"(envs, arms left/right, {', '.join(self.action_names())}), "
                             f"got {a.shape}")
        if not math.isfinite(a.sum()):  # cheap test first: NaN and inf propagate through the sum
            bad = np.argwhere(~np.isfinite(a))
            if len(bad):               # (a sum of huge finite values can overflow: those clip)
                env, arm, index = bad[0]
                where = f" in env {env}" if self.num_envs > 1 else ""
                raise ValueError(f"action of the {ARMS[arm]} arm{where} has a non-finite value "
                                 f"{a[env, arm, index]} at index {index} "
                                 f"({self.action_names()[index]})")
        return np.minimum(np.maximum(a, -1.0), 1.0)

    def action_names(self) -> tuple[str, ...]:
        """Names of one arm's action components."""
        if self.cartesian:
            return ("dx", "dy", "dz", "grip")
        return tuple(f"d{j}" for j in BAXTER_JOINT_NAMES) + ("grip",)

    def step_all(self, actions, active: np.ndarray | None = None) -> StepResult:
        """Advance every copy one control step (``config.substeps`` physics steps each).

        Args:
            actions: (num_envs, 2, action_size) in [-1, 1] (clipped).
            active: optional (num_envs,) bool mask: copies that are False are not simulated
                (their episode has ended and waits for a reset); their rows of the result
                are stale and must be ignored. None steps every copy.

        Returns:
            A ``StepResult`` whose fields have a leading env axis: obs (n, 2, obs_size),
            reward (n, 2), terminated and truncated (n,) bool arrays, info values (n, ...).
            Copies that end must be ``reset_env`` before the next ``step_all``.
        """
        if active is None:
            stepped = range(self.num_envs)
            waiting = self.needs_reset
        else:
            active = np.asarray(active, dtype=bool)
            if active.shape != (self.num_envs,):
                raise ValueError(f"active must have shape ({self.num_envs},), got {active.shape}")
            stepped = np.flatnonzero(active).tolist()
            waiting = self.needs_reset & active
        if waiting.any():
            raise RuntimeError(f"reset env {int(np.argmax(waiting))} before stepping "
                               "(its episode has ended or not begun)")
        a = self.check_actions(actions)
        c, m, ix = self.config, self.model, self.ix
        previous_grip = self.grip_pos
        fingers = finger_targets(0.5 * (a[..., -1] + 1.0))                        # (n, 2, 2)
        if self.cartesian:
            commands = np.minimum(np.maximum(previous_grip + c.max_cartesian_step * a[..., :3],
                                             self._workspace_low), self._workspace_high)
        else:
            commands = np.minimum(np.maximum(self.joint_command + c.max_joint_step * a[..., :7],
                                             self._lower), self._upper)
            self.joint_command = commands
        physics_error = np.zeros(self.num_envs, dtype=bool)
        grip = previous_grip.copy() if active is not None else np.empty_like(previous_grip)
        for i in stepped:                    # the only per-copy work: set, step, read
            d = self.datas[i]
            if self.cartesian:
                d.mocap_pos[ix.hand_mocap] = commands[i]
            else:
                d.ctrl[ix.arm_ctrl] = commands[i]
            d.ctrl[ix.finger_ctrl] = fingers[i]
            warnings_before = self._instability_warnings(d)
            mujoco.mj_step(m, d, nstep=c.substeps)
            mujoco.mj_kinematics(m, d)  # site positions of the new state (mj_step leaves the old)
            # MuJoCo resets the state itself after a bad qpos/qvel/qacc and warns: count them.
            physics_error[i] = self._instability_warnings(d) != warnings_before
            self._qpos[i] = d.qpos[ix.qpos_gather]
            self._qvel[i] = d.qvel[ix.qvel_gather]
            grip[i] = d.site_xpos[ix.grip_site]
        if not math.isfinite(self._qpos.sum() + grip.sum()):
            physics_error |= ~np.isfinite(self._qpos).all(axis=(1, 2)) | ~np.isfinite(grip).all(axis=(1, 2))
        if active is None:
            self.step_count += 1
        else:
            self.step_count += active
        self.grip_pos = grip
        grip_vel = (grip - previous_grip) * (1.0 / c.control_period)
        state = self._evaluate(grip, self._qpos, self.target_pos)
        obs = self._observe(state, self._qvel, grip_vel, self.target_pos)
        terms = self._reward_terms(state)
        reward = terms["distance"] + terms["guide"] + terms["goal"] + terms["coordinate"]
        if physics_error.any():
            obs = np.nan_to_num(obs, nan=0.0, posinf=0.0, neginf=0.0)
            reward = np.nan_to_num(reward, nan=0.0)
            terms = {k: np.nan_to_num(v, nan=0.0) for k, v in terms.items()}
        terminated = physics_error | (state["success"] & c.terminate_on_success)
        truncated = ~terminated & (self.step_count >= c.max_episode_steps)
        ended = terminated | truncated
        self.needs_reset |= ended if active is None else ended & active
        return StepResult(obs, reward, terminated, truncated, self._info(state, terms, physics_error))

    # ------------------------------------------------- replaying joint targets
    def grip_sites(self, q: np.ndarray) -> np.ndarray:
        """The grip sites' world positions (T, 2, 3) m for Baxter joint vectors q (T, 14) rad
        (left s0..w2, then right), by the simulator's own forward kinematics."""
        q = np.asarray(q, dtype=float).reshape(-1, 14)
        d = mujoco.MjData(self.model)
        out = np.empty((len(q), 2, 3))
        for t, joints in enumerate(q):
            d.qpos[self.ix.arm_qpos] = joints.reshape(2, 7)
            mujoco.mj_kinematics(self.model, d)
            out[t] = d.site_xpos[self.ix.grip_site]
        return out

    def servo_to(self, i: int, joints: np.ndarray, grip: np.ndarray, seconds: float) -> None:
        """Joint control only: hold copy ``i``'s position servos at ``joints`` (2, 7) rad and
        its fingers at closure ``grip`` (2,) (0 open .. 1 closed) for ``seconds`` of
        simulated time (whole physics steps). For replaying a given joint trajectory."""
        if self.cartesian:
            raise ValueError("servo_to needs a joint-control task (TaskConfig(control='joint'))")
        d, ix = self.datas[i], self.ix
        d.ctrl[ix.arm_ctrl] = np.clip(joints, self._lower, self._upper)
        d.ctrl[ix.finger_ctrl] = finger_targets(np.clip(grip, 0, 1))
        mujoco.mj_step(self.model, d, nstep=max(1, round(seconds / self.model.opt.timestep)))

    def task_state(self, i: int) -> dict:
        """Copy ``i``'s sub-task predicates now: ``reached``, ``grasped``, ``aligned`` (2,) and
        ``success`` (bool), as the task defines them."""
        d, ix = self.datas[i], self.ix
        mujoco.mj_kinematics(self.model, d)      # site positions of the current state
        state = self._evaluate(d.site_xpos[ix.grip_site][None], d.qpos[ix.qpos_gather][None],
                               self.target_pos[i:i + 1])
        return {"reached": state["reached"][0], "grasped": state["grasped"][0],
                "aligned": state["aligned"][0], "success": bool(state["success"][0])}

    # -------------------------------------------------------------- internals
    def _instability_warnings(self, d: mujoco.MjData) -> int:
        """How many times MuJoCo has found a bad qpos, qvel or qacc (and reset the state)."""
        w = d.warning
        return w[self._instability[0]].number + w[self._instability[1]].number \
            + w[self._instability[2]].number

    def _evaluate(self, grip: np.ndarray, qpos: np.ndarray, targets: np.ndarray) -> dict:
        """Sub-task predicates (n, 2) from grip sites (n, 2, 3) and gathered qpos (n, 2, 16)."""
        box = qpos[..., QPOS_BOX_POS]
        rel = box - grip
        to_box, grasped, aligned = self._rule(rel, qpos[..., QPOS_FINGERS], box, targets)
        reached, subtask = self._rule.progress(to_box, grasped)
        state = {"grip": grip, "qpos": qpos, "rel": rel, "targets": targets, "reached": reached,
                 "grasped": grasped, "aligned": aligned, "subtask": subtask}
        done = state[self._success_key]
        state["success"] = done[:, 0] & done[:, 1]
        return state

    def _reward_terms(self, state: dict) -> dict[str, np.ndarray]:
        """Eq. 16-18 terms, each (n, 2): distance, guide, goal (rg1/rg2) and coordinate (rc)."""
        c = self.config
        subtask = state["subtask"]
        to_target = state["targets"] - state["grip"]
        if self._goal_is_subtask:
            to_box = rel = state["rel"]
            if c.reach_funnel > 0:      # during reach, aim above the box until over it
                lift = np.minimum(c.reach_funnel * np.sqrt(rel[..., 0] ** 2 + rel[..., 1] ** 2),
                                  c.reach_funnel_height)
                to_box = rel + np.where(subtask == 0, lift, 0.0)[..., None] * UP
            to_goal = np.where((subtask == 2)[..., None], to_target, to_box)
        else:
            to_goal = to_target
        distance = -np.sqrt((to_goal * to_goal).sum(axis=-1))
        if self.constraints is not None:
            q = state["qpos"][..., QPOS_JOINTS].reshape(-1, 14)
            guide = self.constraints.guide_reward(q, subtask[:, 0], subtask[:, 1], self._c0)
        else:
            guide = np.zeros_like(distance)
        new_reach = state["reached"] & ~self.reached_once
        new_grasp = state["grasped"] & ~self.grasped_once
        self.reached_once |= state["reached"]
        self.grasped_once |= state["grasped"]
        goal_bonus = c.reach_bonus * new_reach + c.grasp_bonus * new_grasp
        pay = state["success"] & ~self.success_paid
        self.success_paid |= pay
        coordinate = np.repeat(np.where(pay, c.coordinate_bonus, 0.0)[:, None], 2, axis=1)
        return {"distance": distance, "guide": guide, "goal": goal_bonus, "coordinate": coordinate}

    def _observe(self, state: dict, qvel: np.ndarray, grip_vel: np.ndarray,
                 targets: np.ndarray) -> np.ndarray:
        """Observations (n, 2, obs_size) in the order of ``OBS_LAYOUT``."""
        qpos = state["qpos"]
        quat = qpos[..., QPOS_BOX_QUAT]
        if (quat[..., 0] < 0).any():                            # one sign per orientation
            quat = quat * np.where(quat[..., :1] < 0, -1.0, 1.0)
        parts = [state["grip"], qpos[..., QPOS_JOINTS], qpos[..., QPOS_BOX_POS], state["rel"],
                 qpos[..., QPOS_FINGERS], quat, qvel[..., QVEL_BOX], grip_vel, qvel[..., QVEL_FINGERS], targets]
        if not self._observe_joints:
            del parts[1]
        return np.concatenate(parts, axis=-1)

    @staticmethod
    def _info(state: dict, terms: dict, physics_error: np.ndarray) -> dict:
        return {"is_success": state["success"], "subtask": state["subtask"],
                "reached": state["reached"], "grasped": state["grasped"],
                "aligned": state["aligned"], "reward_terms": terms,
                "physics_error": physics_error}

    # ----------------------------------------------------------------- render
    def render_env(self, i: int = 0, camera: str = "front") -> np.ndarray:
        """An RGB frame (height, width, 3) uint8 of copy ``i`` from a scene camera."""
        if self._renderer is None:
            from dualarm.envs.rendering import SceneRenderer
            self._renderer = SceneRenderer(self.config.scene, self.config.control, *self.render_size)
        return self._renderer.render(self.datas[i], camera)

    def close(self) -> None:
        """Free the renderer's GL context, if any."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


class BaxterReachGraspAlign(BaxterBatch):
    """One copy of the task, arrays without the env axis: obs (2, obs_size), action (2, A).

    Args:
        config: the task configuration.
        constraints: the joint-angle constraints of the guide term ("single"/"multi").
        render_size: (height, width) of rendered frames in pixels.
    """

    def __init__(self, config: TaskConfig = TaskConfig(), constraints: ConstraintSet | None = None,
                 render_size: tuple[int, int] = (480, 640)):
        super().__init__(config, constraints, 1, render_size)

    @property
    def data(self) -> mujoco.MjData:
        """The copy's MuJoCo state."""
        return self.datas[0]

    @property
    def rng(self) -> np.random.Generator:
        """Random stream of the placements."""
        return self.rngs[0]

    @rng.setter
    def rng(self, generator: np.random.Generator) -> None:
        self.rngs[0] = generator

    @property
    def targets(self) -> np.ndarray:
        """(2, 3) targets of the left and right arm, m."""
        return self.target_pos[0]

    @property
    def box_start(self) -> np.ndarray:
        """(2, 3) start positions of the left and right box, m."""
        return self.box_start_pos[0]

    @property
    def steps(self) -> int:
        """Steps taken in the current episode."""
        return int(self.step_count[0])

    def reset(self, seed: int | None = None, placement=None) -> tuple[np.ndarray, dict]:
        """Start an episode: arms at home, fingers open, boxes and targets drawn at random.

        Args:
            seed: seeds the episode's random placement (None: continue the current stream).
            placement: boxes and targets instead of random ones (see ``reset_env``).

        Returns:
            (obs (2, obs_size), info) as after a step with no reward.
        """
        return self.reset_env(0, seed, placement)

    def check_action(self, action) -> np.ndarray:
        """Validate and clip an action to (2, action_size) in [-1, 1] (ValueError names the arm)."""
        return self.check_actions(self._one_action(action)[None])[0]

    def _one_action(self, action) -> np.ndarray:
        a = np.asarray(action, dtype=np.float64)
        if a.shape != (2, self.action_size):
            raise ValueError(f"action must have shape (2, {self.action_size}) (rows left, right; "
                             f"columns {', '.join(self.action_names())}), got {a.shape}")
        return a

    def step(self, action) -> StepResult:
        """Advance one control step; ``action`` is (2, action_size) in [-1, 1] (clipped)."""
        if self.needs_reset[0]:
            raise RuntimeError("call reset() before step() (the episode has ended or not begun)")
        result = self.step_all(self._one_action(action)[None])
        return StepResult(result.obs[0], result.reward[0], bool(result.terminated[0]),
                          bool(result.truncated[0]), _one_info(result.info, 0))

    def render(self, camera: str = "front") -> np.ndarray:
        """An RGB frame (height, width, 3) uint8 of the current state from a scene camera."""
        return self.render_env(0, camera)

    def joint_angles(self) -> np.ndarray:
        """Current Baxter joint angles (14,) rad, left s0..w2 then right s0..w2."""
        return self.data.qpos[self.ix.arm_qpos].reshape(14).copy()

