"""The MuJoCo Baxter model agrees with the project's kinematics and is assembled as documented."""

import mujoco
import numpy as np
import pytest

from dualarm.envs.scene import build_spec, compiled_model, robosuite_assets
from dualarm.errors import DualarmError
from dualarm.kinematics import ARMS, BAXTER_JOINT_LIMITS, BAXTER_JOINT_NAMES, baxter_arm


@pytest.fixture(scope="module")
def joint_model():
    model = compiled_model(visual=False, control="joint")
    return model, mujoco.MjData(model)


@pytest.mark.parametrize("arm", ARMS)
def test_joint_conventions_match_the_dh_chain(joint_model, arm):
    """Same joint vector -> same hand orientation in MuJoCo (robosuite MJCF) and in Table 2's D-H
    chain: zeros, senses and axes of all 7 joints agree, so constraints carry over unchanged."""
    model, data = joint_model
    chain = baxter_arm(arm)
    rng = np.random.default_rng(1)
    hand = model.body(f"{arm}_hand").id
    for _ in range(20):
        q = rng.uniform(BAXTER_JOINT_LIMITS[:, 0], BAXTER_JOINT_LIMITS[:, 1])
        for k, joint in enumerate(BAXTER_JOINT_NAMES):
            data.qpos[model.joint(f"{arm}_{joint}").qposadr[0]] = q[k]
        mujoco.mj_kinematics(model, data)
        dh_rotation = chain.forward(q)[-1, :3, :3]
        np.testing.assert_allclose(dh_rotation.T @ data.xmat[hand].reshape(3, 3), np.eye(3), atol=1e-5)  # MJCF quats have 6 digits


def test_cartesian_and_joint_scenes_differ_only_in_arm_actuation():
    cartesian = compiled_model(visual=False, control="cartesian")
    joint = compiled_model(visual=False, control="joint")
    assert cartesian.nq == joint.nq and cartesian.nv == joint.nv
    assert cartesian.neq == 2 and joint.neq == 0           # the two hand welds
    assert joint.nu == cartesian.nu + 14                    # 7 servos per arm
    for name in ("left_box", "right_box", "left_target", "right_target", "table"):
        assert mujoco.mj_name2id(joint, mujoco.mjtObj.mjOBJ_BODY, name) >= 0


def test_collisions_are_primitives_only():
    model = compiled_model(visual=False, control="cartesian")
    colliding = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
    types = set(model.geom_type[colliding])
    assert int(mujoco.mjtGeom.mjGEOM_MESH) not in types


def test_visual_twin_has_the_same_state_layout():
    physics = compiled_model(visual=False, control="cartesian")
    visual = compiled_model(visual=True, control="cartesian")
    assert visual.nmesh > physics.nmesh == 0
    assert (visual.nq, visual.nv, visual.nmocap, visual.nbody) == \
        (physics.nq, physics.nv, physics.nmocap, physics.nbody)


def test_missing_robosuite_assets_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setenv("DUALARM_ROBOSUITE_ASSETS", str(tmp_path))
    with pytest.raises(DualarmError, match="Baxter model not found"):
        robosuite_assets()
    with pytest.raises(DualarmError):
        build_spec()


def test_unknown_control_mode_is_rejected():
    with pytest.raises(ValueError, match="control must be one of"):
        build_spec(control="torque")


def test_batch_of_copies_equals_separate_environments():
    """BaxterBatch steps n copies at once; each must follow exactly the trajectory of a single
    environment with the same seed and actions, including resets of copies that end."""
    from dualarm.envs.baxter import BaxterBatch, BaxterReachGraspAlign
    from dualarm.envs.config import TaskConfig
    from dualarm.envs.expert import ScriptedExpert

    config = TaskConfig(max_episode_steps=12)
    batch = BaxterBatch(config, num_envs=3)
    singles = [BaxterReachGraspAlign(config) for _ in range(3)]
    expert = ScriptedExpert(config)
    seeds = [5, 6, 7]
    obs = np.stack([batch.reset_env(i, s)[0] for i, s in enumerate(seeds)])
    single_obs = [env.reset(seed=s)[0] for env, s in zip(singles, seeds)]
    assert all(np.array_equal(obs[i], single_obs[i]) for i in range(3))
    rng = np.random.default_rng(0)
    for step in range(30):
        actions = np.stack([expert(o) for o in obs]) + rng.normal(0, 0.3, (3, 2, 4))
        result = batch.step_all(actions)
        for i, env in enumerate(singles):
            one = env.step(actions[i])
            assert np.array_equal(result.obs[i], one.obs)
            assert np.array_equal(result.reward[i], one.reward)
            assert result.terminated[i] == one.terminated and result.truncated[i] == one.truncated
            for name, term in one.info["reward_terms"].items():
                assert np.array_equal(result.info["reward_terms"][name][i], term)
            if one.terminated or one.truncated:
                seed = 100 * step + i
                result.obs[i] = batch.reset_env(i, seed)[0]
                assert np.array_equal(result.obs[i], env.reset(seed=seed)[0])
        obs = result.obs
    with pytest.raises(ValueError, match="shape"):
        batch.step_all(np.zeros((2, 2, 4)))
    bad = np.zeros((3, 2, 4))
    bad[2, 1, 0] = np.nan
    with pytest.raises(ValueError, match="right arm in env 2"):
        batch.step_all(bad)
