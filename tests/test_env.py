"""The MuJoCo reach-grasp-align task: sub-task states, rewards (Eqs. 16-18), API wrappers,
determinism, rendering, input validation, physics failures and both control modes."""

from __future__ import annotations

import math
import warnings

import dualarm  # noqa: F401  (sets MUJOCO_GL=egl on a headless machine before mujoco loads)

import gymnasium
import mujoco
import numpy as np
import pytest

from dualarm.constraints.constraint_set import ConstraintSet
from dualarm.envs.baxter import BaxterReachGraspAlign, StepResult, home_posture
from dualarm.envs.rules import GAP_AT_ZERO, OBS_LAYOUT, observation_layout
from dualarm.envs.config import TaskConfig
from dualarm.errors import InputError
from dualarm.envs.expert import ScriptedExpert
from dualarm.envs.gym_env import BaxterReachGraspAlignEnv
from dualarm.envs.pettingzoo_env import BaxterParallelEnv
from dualarm.kinematics import BAXTER_JOINT_LIMITS

ZERO = np.zeros((2, 4))
#: Stand still with the fingers fully open (grip 0 would be half closed).
OPEN = np.array([[0.0, 0.0, 0.0, -1.0], [0.0, 0.0, 0.0, -1.0]])
TERMS = ("distance", "guide", "goal", "coordinate")


# --------------------------------------------------------------------------- helpers

def run_expert(env: BaxterReachGraspAlign, expert: ScriptedExpert, seed: int, on_step=None,
               max_steps: int = 1000) -> list[StepResult]:
    """One expert episode; ``on_step(env, result)`` is called right after each step."""
    obs, _ = env.reset(seed=seed)
    results = []
    for _ in range(max_steps):
        result = env.step(expert(obs))
        results.append(result)
        if on_step is not None:
            on_step(env, result)
        obs = result.obs
        if result.terminated or result.truncated:
            break
    return results


def grip_pos(env) -> np.ndarray:
    """Grip-site positions (2, 3) of the current qpos, from kinematics run here on a scratch
    copy (so a stale ``env.data.site_xpos`` would show)."""
    scratch = _SCRATCH.get(id(env.model))
    if scratch is None:
        scratch = _SCRATCH[id(env.model)] = mujoco.MjData(env.model)
    scratch.qpos[:] = env.data.qpos
    scratch.mocap_pos[:] = env.data.mocap_pos
    scratch.mocap_quat[:] = env.data.mocap_quat
    mujoco.mj_kinematics(env.model, scratch)
    return scratch.site_xpos[env.ix.grip_site].copy()


_SCRATCH: dict[int, mujoco.MjData] = {}


def box_pos(env) -> np.ndarray:
    return env.data.qpos[env.ix.box_pos].copy()


def finger_gap(env) -> np.ndarray:
    q = env.data.qpos[env.ix.finger_qpos]
    return GAP_AT_ZERO + q[:, 1] - q[:, 0]


def assert_reward_is_sum_of_terms(result: StepResult) -> None:
    t = result.info["reward_terms"]
    total = t["distance"] + t["guide"] + t["goal"] + t["coordinate"]
    np.testing.assert_allclose(result.reward, total, rtol=0, atol=1e-12)


# --------------------------------------------------------------------------- fixtures

@pytest.fixture(scope="module")
def core():
    env = BaxterReachGraspAlign()
    yield env
    env.close()


@pytest.fixture(scope="module")
def expert():
    return ScriptedExpert()


@pytest.fixture(scope="module")
def core_no_stop():
    """Episodes run to the step limit after success (to see that rc is paid once)."""
    return BaxterReachGraspAlign(TaskConfig(terminate_on_success=False))


@pytest.fixture(scope="module")
def joint_core():
    return BaxterReachGraspAlign(TaskConfig(control="joint"))


# --------------------------------------------------------------------------- sub-task states

@pytest.mark.parametrize("seed", [0, 1, 2, 7, 11])
def test_expert_passes_reach_grasp_align_in_order(core, expert, seed):
    results = run_expert(core, expert, seed)
    subtasks = np.array([r.info["subtask"] for r in results])          # (steps, 2)
    assert subtasks.dtype.kind == "i"
    for arm in range(2):
        seq = subtasks[:, arm]
        assert seq[0] == 0
        steps = np.diff(seq)
        assert np.all((steps == 0) | (steps == 1)), f"arm {arm}: {seq.tolist()}"
        assert set(seq.tolist()) == {0, 1, 2}
        assert seq[-1] == 2
    last = results[-1]
    assert last.terminated and not last.truncated
    assert last.info["is_success"] is True
    assert last.info["physics_error"] is False
    assert not any(r.info["is_success"] for r in results[:-1])   # ends at the first success


@pytest.mark.parametrize("seed", [3, 4])
def test_subtask_predicates_follow_the_physical_state(core, expert, seed):
    """Each step: reached / grasped / aligned / success recomputed from grip, box, fingers."""
    c = core.config
    closed_gap = 2 * c.scene.box_half_size + c.grasp_gap_margin
    lifted_z = c.scene.table_height + c.scene.box_half_size + c.lift_height
    seen = set()

    def check(env, result):
        info = result.info
        grip, box, gap = grip_pos(env), box_pos(env), finger_gap(env)
        to_box = np.linalg.norm(box - grip, axis=1)
        grasped = (to_box < c.grasp_tolerance) & (gap <= closed_gap) & (box[:, 2] > lifted_z)
        reached = grasped | (to_box < c.reach_threshold)
        aligned = grasped & (np.linalg.norm(box - env.targets, axis=1) < c.align_threshold)
        np.testing.assert_array_equal(info["grasped"], grasped)
        np.testing.assert_array_equal(info["reached"], reached)
        np.testing.assert_array_equal(info["aligned"], aligned)
        np.testing.assert_array_equal(info["subtask"], reached.astype(int) + grasped.astype(int))
        assert info["is_success"] == bool(aligned.all())
        seen.update(info["subtask"].tolist())

    results = run_expert(core, expert, seed, check)
    assert seen == {0, 1, 2} and results[-1].info["is_success"]


@pytest.mark.slow
def test_expert_success_rate_over_200_seeds(core, expert):
    successes = sum(bool(run_expert(core, expert, seed)[-1].info["is_success"]) for seed in range(200))
    assert successes >= 190, f"expert solved {successes}/200 episodes"


# --------------------------------------------------------------------------- reward terms

@pytest.mark.parametrize("seed", [0, 5])
def test_distance_term_subtask_goal(core, expert, seed):
    """goal="subtask": grip -> box centre in reach and grasp, grip -> target in align."""
    seen = set()

    def check(env, result):
        grip, box, subtask = grip_pos(env), box_pos(env), result.info["subtask"]
        goal = np.where((subtask == 2)[:, None], env.targets, box)
        expected = -np.linalg.norm(goal - grip, axis=1)
        np.testing.assert_allclose(result.info["reward_terms"]["distance"], expected, rtol=1e-12, atol=1e-12)
        assert_reward_is_sum_of_terms(result)
        seen.update(subtask.tolist())

    run_expert(core, expert, seed, check)
    assert seen == {0, 1, 2}


def test_distance_term_reach_funnel():
    """reach_funnel: during reach the goal sits above the box by slope x horizontal offset
    (at most reach_funnel_height); grasp and align keep their goals."""
    config = TaskConfig(reach_funnel=1.5, reach_funnel_height=0.08)
    env = BaxterReachGraspAlign(config)
    seen, lifted = set(), []

    def check(env, result):
        grip, box, subtask = grip_pos(env), box_pos(env), result.info["subtask"]
        offset = np.linalg.norm((box - grip)[:, :2], axis=1)
        lift = np.where(subtask == 0, np.minimum(1.5 * offset, 0.08), 0.0)
        goal = np.where((subtask == 2)[:, None], env.targets, box + lift[:, None] * [0, 0, 1])
        expected = -np.linalg.norm(goal - grip, axis=1)
        np.testing.assert_allclose(result.info["reward_terms"]["distance"], expected, rtol=1e-12, atol=1e-12)
        seen.update(subtask.tolist())
        lifted.extend(lift.tolist())

    results = run_expert(env, ScriptedExpert(config), 1, check)
    assert seen == {0, 1, 2} and results[-1].info["is_success"]
    assert max(lifted) == pytest.approx(0.08) and 0 < min(x for x in lifted if x > 0) < 0.08
    with pytest.raises(ValueError, match="reach_funnel"):
        TaskConfig(reach_funnel=-1.0)


def test_distance_term_final_goal():
    config = TaskConfig(goal="final")
    env = BaxterReachGraspAlign(config)
    seen = set()

    def check(env, result):
        expected = -np.linalg.norm(env.targets - grip_pos(env), axis=1)
        np.testing.assert_allclose(result.info["reward_terms"]["distance"], expected, rtol=1e-12, atol=1e-12)
        assert_reward_is_sum_of_terms(result)
        seen.update(result.info["subtask"].tolist())

    results = run_expert(env, ScriptedExpert(config), 2, check)
    assert seen == {0, 1, 2} and results[-1].info["is_success"]


def test_reach_bonus_once_on_hand_placed_box_and_drop_returns_to_reach(core):
    """Box put by hand at the open gripper: reach pays rg1 once; the falling box sends the arm
    back to reach; putting it back reaches again without paying again."""
    rg1 = core.config.reach_bonus
    core.reset(seed=0)
    core.data.qpos[core.ix.box_pos[0]] = grip_pos(core)[0]
    mujoco.mj_forward(core.model, core.data)

    first = core.step(OPEN)
    np.testing.assert_array_equal(first.info["subtask"], [1, 0])
    np.testing.assert_array_equal(first.info["reward_terms"]["goal"], [rg1, 0.0])
    np.testing.assert_allclose(first.info["reward_terms"]["distance"][0],
                               -np.linalg.norm(box_pos(core)[0] - grip_pos(core)[0]), rtol=1e-12)
    assert_reward_is_sum_of_terms(first)

    subtasks, goals = [], []
    for _ in range(6):                                     # the box falls out of the open fingers
        r = core.step(OPEN)
        subtasks.append(int(r.info["subtask"][0]))
        goals.append(r.info["reward_terms"]["goal"].copy())
    assert subtasks[-1] == 0, subtasks
    assert np.all(np.array(goals) == 0.0)

    core.data.qpos[core.ix.box_pos[0]] = grip_pos(core)[0]   # put it back in reach
    core.data.qvel[core.ix.box_linvel[0]] = 0.0
    mujoco.mj_forward(core.model, core.data)
    again = core.step(OPEN)
    assert again.info["subtask"][0] == 1
    np.testing.assert_array_equal(again.info["reward_terms"]["goal"], [0.0, 0.0])


def test_boxes_at_targets_without_a_grasp_are_not_a_success(core):
    """Both boxes put by hand on their targets (floating, fingers open): not held, so not
    aligned, no success and no rc; the arms are not even in reach."""
    core.reset(seed=2)
    core.data.qpos[core.ix.box_pos] = core.targets
    mujoco.mj_forward(core.model, core.data)
    r = core.step(OPEN)
    assert np.all(np.linalg.norm(box_pos(core) - core.targets, axis=1) < 0.01)   # still there
    np.testing.assert_array_equal(r.info["aligned"], [False, False])
    np.testing.assert_array_equal(r.info["subtask"], [0, 0])
    assert r.info["is_success"] is False and not r.terminated
    np.testing.assert_array_equal(r.info["reward_terms"]["coordinate"], [0.0, 0.0])
    np.testing.assert_array_equal(r.info["reward_terms"]["goal"], [0.0, 0.0])


def test_goal_and_coordinate_bonuses_paid_once_at_the_transitions(core_no_stop):
    env = core_no_stop
    c = env.config
    results = run_expert(env, ScriptedExpert(c), 3)
    assert results[-1].truncated and not results[-1].terminated
    assert len(results) == c.max_episode_steps
    subtasks = np.array([r.info["subtask"] for r in results])
    goal = np.array([r.info["reward_terms"]["goal"] for r in results])
    coordinate = np.array([r.info["reward_terms"]["coordinate"] for r in results])
    success = np.array([r.info["is_success"] for r in results])
    for arm in range(2):
        seq = subtasks[:, arm]
        reach_step = int(np.argmax(seq >= 1))
        grasp_step = int(np.argmax(seq >= 2))
        assert 0 < reach_step < grasp_step
        expected = np.zeros(len(results))
        expected[reach_step] += c.reach_bonus
        expected[grasp_step] += c.grasp_bonus
        np.testing.assert_array_equal(goal[:, arm], expected)
    first_success = int(np.argmax(success))
    assert success[first_success] and success[first_success:].sum() > 5   # success persists...
    expected_rc = np.zeros((len(results), 2))
    expected_rc[first_success] = c.coordinate_bonus
    np.testing.assert_array_equal(coordinate, expected_rc)                  # ...rc is paid once
    for r in results:
        assert_reward_is_sum_of_terms(r)


def test_success_step_pays_coordinate_bonus_and_terminates(core, expert):
    results = run_expert(core, expert, 8)
    last = results[-1]
    assert last.terminated and last.info["is_success"]
    np.testing.assert_array_equal(last.info["reward_terms"]["coordinate"], [4000.0, 4000.0])
    for r in results[:-1]:
        np.testing.assert_array_equal(r.info["reward_terms"]["coordinate"], [0.0, 0.0])
    total_goal = sum(r.info["reward_terms"]["goal"] for r in results)
    np.testing.assert_array_equal(total_goal, [21.0, 21.0])             # rg1 + rg2 per arm
    assert np.all(last.reward > 4000.0 - 1.0)


def test_reset_info_has_zero_terms(core):
    obs, info = core.reset(seed=1)
    assert obs.shape == (2, core.obs_size)
    for name in TERMS:
        np.testing.assert_array_equal(info["reward_terms"][name], [0.0, 0.0])
    np.testing.assert_array_equal(info["subtask"], [0, 0])
    assert info["is_success"] is False and info["physics_error"] is False


# --------------------------------------------------------------------------- guide term

C0 = (0.01, 0.03, 0.05)   # distinct per sub-task so that a wrong sub-task shows


def _hand_made_constraints() -> ConstraintSet:
    """Reach+grasp and align boxes around the home posture: per arm some joints inside at home,
    some outside, with a different pattern for the two segments and for the two arms."""
    home = home_posture(TaskConfig()).reshape(14)
    inside_rg = np.array([1, 0, 1, 0, 1, 0, 1] + [0, 1, 1, 0, 0, 1, 1], dtype=bool)
    inside_al = np.array([0, 0, 1, 1, 1, 1, 0] + [1, 1, 1, 1, 0, 0, 0], dtype=bool)

    def box(inside, width):
        lower = np.where(inside, home - width, home + width)
        upper = np.where(inside, home + width, home + 3 * width)
        return lower, upper

    return ConstraintSet.from_groups({"reach+grasp": box(inside_rg, 0.15), "align": box(inside_al, 0.4)},
                                     name="hand-made")


@pytest.fixture(scope="module")
def multi_core():
    constraints = _hand_made_constraints()
    return BaxterReachGraspAlign(TaskConfig(condition="multi", guide_c0=C0), constraints)


def test_guide_term_matches_hand_computation(multi_core):
    env = multi_core
    cs = env.constraints
    lower = np.array(cs.lower_by_subtask)      # (3, 14)
    upper = np.array(cs.upper_by_subtask)
    values, subtasks_seen = [], set()

    def check(env, result):
        q = env.joint_angles()
        subtask = result.info["subtask"]
        expected = np.zeros(2)
        for arm in range(2):
            n = int(subtask[arm])
            for k in range(7):
                j = 7 * arm + k
                ok = lower[n, j] <= q[j] <= upper[n, j]
                expected[arm] += C0[n] if ok else -C0[n]
        np.testing.assert_allclose(result.info["reward_terms"]["guide"], expected, rtol=0, atol=1e-12)
        assert_reward_is_sum_of_terms(result)
        values.extend(expected.round(6).tolist())
        subtasks_seen.update(subtask.tolist())

    results = run_expert(env, ScriptedExpert(env.config), 0, check)
    assert results[-1].info["is_success"]
    assert subtasks_seen == {0, 1, 2}
    assert len(set(values)) >= 3, sorted(set(values))   # the bounds do separate joints

    # At home (first step barely moves): the designed pattern, 4 in / 3 out and 4 in / 3 out.
    env.reset(seed=0)
    r = env.step(ZERO)
    np.testing.assert_array_equal(r.info["subtask"], [0, 0])
    np.testing.assert_allclose(r.info["reward_terms"]["guide"], [C0[0] * (4 - 3), C0[0] * (4 - 3)],
                               rtol=0, atol=1e-12)


def test_guide_term_is_zero_without_guidance(core, expert):
    def check(env, result):
        np.testing.assert_array_equal(result.info["reward_terms"]["guide"], [0.0, 0.0])
    run_expert(core, expert, 0, check)


def test_guide_condition_needs_matching_constraints():
    two = _hand_made_constraints()
    one = ConstraintSet.full_range()
    with pytest.raises(ValueError, match="single"):
        BaxterReachGraspAlign(TaskConfig(condition="single"), two)
    with pytest.raises(ValueError, match="multi"):
        BaxterReachGraspAlign(TaskConfig(condition="multi"), None)
    with pytest.raises(ValueError, match="single"):
        BaxterReachGraspAlign(TaskConfig(condition="single"), None)
    with pytest.raises(ValueError, match="none"):
        BaxterReachGraspAlign(TaskConfig(condition="none"), one)
    env = BaxterReachGraspAlign(TaskConfig(condition="single"), one)   # full range: all inside
    env.reset(seed=0)
    r = env.step(ZERO)
    np.testing.assert_allclose(r.info["reward_terms"]["guide"], [7 * 0.01, 7 * 0.01], rtol=0, atol=1e-12)


def test_observation_layout_with_and_without_joint_angles(core, multi_core):
    assert core.obs_size == 29 and multi_core.obs_size == 36
    full = observation_layout(True)
    assert list(full) == [name for name, _ in OBS_LAYOUT]
    assert "joint_angles" not in observation_layout(False)
    for env, expect_joints in ((core, False), (multi_core, True)):
        layout = observation_layout(expect_joints)
        assert max(s.stop for s in layout.values()) == env.obs_size
        obs, _ = env.reset(seed=6)
        for step in range(4):
            assert obs.shape == (2, env.obs_size)
            if expect_joints:
                np.testing.assert_array_equal(obs[:, layout["joint_angles"]], env.joint_angles().reshape(2, 7))
            np.testing.assert_array_equal(obs[:, layout["grip_pos"]], grip_pos(env))
            np.testing.assert_array_equal(obs[:, layout["object_pos"]], box_pos(env))
            np.testing.assert_allclose(obs[:, layout["object_rel_pos"]], box_pos(env) - grip_pos(env),
                                       atol=1e-15)
            np.testing.assert_array_equal(obs[:, layout["target_pos"]], env.targets)
            np.testing.assert_array_equal(obs[:, layout["fingers"]], env.data.qpos[env.ix.finger_qpos])
            np.testing.assert_array_equal(obs[:, layout["object_linvel"]],
                                          env.data.qvel[env.ix.box_linvel])
            action = np.zeros((2, 4))
            action[:, 0] = 1.0                                   # move so the angles change
            before = grip_pos(env)
            obs = env.step(action).obs
            velocity = (grip_pos(env) - before) / env.config.control_period
            np.testing.assert_allclose(obs[:, layout["grip_linvel"]], velocity, rtol=1e-9, atol=1e-9)
            assert np.all(obs[:, layout["grip_linvel"]][:, 0] > 0.2)      # m/s along +x
    # The joint angles in the observation are the arm's own, left then right.
    assert not np.allclose(obs[0, full["joint_angles"]], obs[1, full["joint_angles"]])
    np.testing.assert_array_equal(env.joint_angles()[:7], obs[0, full["joint_angles"]])
    # An explicit request overrides the default.
    assert BaxterReachGraspAlign(TaskConfig(joint_angles_in_obs=True)).obs_size == 36


def test_observed_box_quaternion_has_nonnegative_w(core):
    """One sign per orientation: a box quaternion stored with w < 0 is observed negated."""
    layout = core.layout
    core.reset(seed=0)
    q = np.array([0.6, 0.0, 0.0, 0.8])                      # a yaw of the right box
    core.data.qpos[core.ix.box_quat[1]] = -q
    core.data.qpos[core.ix.box_quat[0]] = q
    mujoco.mj_forward(core.model, core.data)
    obs = core.step(OPEN).obs
    stored = core.data.qpos[core.ix.box_quat]
    assert stored[1, 0] < 0 < stored[0, 0]
    np.testing.assert_array_equal(obs[1, layout["object_quat"]], -stored[1])
    np.testing.assert_array_equal(obs[0, layout["object_quat"]], stored[0])
    np.testing.assert_allclose(np.abs(obs[:, layout["object_quat"]][:, [0, 3]]), [[0.6, 0.8]] * 2, atol=0.02)


# --------------------------------------------------------------------------- API checkers

def test_gymnasium_check_env():
    from gymnasium.utils.env_checker import check_env
    env = gymnasium.make("dualarm/BaxterReachGraspAlign-v0")
    assert isinstance(env.unwrapped, BaxterReachGraspAlignEnv)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*Box observation space (minimum|maximum) value.*")
        check_env(env.unwrapped)
    env.close()


def test_pettingzoo_parallel_api():
    from pettingzoo.test import parallel_api_test
    env = BaxterParallelEnv()
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*(infinity|-inf|inf).*", category=UserWarning)
        parallel_api_test(env, num_cycles=100)
    env.close()


def test_wrappers_agree_with_the_core(core, expert):
    """Gym reward = sum of both arms; PettingZoo per-agent rewards and observations = core rows."""
    gym_env = BaxterReachGraspAlignEnv()
    pz_env = BaxterParallelEnv()
    pz_obs, _ = pz_env.reset(seed=4)
    core_obs, _ = core.reset(seed=4)
    np.testing.assert_array_equal(pz_obs["left"], core_obs[0])
    np.testing.assert_array_equal(pz_obs["right"], core_obs[1])
    gym_obs, _ = gym_env.reset(seed=4)
    assert gym_obs.shape == (2 * core.obs_size,)
    for _ in range(15):
        action = expert(core_obs)
        r = core.step(action)
        pz_obs, pz_rew, _, _, pz_info = pz_env.step({"left": action[0], "right": action[1]})
        np.testing.assert_array_equal(pz_obs["left"], r.obs[0])
        np.testing.assert_array_equal(pz_env.state(), r.obs.reshape(-1))
        assert pz_rew == {"left": r.reward[0], "right": r.reward[1]}
        assert pz_info["right"]["subtask"] == r.info["subtask"][1]
        g_obs, g_rew, _, _, g_info = gym_env.step(expert(gym_obs).reshape(-1).astype(np.float32))
        assert g_rew == pytest.approx(g_info["rewards"]["left"] + g_info["rewards"]["right"], abs=1e-12)
        gym_obs = g_obs
        core_obs = r.obs
    gym_env.close()
    pz_env.close()


# --------------------------------------------------------------------------- determinism

def _rollout(env: BaxterReachGraspAlign, seed: int, actions: np.ndarray):
    obs, _ = env.reset(seed=seed)
    observations, rewards = [obs], []
    for a in actions:
        r = env.step(a)
        observations.append(r.obs)
        rewards.append(r.reward)
        if r.terminated or r.truncated:
            break
    return np.array(observations), np.array(rewards)


def test_same_seed_and_actions_are_bit_identical():
    actions = np.random.default_rng(1234).uniform(-1.0, 1.0, size=(30, 2, 4))
    a_obs, a_rew = _rollout(BaxterReachGraspAlign(), 17, actions)
    b_obs, b_rew = _rollout(BaxterReachGraspAlign(), 17, actions)
    assert len(a_obs) > 10
    assert np.array_equal(a_obs, b_obs) and np.array_equal(a_rew, b_rew)


def test_different_seeds_place_boxes_and_targets_differently(core):
    layout = core.layout
    first, _ = core.reset(seed=0)
    second, _ = core.reset(seed=1)
    again, _ = core.reset(seed=0)
    assert not np.array_equal(first[:, layout["object_pos"]], second[:, layout["object_pos"]])
    assert not np.array_equal(first[:, layout["target_pos"]], second[:, layout["target_pos"]])
    np.testing.assert_array_equal(first, again)
    # Placement inside the configured ranges: left box at +y, right at -y.
    c = core.config
    boxes = []
    for seed in range(20):
        core.reset(seed=seed)
        boxes.append(core.box_start)
    boxes = np.array(boxes)
    assert np.all((boxes[..., 0] >= c.box_x_range[0]) & (boxes[..., 0] <= c.box_x_range[1]))
    assert np.all((boxes[:, 0, 1] >= c.box_y_range[0]) & (boxes[:, 0, 1] <= c.box_y_range[1]))
    assert np.all((-boxes[:, 1, 1] >= c.box_y_range[0]) & (-boxes[:, 1, 1] <= c.box_y_range[1]))


def test_gymnasium_reset_seed_reproduces():
    env = BaxterReachGraspAlignEnv()
    actions = np.random.default_rng(7).uniform(-1, 1, size=(10, 8)).astype(np.float32)

    def episode(seed):
        obs, _ = env.reset(seed=seed)
        out, rew = [obs], []
        for a in actions:
            obs, reward, *_ = env.step(a)
            out.append(obs)
            rew.append(reward)
        return np.array(out), np.array(rew)

    o1, r1 = episode(3)
    o2, r2 = episode(4)
    o3, r3 = episode(3)
    assert np.array_equal(o1, o3) and np.array_equal(r1, r3)
    assert not np.array_equal(o1[0], o2[0])


# --------------------------------------------------------------------------- rendering

def _project(env, camera: str, point: np.ndarray, height: int, width: int) -> tuple[int, int]:
    """Pixel (row, column) of a world point in a scene camera (pinhole, looking along -z)."""
    cam = mujoco.mj_name2id(env.model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
    rot = env.data.cam_xmat[cam].reshape(3, 3)
    p = rot.T @ (point - env.data.cam_xpos[cam])
    f = 0.5 * height / math.tan(math.radians(env.model.cam_fovy[cam]) / 2)
    return int(round(height / 2 - f * p[1] / -p[2])), int(round(width / 2 + f * p[0] / -p[2]))


YELLOW = np.array([0.95, 0.8, 0.05]) * 255


def _yellow_mask(frame: np.ndarray) -> np.ndarray:
    f = frame.astype(float)
    return (f[..., 0] > 120) & (f[..., 1] > 100) & (f[..., 2] < 60) & (f[..., 0] - f[..., 2] > 100)


@pytest.fixture(scope="module")
def render_env():
    env = BaxterReachGraspAlignEnv(render_mode="rgb_array")
    yield env
    env.close()


def test_render_frames_from_both_cameras(render_env):
    env = render_env
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (480, 640, 3) and frame.dtype == np.uint8
    for camera in ("front", "side"):
        frame = env.core.render(camera)
        assert frame.shape == (480, 640, 3) and frame.dtype == np.uint8
        assert frame.std() > 10
        assert len(np.unique(frame.reshape(-1, 3) // 32, axis=0)) >= 8, camera
        assert _yellow_mask(frame).sum() > 30, camera     # the yellow box is in view
    with pytest.raises(ValueError, match="camera"):
        env.core.render("top")
    assert BaxterReachGraspAlignEnv().render() is None


def test_render_shows_the_boxes_where_they_are(render_env):
    core = render_env.core
    core.reset(seed=0)
    h, w = core.render_size
    frame = core.render("front")
    boxes = box_pos(core)
    # Yellow (right arm's) box: the yellow pixels sit around its projected centre.
    ys, xs = np.nonzero(_yellow_mask(frame))
    row, col = _project(core, "front", boxes[1], h, w)
    assert abs(np.median(ys) - row) < 12 and abs(np.median(xs) - col) < 12
    pixel = frame[row, col].astype(float)
    assert np.abs(pixel - YELLOW).max() < 90, pixel
    # Black (left arm's) box: dark at its projection.
    row, col = _project(core, "front", boxes[0], h, w)
    assert frame[row - 2:row + 3, col - 2:col + 3].max() < 60
    # Move the black box by hand: its old place shows the table, the new one is dark.
    new = boxes[0] + np.array([0.0, 0.25, 0.0])
    core.data.qpos[core.ix.box_pos[0]] = new
    mujoco.mj_forward(core.model, core.data)
    moved = core.render("front")
    assert moved[row - 2:row + 3, col - 2:col + 3].min() > 60
    row2, col2 = _project(core, "front", new, h, w)
    assert abs(col2 - col) > 30
    assert moved[row2 - 2:row2 + 3, col2 - 2:col2 + 3].max() < 60


# --------------------------------------------------------------------------- bad actions

@pytest.mark.parametrize("arm, index", [(0, 0), (0, 3), (1, 2)])
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_nonfinite_action_names_the_arm(core, arm, index, bad):
    core.reset(seed=0)
    action = np.zeros((2, 4))
    action[arm, index] = bad
    name = ("left", "right")[arm]
    with pytest.raises(ValueError, match=f"{name} arm"):
        core.step(action)


def test_nonfinite_action_through_the_wrappers_names_the_arm():
    gym_env = BaxterReachGraspAlignEnv()
    gym_env.reset(seed=0)
    action = np.zeros(8, dtype=np.float32)
    action[5] = np.nan                                          # right arm's dy
    with pytest.raises(ValueError, match="right arm"):
        gym_env.step(action)
    pz_env = BaxterParallelEnv()
    pz_env.reset(seed=0)
    with pytest.raises(ValueError, match="left arm"):
        pz_env.step({"left": np.array([0.0, np.inf, 0.0, 0.0]), "right": np.zeros(4)})


def test_wrong_action_shapes_raise():
    core = BaxterReachGraspAlign()
    core.reset(seed=0)
    for shape in [(4,), (8,), (2, 3), (2, 8), (1, 4), (2, 4, 1)]:
        with pytest.raises(ValueError, match="shape"):
            core.step(np.zeros(shape))
    gym_env = BaxterReachGraspAlignEnv()
    gym_env.reset(seed=0)
    for shape in [(2, 4), (4,), (9,)]:
        with pytest.raises(ValueError, match="8"):
            gym_env.step(np.zeros(shape, dtype=np.float32))
    pz_env = BaxterParallelEnv()
    pz_env.reset(seed=0)
    with pytest.raises(ValueError, match="right arm"):
        pz_env.step({"left": np.zeros(4), "right": np.zeros(5)})
    with pytest.raises(ValueError, match="left arm"):
        pz_env.step({"left": np.zeros((2, 4)), "right": np.zeros(4)})
    with pytest.raises(ValueError, match="right arm"):
        pz_env.step({"left": np.zeros(4)})
    with pytest.raises(ValueError, match="left arm"):
        pz_env.step({"right": np.zeros(4)})
    with pytest.raises(ValueError, match="unknown"):
        pz_env.step({"left": np.zeros(4), "right": np.zeros(4), "head": np.zeros(4)})
    # None of the rejected actions advanced the episode.
    assert core.steps == 0 and pz_env.core.steps == 0


def test_out_of_range_actions_are_clipped_bit_for_bit(core):
    def next_state(action):
        core.reset(seed=9)
        r = core.step(action)
        return r.obs.copy(), r.reward.copy(), core.data.qpos.copy(), core.data.qvel.copy()

    big = np.array([[5.0, -7.0, 3.0, 5.0], [-5.0, 2.5, -1e6, -3.0]])
    unit = np.clip(big, -1.0, 1.0)
    a, b = next_state(big), next_state(unit)
    for x, y in zip(a, b):
        assert np.array_equal(x, y)
    c = next_state(np.zeros((2, 4)))
    assert not np.array_equal(a[2], c[2])       # and the action did something
    np.testing.assert_array_equal(core.check_action(big), unit)

    gym_env = BaxterReachGraspAlignEnv()        # the wrapper clips too (float32 in)
    gym_env.reset(seed=9)
    o1 = gym_env.step(big.reshape(-1).astype(np.float32))[0]
    gym_env.reset(seed=9)
    o2 = gym_env.step(unit.reshape(-1).astype(np.float32))[0]
    assert np.array_equal(o1, o2)


def test_huge_finite_action_is_clipped(core):
    huge = np.array([[1e308, 1e308, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]])
    with np.errstate(over="ignore", invalid="ignore"):
        clipped = core.check_action(huge)
    np.testing.assert_array_equal(clipped, np.clip(huge, -1.0, 1.0))


def test_step_after_episode_end_raises(expert):
    fresh = BaxterReachGraspAlign()
    with pytest.raises(RuntimeError, match="reset"):
        fresh.step(ZERO)                                   # never reset
    results = run_expert(fresh, expert, 0)
    assert results[-1].terminated
    with pytest.raises(RuntimeError, match="reset"):
        fresh.step(ZERO)
    # Truncation ends the episode too.
    short = BaxterReachGraspAlign(TaskConfig(max_episode_steps=3))
    short.reset(seed=0)
    flags = [short.step(ZERO) for _ in range(3)]
    assert [(r.terminated, r.truncated) for r in flags] == [(False, False), (False, False), (False, True)]
    with pytest.raises(RuntimeError):
        short.step(ZERO)
    short.reset(seed=0)
    assert not short.step(ZERO).truncated                 # a reset starts over
    # Gymnasium and PettingZoo views.
    gym_env = BaxterReachGraspAlignEnv(max_episode_steps=2)
    gym_env.reset(seed=0)
    gym_env.step(np.zeros(8, dtype=np.float32))
    assert gym_env.step(np.zeros(8, dtype=np.float32))[3] is True
    with pytest.raises(RuntimeError):
        gym_env.step(np.zeros(8, dtype=np.float32))
    pz_env = BaxterParallelEnv(max_episode_steps=1)
    pz_env.reset(seed=0)
    _, _, _, trunc, _ = pz_env.step({"left": np.zeros(4), "right": np.zeros(4)})
    assert trunc == {"left": True, "right": True} and pz_env.agents == []
    with pytest.raises(RuntimeError):
        pz_env.step({"left": np.zeros(4), "right": np.zeros(4)})


# --------------------------------------------------------------------------- physics failures

def _nan_warmstart(env):
    env.data.qacc_warmstart[:] = np.nan


def _huge_velocity(env):
    env.data.qvel[:] = 1e8


def _nan_force(env):
    env.data.qfrc_applied[:] = np.nan


def _check_blowup_is_reported(env, provoke):
    env.reset(seed=0)
    provoke(env)
    r = env.step(ZERO)
    assert r.terminated is True and r.truncated is False
    assert r.info["physics_error"] is True
    assert np.all(np.isfinite(r.obs)) and np.all(np.isfinite(r.reward))
    for name in TERMS:
        assert np.all(np.isfinite(r.info["reward_terms"][name]))
    with pytest.raises(RuntimeError):
        env.step(ZERO)


@pytest.mark.parametrize("provoke", [_nan_warmstart, _huge_velocity, _nan_force])
def test_physics_blowup_ends_the_episode(core, expert, provoke, capfd):
    _check_blowup_is_reported(core, provoke)
    # The next episode is healthy.
    results = run_expert(core, expert, 0)
    assert results[-1].info["is_success"] and not results[-1].info["physics_error"]


def _nan_velocity(env):
    env.data.qvel[:] = np.nan


def _nan_position(env):
    env.data.qpos[env.ix.box_pos[1]] = np.nan


@pytest.mark.parametrize("provoke", [_nan_velocity, _nan_position])
def test_nan_state_ends_the_episode(core, provoke, capfd):
    _check_blowup_is_reported(core, provoke)


# --------------------------------------------------------------------------- control modes

def test_joint_control_moves_the_commanded_joint(joint_core):
    env = joint_core
    assert env.action_size == 8
    assert env.action_names()[-1] == "grip" and env.action_names()[0] == "ds0"
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"\(2, 8\)"):
        env.step(np.zeros((2, 4)))
    for joint, right_joint, sign in [(0, 3, 1.0), (3, 1, -1.0), (5, 6, 1.0)]:
        env.reset(seed=0)
        q0 = env.joint_angles()
        action = np.zeros((2, 8))
        action[0, joint] = sign
        action[1, right_joint] = -sign
        for _ in range(5):
            env.step(action)
        dq = env.joint_angles() - q0
        assert sign * dq[joint] > 0.1, dq
        assert -sign * dq[7 + right_joint] > 0.1, dq
        others = np.delete(np.abs(dq[:7]), joint)
        assert np.abs(dq[joint]) > 3 * others.max(), dq           # that joint, not the others
        q = env.joint_angles().reshape(2, 7)
        assert np.all(q >= BAXTER_JOINT_LIMITS[:, 0] - 1e-3) and np.all(q <= BAXTER_JOINT_LIMITS[:, 1] + 1e-3)


def test_joint_control_stays_within_joint_limits(joint_core):
    env = joint_core
    env.reset(seed=0)
    action = np.zeros((2, 8))
    action[:, 3] = 1.0                                   # e1 towards its upper limit, for 1.5 rad
    action[:, 1] = -1.0                                  # s1 towards its lower limit
    for _ in range(15):
        r = env.step(action)
    q = env.joint_angles().reshape(2, 7)
    upper, lower = BAXTER_JOINT_LIMITS[3, 1], BAXTER_JOINT_LIMITS[1, 0]
    assert np.all(q[:, 3] <= upper + 0.02) and np.all(q[:, 3] > upper - 0.15), q[:, 3]
    assert np.all(q[:, 1] >= lower - 0.02), q[:, 1]
    assert not r.info["physics_error"]
    # The command saturates at the limit (no wind-up): reversing moves the joint at once.
    action[:, 3] = -1.0
    for _ in range(3):
        env.step(action)
    assert np.all(env.joint_angles().reshape(2, 7)[:, 3] < q[:, 3] - 0.05)


def test_joint_control_gripper_closes_and_opens(joint_core):
    env = joint_core
    env.reset(seed=0)
    open_gap = finger_gap(env)
    action = np.zeros((2, 8))
    action[:, 7] = 1.0
    gaps = [open_gap]
    for _ in range(6):
        env.step(action)
        gaps.append(finger_gap(env))
    gaps = np.array(gaps)
    assert np.all(np.diff(gaps, axis=0) < 0)                 # shrinks every step
    assert np.all(gaps[-1] < open_gap - 0.02)
    action[:, 7] = -1.0
    for _ in range(6):
        env.step(action)
    assert np.all(finger_gap(env) > gaps[-1] + 0.02)


@pytest.mark.parametrize("axis, sign", [(0, 1.0), (1, -1.0), (2, 1.0)])
def test_cartesian_action_moves_the_grip_site(core, axis, sign):
    steps = 6
    core.reset(seed=0)
    g0, q0 = grip_pos(core), core.joint_angles()
    action = np.zeros((2, 4))
    action[0, axis] = sign                           # left arm only
    for _ in range(steps):
        r = core.step(action)
        z_axis = core.data.site_xmat[core.ix.grip_site].reshape(2, 3, 3)[:, :, 2]
        tilt = np.degrees(np.arccos(np.clip(-z_axis[:, 2], -1.0, 1.0)))
        assert np.all(tilt < 5.0), tilt                # the gripper keeps pointing down
    moved = grip_pos(core) - g0
    full = steps * core.config.max_cartesian_step
    assert 0.3 * full <= sign * moved[0, axis] <= 1.0 * full, moved
    assert np.all(np.abs(np.delete(moved[0], axis)) < 0.01), moved    # along that axis only
    assert np.all(np.abs(moved[1]) < 0.005), moved                     # the right arm stays
    dq = core.joint_angles() - q0
    assert np.abs(dq[:7]).max() > 0.1                 # the arm's joints really moved
    assert np.abs(dq[7:]).max() < 0.02
    assert not r.info["physics_error"]


def test_cartesian_grip_site_stays_above_the_table(core):
    core.reset(seed=0)
    action = np.zeros((2, 4))
    action[:, 2] = -1.0
    for _ in range(15):
        core.step(action)
    floor = core.config.scene.table_height + core.config.min_grip_height
    z = grip_pos(core)[:, 2]
    assert np.all(z > floor - 0.005) and np.all(z < floor + 0.02), z


def test_cartesian_commands_stay_in_the_configured_workspace():
    """The grip-site workspace comes from TaskConfig: a lower ceiling and a narrower y range
    stop arms that are driven up and outwards."""
    env = BaxterReachGraspAlign(TaskConfig(grip_max_z=1.0, grip_y_range=(-0.3, 0.3)))
    env.reset(seed=0)
    action = np.array([[0.0, 1.0, 1.0, 0.0], [0.0, -1.0, 1.0, 0.0]])   # left up and to +y, right to -y
    for _ in range(15):
        env.step(action)
    p = grip_pos(env)
    assert np.all(p[:, 2] < 1.0 + 0.01) and np.all(p[:, 2] > 0.97), p
    assert p[0, 1] < 0.3 + 0.01 and p[1, 1] > -0.3 - 0.01, p


def test_a_workspace_ceiling_below_the_floor_is_refused():
    with pytest.raises(InputError, match="grip_max_z"):
        TaskConfig(grip_max_z=0.7)
