"""The compiled Baxter scene's addresses (joints, actuators, sites, mocap bodies, resolved once
after the model loads), the arms' inverse kinematics to grip positions, and the home posture."""

from __future__ import annotations

import functools
import math

import mujoco
import numpy as np

from dualarm.envs.config import TaskConfig
from dualarm.envs.rules import FINGER_OPEN
from dualarm.envs.scene import GRIP_DOWN_QUAT, REST_POSTURE, compiled_model
from dualarm.kinematics import ARMS, BAXTER_JOINT_LIMITS, BAXTER_JOINT_NAMES


def solve_grip_ik(model: mujoco.MjModel, data: mujoco.MjData, ix: "SceneIndices",
                  grip: np.ndarray, iterations: int = 20, tolerance: float = 1e-4) -> float:
    """Set both arms' joints in ``data.qpos`` so that the grip sites reach ``grip`` (2, 3) m
    with the gripper pointing down (``GRIP_DOWN_QUAT``); damped least squares from the
    current joints, within Baxter's joint limits.

    Returns:
        the largest remaining position error (m).
    """
    jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    want, have, inverse, error = np.array(GRIP_DOWN_QUAT), np.zeros(4), np.zeros(4), np.zeros(4)
    rotation = np.zeros(3)
    worst = math.inf
    for _ in range(iterations):
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        worst = 0.0
        for arm in range(2):
            site = ix.grip_site[arm]
            offset = grip[arm] - data.site_xpos[site]
            worst = max(worst, float(np.abs(offset).max()))
            mujoco.mju_mat2Quat(have, data.site_xmat[site])
            mujoco.mju_negQuat(inverse, have)
            mujoco.mju_mulQuat(error, want, inverse)
            mujoco.mju_quat2Vel(rotation, error, 1.0)
            mujoco.mj_jacSite(model, data, jacp, jacr, site)
            jac = np.vstack([jacp[:, ix.arm_dof[arm]], jacr[:, ix.arm_dof[arm]]])   # (6, 7)
            step = jac.T @ np.linalg.solve(jac @ jac.T + 1e-4 * np.eye(6),
                                           np.concatenate([offset, rotation]))
            q = data.qpos[ix.arm_qpos[arm]] + step
            data.qpos[ix.arm_qpos[arm]] = np.clip(q, BAXTER_JOINT_LIMITS[:, 0], BAXTER_JOINT_LIMITS[:, 1])
        if worst < tolerance:
            break
    mujoco.mj_kinematics(model, data)
    return worst


def home_posture(config: TaskConfig) -> np.ndarray:
    """Arm joint angles (2, 7) rad with the grip sites at ``config.home_grip``, gripper down.

    Found once per scene and home position (whatever the control mode or condition) by
    letting the cartesian controller settle from ``REST_POSTURE``.
    """
    return _settled_posture(config.scene, config.home_grip).copy()


@functools.lru_cache(maxsize=8)
def _settled_posture(scene, home_grip: tuple[float, float, float]) -> np.ndarray:
    model = compiled_model(scene, False, "cartesian")
    data = mujoco.MjData(model)
    task = SceneIndices(model)
    for arm in range(2):
        data.qpos[task.arm_qpos[arm]] = REST_POSTURE[arm]
    hx, hy, hz = home_grip
    data.mocap_pos[task.hand_mocap] = [[hx, hy, hz], [hx, -hy, hz]]
    data.ctrl[task.finger_ctrl] = FINGER_OPEN
    mujoco.mj_step(model, data, nstep=600)
    return data.qpos[task.arm_qpos].copy()


class SceneIndices:
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
        self.arm_dof = np.array([[model.jnt_dofadr[jid(f"{a}_{j}")] for j in BAXTER_JOINT_NAMES]
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
