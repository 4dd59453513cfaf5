"""The task's mirror map (dualarm.envs.mirror) against the physics and the reward."""

import mujoco
import numpy as np
import pytest

from dualarm.constraints.constraint_set import ConstraintSet, default_constraints_path
from dualarm.envs.baxter import BaxterBatch
from dualarm.envs.config import TaskConfig
from dualarm.envs.expert import ScriptedExpert
from dualarm.envs.mirror import JOINT_SIGNS, TaskMirror
from dualarm.envs.starts import StartDistribution
from dualarm.errors import InputError

FLIP = np.array([1.0, -1.0, 1.0])


def mirror_scene(src: BaxterBatch, dst: BaxterBatch) -> None:
    """Put copy 0 of ``dst`` in the mirror image of copy 0 of ``src`` (arms swapped, y -> -y):
    the physical state (joints, fingers, boxes and their velocities, the hands' weld targets,
    the target spheres) and the task's bookkeeping."""
    s, d, ix, m = src.datas[0], dst.datas[0], src.ix, src.model
    swap = [1, 0]
    d.qpos[:] = s.qpos
    d.qvel[:] = s.qvel
    d.qpos[ix.arm_qpos] = s.qpos[ix.arm_qpos][swap] * JOINT_SIGNS
    d.qvel[ix.arm_dof] = s.qvel[ix.arm_dof][swap] * JOINT_SIGNS
    d.qpos[ix.finger_qpos] = -s.qpos[ix.finger_qpos][swap][:, ::-1]
    d.qvel[ix.finger_dof] = -s.qvel[ix.finger_dof][swap][:, ::-1]
    d.ctrl[ix.finger_ctrl] = -s.ctrl[ix.finger_ctrl][swap][:, ::-1]
    d.qpos[ix.box_pos] = s.qpos[ix.box_pos][swap] * FLIP
    d.qpos[ix.box_quat] = s.qpos[ix.box_quat][swap] * [1.0, -1.0, 1.0, -1.0]
    d.qvel[ix.box_linvel] = s.qvel[ix.box_linvel][swap] * FLIP
    d.qvel[ix.box_angvel] = s.qvel[ix.box_angvel][swap] * [-1.0, 1.0, -1.0]
    d.mocap_pos[ix.hand_mocap] = s.mocap_pos[ix.hand_mocap][swap] * FLIP
    d.mocap_pos[ix.target_mocap] = s.mocap_pos[ix.target_mocap][swap] * FLIP
    mujoco.mj_forward(m, d)
    for name in ("target_pos", "box_start_pos", "grip_pos"):
        getattr(dst, name)[0] = getattr(src, name)[0][swap] * FLIP
    for name in ("reached_once", "grasped_once"):
        getattr(dst, name)[0] = getattr(src, name)[0][swap]
    dst.step_count[0], dst.success_paid[0] = src.step_count[0], src.success_paid[0]
    dst._qpos[0] = d.qpos[ix.qpos_gather]
    dst._qvel[0] = d.qvel[ix.qvel_gather]


@pytest.fixture(scope="module")
def multi():
    config = TaskConfig(condition="multi")
    return config, ConstraintSet.load(default_constraints_path("multi"))


#: How close the mirrored scene must stay, by observation field: positions to a millimetre;
#: joint angles to 0.02 rad (the weld fixes the grip, not the elbow's swivel, and the
#: robot model is symmetric only to its meshes' precision); velocities to 5 cm/s, and the
#: box's spin, which the fingers' contacts jolt at the grasp, to 0.5 rad/s.
TOLERANCE = {"grip_pos": 1e-3, "joint_angles": 0.02, "object_pos": 1e-3, "object_rel_pos": 1e-3,
             "fingers": 1e-3, "object_quat": 5e-3, "object_linvel": 0.05, "object_angvel": 0.5,
             "grip_linvel": 0.05, "finger_vel": 0.05, "target_pos": 1e-6}


@pytest.mark.parametrize("starts", [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)],
                         ids=["reset", "at-box", "held"])
def test_a_mirrored_scene_under_mirrored_actions_follows_the_mirrored_trajectory(multi, starts):
    """The map is the physics' symmetry: joint signs, finger order, box orientation and spin,
    velocities. The expert grasps and carries in one scene; the other is driven by the
    mirrors of its actions and must stay the mirror image, contacts and all."""
    config, constraints = multi
    source = BaxterBatch(config, constraints, starts=StartDistribution(starts))
    image = BaxterBatch(config, constraints)
    mirror = TaskMirror(config, constraints)
    expert = ScriptedExpert(config)
    obs, _ = source.reset_env(0, seed=3)
    image.reset_env(0, seed=4)
    mirror_scene(source, image)
    steps, grasped = 0, 0
    for _ in range(config.max_episode_steps):
        action = expert(obs)[None]
        a = source.step_all(action)
        b = image.step_all(mirror.act(action))
        expected = mirror.obs(a.obs)
        for name, columns in mirror.layout.items():
            np.testing.assert_allclose(b.obs[..., columns], expected[..., columns],
                                       atol=TOLERANCE[name], err_msg=f"{name} at step {steps}")
        np.testing.assert_allclose(b.reward, mirror.reward(a.reward, a.obs), atol=1e-3)
        np.testing.assert_array_equal(b.info["grasped"], a.info["grasped"][:, ::-1])
        assert b.terminated[0] == a.terminated[0]
        grasped += int(a.info["grasped"].sum())
        steps += 1
        obs = a.obs[0]
        if a.terminated[0] or a.truncated[0]:
            break
    assert grasped > 0, "the expert never held a box: the test checked no contact"
    assert a.info["is_success"][0] and b.info["is_success"][0], "both scenes end aligned"


def test_the_mirrored_guide_term_is_the_guide_of_the_arm_the_joints_now_belong_to(multi):
    """With constraints that differ between the arms, a mirrored transition is paid the guide
    of the mirrored joints under the other arm's ranges, not the original arm's guide."""
    config, constraints = multi
    env = BaxterBatch(config, constraints, num_envs=1)
    mirror = TaskMirror(config, constraints)
    obs, _ = env.reset_env(0, seed=5)
    rng = np.random.default_rng(0)
    changed = 0
    for _ in range(20):
        step = env.step_all(rng.uniform(-1, 1, (1, 2, 4)))
        own = step.info["reward_terms"]["guide"]                      # (1, 2) as paid
        np.testing.assert_allclose(mirror.guide(step.obs), own)
        mirrored = mirror.reward(step.reward, step.obs)
        expected = step.reward[:, ::-1] - own[:, ::-1] + mirror.guide(mirror.obs(step.obs))
        np.testing.assert_allclose(mirrored, expected)
        changed += int(not np.allclose(mirrored, step.reward[:, ::-1]))
        if step.terminated[0] or step.truncated[0]:
            break
    assert changed > 0, "the two arms' ranges never paid differently: the test shows nothing"


def test_mirroring_twice_is_the_identity_and_none_has_no_guide_to_move():
    config = TaskConfig(condition="none", joint_angles_in_obs=True)
    env = BaxterBatch(config)
    mirror = TaskMirror(config)
    env.reset_env(0, seed=2)
    step = env.step_all(np.random.default_rng(1).uniform(-1, 1, (1, 2, 4)))
    np.testing.assert_array_equal(mirror.obs(mirror.obs(step.obs)), step.obs)
    act = np.random.default_rng(2).uniform(-1, 1, (3, 2, 4))
    np.testing.assert_array_equal(mirror.act(mirror.act(act)), act)
    np.testing.assert_array_equal(mirror.reward(step.reward, step.obs), step.reward[:, ::-1])
    joint = TaskMirror(TaskConfig(control="joint", joint_angles_in_obs=True))
    u = np.random.default_rng(3).uniform(-1, 1, (2, 2, 8))
    np.testing.assert_array_equal(joint.act(u)[:, 0, :7], u[:, 1, :7] * JOINT_SIGNS)


def test_a_guided_condition_without_joint_angles_cannot_be_mirrored(multi):
    _, constraints = multi
    with pytest.raises(InputError, match="joint_angles_in_obs"):
        TaskMirror(TaskConfig(condition="multi", joint_angles_in_obs=False), constraints)
