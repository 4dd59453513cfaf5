"""The training loop: learning a toy task, determinism, kill and resume, bad checkpoints, NaN."""

import csv
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

from dualarm.envs.point_mass import TwoPointMassEnv
from dualarm.rl import DADDPG, DADDPGConfig
from dualarm.training import TrainConfig, Trainer, TrainingDiverged, resume, train
from dualarm.training.config import RECIPE_ALGO
from dualarm.training.run_dir import CheckpointError, load_checkpoint
from dualarm.training.vector import ParallelEnvVector, seeds_for

ROOT = Path(__file__).resolve().parents[1]

# Plappert's target and L2 settings suit the toy's returns (about -25..10); see docs/training.md.
TOY_ALGO = DADDPGConfig(hidden=(64, 64), batch_size=128, updates_per_step=0.5, tau=0.05,
                        action_l2=1.0, warmup_steps=500, buffer_size=100_000,
                        actor_lr=1e-3, noise_std=0.2, random_eps=0.3)   # Plappert's exploration


def rows(path, drop=("wall_time_s",)):
    with open(path, newline="") as f:
        return [{k: v for k, v in r.items() if k not in drop} for r in csv.DictReader(f)]


@pytest.mark.slow(minutes=0.75)
def test_daddpg_solves_the_two_point_mass_task(tmp_path):
    """Learning is tested by learning: >= 90% evaluation success (50 fixed episodes) after
    600 episodes, about 40 s on one core (seeds 0-3 measured: 1.0, 0.96, 1.0, 1.0); with
    ``stop_at`` the same run ends at its first evaluation that reaches 0.9."""
    config = TrainConfig.paper().with_(condition="none", episodes=600, num_envs=8, eval_every=100,
                         eval_episodes=50, algo=TOY_ALGO, seed=1)
    result = train(config, tmp_path / "run", make_env=TwoPointMassEnv, progress=False)
    assert result.episodes == 600
    assert result.last_eval["success_rate"] >= 0.9, result.last_eval
    evals = rows(tmp_path / "run" / "eval.csv")
    assert float(evals[0]["success_rate"]) < 0.9          # it was not solved before learning
    metrics = rows(tmp_path / "run" / "metrics.csv")
    assert [int(r["episode"]) for r in metrics] == list(range(1, 601))
    assert (tmp_path / "run" / "checkpoints" / "best_policy.pt").exists()
    assert any(p.name.startswith("events.out.tfevents") for p in (tmp_path / "run" / "events").iterdir())
    # stop_at: the same run ends after its first evaluation at 0.9, row for row the run above
    # up to there, and stays ended on resume, whatever the episodes asked for
    first = next(int(r["episode"]) for r in evals if float(r["success_rate"]) >= 0.9)
    assert first < 600
    stopped = train(config.with_(stop_at=0.9), tmp_path / "stop", make_env=TwoPointMassEnv,
                    progress=False)
    assert stopped.stopped and stopped.episodes == first and not result.stopped
    assert rows(tmp_path / "stop" / "metrics.csv") == metrics[:first]
    again = resume(tmp_path / "stop", episodes=900, make_env=TwoPointMassEnv, progress=False)
    assert again.stopped and again.episodes == first
    with pytest.raises(ValueError, match="stop_at .* needs evaluations"):
        config.with_(stop_at=0.9, eval_every=0)


def test_same_seed_gives_identical_baxter_metrics(tmp_path):
    algo = DADDPGConfig(hidden=(32, 32), batch_size=32, warmup_steps=200, buffer_size=5000)
    config = TrainConfig.paper().with_(condition="none", episodes=20, num_envs=4, eval_every=0, algo=algo,
                         task={"max_episode_steps": 20}, seed=7)
    train(config, tmp_path / "a", progress=False)
    train(config, tmp_path / "b", progress=False)
    a, b = rows(tmp_path / "a" / "metrics.csv"), rows(tmp_path / "b" / "metrics.csv")
    assert len(a) == 20 and a == b
    train(config.with_(seed=8), tmp_path / "c", progress=False)
    assert rows(tmp_path / "c" / "metrics.csv") != a


def test_averaged_actors_are_evaluated_beside_without_changing_training(tmp_path, monkeypatch):
    """algo.policy_average: every evaluation also evaluates the averaged actors (eval.csv's
    average_* columns) on the same placements, and the training episodes are exactly those
    of the run without them. eval_actor "average" makes them the run's policy and still
    trains the same episodes: the curriculum's probes act with the online actors."""
    algo = DADDPGConfig(hidden=(32, 32), batch_size=32, warmup_steps=100, buffer_size=5000)
    config = TrainConfig.paper().with_(condition="none", episodes=24, num_envs=4, eval_every=8,
                         eval_episodes=4, algo=algo, task={"max_episode_steps": 20}, seed=5,
                         starts={"probs": (0.2, 0.2, 0.6), "curriculum": 0.5, "probe": 4})
    averaged = config.with_(algo=algo.with_(policy_average=0.05))
    train(config, tmp_path / "plain", progress=False)
    train(averaged, tmp_path / "averaged", progress=False)
    acting, act = [], DADDPG.act

    def recording_act(self, obs, *args, explore=False, actors=None, **kwargs):
        acting.append((explore, actors))
        return act(self, obs, *args, explore=explore, actors=actors, **kwargs)
    monkeypatch.setattr(DADDPG, "act", recording_act)
    train(config.with_(algo=algo.with_(policy_average=0.05, eval_actor="average")),
          tmp_path / "policy", progress=False)
    assert {a for explore, a in acting if not explore} == {None, "online"}  # evaluations, probes
    for run in ("averaged", "policy"):
        assert rows(tmp_path / "plain" / "metrics.csv") == rows(tmp_path / run / "metrics.csv")
    plain, both = rows(tmp_path / "plain" / "eval.csv"), rows(tmp_path / "averaged" / "eval.csv")
    assert len(both) == 3 and "average_success_rate" not in plain[0]
    assert [{k: r[k] for k in plain[0]} for r in both] == plain    # the run's own, unchanged
    returns = [float(r["average_return_mean"]) for r in both]
    assert returns[0] != float(both[0]["return_mean"]) or returns[1] != float(both[1]["return_mean"])
    policy = rows(tmp_path / "policy" / "eval.csv")                 # the averaged actors', as the run's
    assert [(r["success_rate"], r["return_mean"]) for r in policy] == \
        [(r["average_success_rate"], r["average_return_mean"]) for r in both]
    assert "average_success_rate" not in policy[0]
    resume(tmp_path / "averaged", episodes=32, progress=False)      # the wider log resumes
    assert len(rows(tmp_path / "averaged" / "eval.csv")) == 4


KILLED_RUN = textwrap.dedent("""
    import sys
    from dualarm.envs.point_mass import TwoPointMassEnv
    from dualarm.rl import DADDPGConfig
    from dualarm.training import TrainConfig, train
    algo = DADDPGConfig(hidden=(32, 32), batch_size=64, updates_per_step=0.5, warmup_steps=300,
                        buffer_size=50_000)
    config = TrainConfig.paper().with_(condition="none", episodes=160, num_envs=8, eval_every=40,
                         eval_episodes=8, checkpoint_every=16, algo=algo, seed=3)
    train(config, sys.argv[1], make_env=TwoPointMassEnv, progress=False)
""")


def test_sigkill_and_resume_loses_and_duplicates_nothing(tmp_path):
    """A run killed with SIGKILL mid-way and resumed ends with the very episodes (and
    evaluations) of an uninterrupted run."""
    script = tmp_path / "run.py"
    script.write_text(KILLED_RUN)
    killed = tmp_path / "killed"
    proc = subprocess.Popen([sys.executable, str(script), str(killed)])
    metrics = killed / "metrics.csv"
    deadline = time.time() + 120
    while time.time() < deadline and proc.poll() is None:
        if metrics.exists() and len(metrics.read_text().splitlines()) > 1 + 70:
            break
        time.sleep(0.05)
    assert proc.poll() is None, "the run ended before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    done_before = len(rows(metrics))
    assert 70 <= done_before < 160
    checkpoint = load_checkpoint(killed / "checkpoints" / "latest.pt")
    assert checkpoint["counters"]["episodes"] <= done_before

    result = resume(killed, make_env=TwoPointMassEnv, progress=False)
    assert result.episodes == 160

    reference = tmp_path / "reference"
    exec(compile(KILLED_RUN.replace("sys.argv[1]", repr(str(reference))), "ref", "exec"), {})
    resumed = rows(metrics)
    assert [int(r["episode"]) for r in resumed] == list(range(1, 161))
    assert resumed == rows(reference / "metrics.csv")
    assert rows(killed / "eval.csv") == rows(reference / "eval.csv")


def small_toy_config(**changes):
    algo = DADDPGConfig(hidden=(16, 16), batch_size=32, warmup_steps=100, buffer_size=5000)
    base = dict(condition="none", episodes=32, num_envs=8, eval_every=0, checkpoint_every=8,
                algo=algo)
    return TrainConfig.paper().with_(**base).with_(**changes)


def test_resume_extends_a_finished_run(tmp_path):
    train(small_toy_config(), tmp_path / "run", make_env=TwoPointMassEnv, progress=False)
    result = resume(tmp_path / "run", episodes=48, make_env=TwoPointMassEnv, progress=False)
    assert result.episodes == 48
    assert [int(r["episode"]) for r in rows(tmp_path / "run" / "metrics.csv")] == list(range(1, 49))


def test_corrupt_or_foreign_checkpoints_give_clear_errors(tmp_path):
    run = tmp_path / "run"
    train(small_toy_config(), run, make_env=TwoPointMassEnv, progress=False)
    latest = run / "checkpoints" / "latest.pt"
    good = latest.read_bytes()
    latest.write_bytes(good[: len(good) // 2])
    with pytest.raises(CheckpointError, match="latest.pt.*corrupt or truncated"):
        Trainer.resume(run, make_env=TwoPointMassEnv, progress=False)
    latest.write_bytes(b"not a checkpoint at all")
    config_before = (run / "config.yaml").read_text()
    with pytest.raises(CheckpointError, match="latest.pt"):
        Trainer.resume(run, episodes=64, make_env=TwoPointMassEnv, progress=False)
    assert (run / "config.yaml").read_text() == config_before   # a refused resume changes nothing
    torch.save({"format": "something-else"}, latest)
    with pytest.raises(CheckpointError, match="not a dualarm DADDPG checkpoint"):
        Trainer.resume(run, make_env=TwoPointMassEnv, progress=False)
    latest.write_bytes(good)
    config_text = (run / "config.yaml").read_text()
    (run / "config.yaml").write_text(config_text.replace("seed: 0", "seed: 5"))
    with pytest.raises(CheckpointError, match="different settings.*seed"):
        Trainer.resume(run, make_env=TwoPointMassEnv, progress=False)
    with pytest.raises(Exception, match="already holds a run"):
        Trainer.start(small_toy_config(), run, make_env=TwoPointMassEnv, progress=False)


class PoisonedPointMass(TwoPointMassEnv):
    """Rewards turn NaN after 200 steps of this copy."""

    def step(self, actions):
        obs, rew, term, trunc, info = super().step(actions)
        self.total = getattr(self, "total", 0) + 1
        if self.total > 200:
            rew = {a: float("nan") for a in rew}
        return obs, rew, term, trunc, info


def test_nan_loss_stops_the_run_and_keeps_the_last_good_checkpoint(tmp_path):
    run = tmp_path / "run"
    with pytest.raises(TrainingDiverged, match="non-finite loss.*last good checkpoint"):
        train(small_toy_config(episodes=200), run, make_env=PoisonedPointMass, progress=False)
    saved = load_checkpoint(run / "checkpoints" / "latest.pt")
    assert 0 < saved["counters"]["episodes"] < 200
    for p in saved["learner"]["critic"].values():
        assert torch.isfinite(p).all()


class ThreeAgents(TwoPointMassEnv):
    def __init__(self):
        super().__init__()
        self.possible_agents = ["a", "b", "c"]


def test_generic_env_adapter_checks_the_env():
    with pytest.raises(ValueError, match="3 agents.*needs two"):
        ParallelEnvVector(ThreeAgents)
    vec = ParallelEnvVector(TwoPointMassEnv, 2)
    assert vec.obs_sizes == (4, 6) and vec.act_sizes == (2, 2)
    obs = vec.reset(0, 1)
    assert obs.shape == (2, 6) and np.all(obs[0, 4:] == 0)      # left padded to 6


@pytest.mark.slow(minutes=1.5)
def test_daddpg_learns_the_baxter_reach_to_80_percent_without_demonstrations(tmp_path):
    """The reach sub-task (both grip sites within 2 cm of their boxes at the same step, the
    paper's rc = 4000) learned by DADDPG alone, no demonstrations: the recipe's learner
    (``RECIPE_ALGO``: rewards scaled by 1/rc, targets clipped to [-1, 1], twin critics, the
    averaged actors as the policy) at 0.5 updates per step, with hindsight boxes (each arm's
    box relabelled with where its grip site went later in the episode, HER's "future" goals,
    share 0.8). Success on the 32 fixed evaluation placements, best evaluation (what `dualarm
    eval` loads). Measured (2026-12-08, docs/benchmarks.md "A round's batches drawn together"):
    0.8 first at 560, 560, 640, 560, 560 and 640 episodes with seeds 0-5, so the budget is
    1,280. Until then the test ran the paper's plain DDPG with the same scaling: 0.8 within
    1,600 episodes in 5 of 9 seeds, 4 of 9 with another (equally random) order of the replay
    draws, so it passed by seed 0's luck and failed when the draws changed. The run ends at
    its first evaluation at 0.8 (``stop_at``): about a minute on one core."""
    algo = RECIPE_ALGO.with_(updates_per_step=0.5)
    config = TrainConfig.paper().with_(condition="none", episodes=1280, num_envs=16, eval_every=80,
                         eval_episodes=32, replay={"her_share": 0.8}, algo=algo, seed=0,
                         task={"success_at": "reach", "max_episode_steps": 30}, stop_at=0.8)
    train(config, tmp_path / "run", progress=False)
    success = [float(r["success_rate"]) for r in rows(tmp_path / "run" / "eval.csv")]
    assert success[0] == 0.0                                  # it starts unable
    assert max(success) >= 0.8, success


@pytest.mark.paper_scale
def test_daddpg_learns_the_whole_task_without_demonstrations(tmp_path):
    """Reach, grasp and align from the normal reset, the paper's reward and constants, no
    demonstrations: the recipe (``TrainConfig()``; what `dualarm train` and
    `dualarm pipeline` run), condition multi, seed 0, evaluated with its policy (the averaged
    actors) on the 50 fixed placements. Measured with the recipe's earlier 0.25 updates per
    step (docs/recombine-runs, multi-seed0): 0.85 first at 1,920 episodes, 1.00 at 4,000; in
    its 3 x 5 comparison every run reached 0.85 by 2,720 episodes. At 1.0, the recipe since
    2026-12-06, seed 0 reaches 0.85 at 640 (docs/human-demos, section 7); 4,000 episodes are
    about 30 minutes on one core, and whether the run keeps 0.85 that long at 1.0 is what
    this test measures: the last evaluation within 0.1 of the best (issue 14's target)."""
    config = TrainConfig().with_(condition="multi", episodes=4000, seed=0)
    train(config, tmp_path / "run", progress=False)
    success = [float(r["success_rate"]) for r in rows(tmp_path / "run" / "eval.csv")]
    assert success[0] == 0.0                                  # it starts unable
    assert max(success) >= 0.85, success
    assert success[-1] >= max(success) - 0.1, success


def test_daddpg_with_demonstrations_learns_the_baxter_reach_to_80_percent(tmp_path):
    """The reach sub-task (both grip sites within 2 cm of their boxes at the same step) learned
    with 64 episodes of the scripted expert in a demonstration buffer and Q-filtered behaviour
    cloning, on the learner of the test above (rewards scaled by 1/rc, targets clipped to
    [-1, 1], hindsight boxes). Success on the 32 fixed evaluation placements, deterministic
    policy, best evaluation (what `dualarm eval` loads). Measured (docs/training.md, D7):
    0.8 or more by episode 400 in 8 of 8 seeds, about 80 s on one core; the same learner
    without the demonstrations is at 0 and 0.31 at 480 (seeds 0, 1). The earlier settings
    (D6: the approach funnel, no hindsight, unscaled rewards) got there in 2 of 4 seeds on
    one machine and in neither on another."""
    algo = DADDPGConfig(hidden=(128, 128), reward_scale=1 / 4000, q_clip=1.0, action_l2=0.02,
                        demo_batch_size=64, bc_weight=30.0)
    config = TrainConfig.paper().with_(condition="none", episodes=480, num_envs=16, eval_every=80,
                         eval_episodes=32, replay={"her_share": 0.8}, demos={"episodes": 64}, algo=algo,
                         seed=0,
                         task={"success_at": "reach", "max_episode_steps": 30})
    train(config, tmp_path / "run", progress=False)
    success = [float(r["success_rate"]) for r in rows(tmp_path / "run" / "eval.csv")]
    assert success[0] < 0.5                                   # it starts unable
    assert max(success) >= 0.8, success


def demo_config(**changes):
    algo = DADDPGConfig(hidden=(32, 32), batch_size=32, warmup_steps=100, buffer_size=5000,
                        demo_batch_size=16, bc_weight=1.0)
    base = dict(condition="none", episodes=16, num_envs=4, eval_every=0, checkpoint_every=8,
                demos={"episodes": 4}, algo=algo, task={"max_episode_steps": 20, "success_at": "reach"},
                seed=2)
    return TrainConfig.paper().with_(**base).with_(**changes)


def test_demonstrations_are_the_expert_in_the_runs_own_environment():
    """The demonstration buffer holds the scripted expert's actions on the run's task, with
    the rewards that task pays, and different placements from the training episodes."""
    from dualarm.envs.expert import ScriptedExpert
    from dualarm.training.demonstrations import record_expert_demonstrations
    from dualarm.training.vector import make_vector_env

    config = demo_config()
    vec = make_vector_env(config, 4)
    demos = record_expert_demonstrations(config, vec)
    n = len(demos)
    assert 4 <= n <= 4 * 20
    obs, act, rew = (demos.data[k][:n] for k in ("obs", "act", "rew"))
    expert = ScriptedExpert(config.task_config())
    np.testing.assert_allclose(act, np.stack([expert(o) for o in obs]), atol=1e-5)
    assert demos.data["done"][:n].sum() >= 3      # the expert reaches both boxes in 20 steps
    assert rew[:, 0].max() > 0                     # ... and earns the reach bonus
    layout = vec.batch.layout
    demo_boxes = obs[0, :, layout["object_pos"]]
    vec.reset(0, seeds_for(config.seed, 0, 1)[0])  # the run's first training episode
    assert not np.allclose(demo_boxes, vec.batch._qpos[0, :, 9:12])


def test_run_with_demonstrations_resumes_exactly(tmp_path):
    train(demo_config(), tmp_path / "ref", progress=False)
    train(demo_config(episodes=8), tmp_path / "run", progress=False)
    resume(tmp_path / "run", episodes=16, progress=False)
    assert rows(tmp_path / "run" / "metrics.csv") == rows(tmp_path / "ref" / "metrics.csv")
    train(demo_config(demos={"episodes": 0}, algo=DADDPGConfig(hidden=(32, 32), batch_size=32,
                                                         warmup_steps=100, buffer_size=5000)),
          tmp_path / "plain", progress=False)
    assert rows(tmp_path / "plain" / "metrics.csv") != rows(tmp_path / "ref" / "metrics.csv")


def test_demonstration_settings_are_checked():
    with pytest.raises(ValueError, match="demos.episodes"):
        TrainConfig.paper().with_(algo=DADDPGConfig(demo_batch_size=8))
    with pytest.raises(ValueError, match="demos: episodes must be >= 0"):
        TrainConfig.paper().with_(demos={"episodes": -1})
    with pytest.raises(ValueError, match="cartesian control only"):
        TrainConfig.paper().with_(demos={"episodes": 2}, task={"control": "joint"})
    with pytest.raises(Exception, match="custom environment"):
        Trainer.start(small_toy_config(demos={"episodes": 2}), "unused", make_env=TwoPointMassEnv)


def curriculum_config(**changes):
    algo = DADDPGConfig(hidden=(32, 32), batch_size=32, warmup_steps=100, buffer_size=5000,
                        twin_critics=True, target_noise=0.2, reward_scale=0.00025)
    base = dict(condition="none", episodes=16, num_envs=4, eval_every=8, eval_episodes=4,
                checkpoint_every=8, algo=algo, task={"max_episode_steps": 20},
                starts={"probs": (0.4, 0.2, 0.4)}, replay={"her_share": 0.8}, seed=3)
    return TrainConfig.paper().with_(**base).with_(**changes)


def box_offset_obs(config, obs_size, offsets) -> np.ndarray:
    """Observations (B, A, O), zero but for each arm's box-minus-grip offset, offsets (B, A, 3) m."""
    from dualarm.envs.rules import observation_layout

    rel = observation_layout(config.task_config().observes_joint_angles)["object_rel_pos"]
    obs = np.zeros((*np.shape(offsets)[:2], obs_size))
    obs[..., rel] = offsets
    return obs


@pytest.mark.parametrize("moving,probe", [(0.0, 0), (0.5, 0), (0.5, 4)])
def test_run_with_later_starts_and_hindsight_targets_resumes_exactly(tmp_path, moving, probe):
    """Start states (fixed or under the reverse curriculum) and hindsight relabelling draw
    from the run's own seeded streams: a run stopped at episode 8 and resumed gives the
    uninterrupted run's rows; the policy loads."""
    from dualarm.training.policy import load_policy

    config = curriculum_config(starts={"curriculum": moving, "probe": probe})
    train(config, tmp_path / "ref", progress=False)
    train(config.with_(episodes=8), tmp_path / "run", progress=False)
    resume(tmp_path / "run", episodes=16, progress=False)
    ref = rows(tmp_path / "ref" / "metrics.csv")
    assert rows(tmp_path / "run" / "metrics.csv") == ref
    assert max(int(r["subtask_left"]) for r in ref) == 2          # some arms started holding
    assert {r[f"start_{a}"] for r in ref for a in ("left", "right")} == {"0", "1", "2"}
    load_policy(tmp_path / "run")
    assert rows(tmp_path / "run" / "eval.csv", drop=("wall_time_s",)) == \
        rows(tmp_path / "ref" / "eval.csv", drop=("wall_time_s",))


def test_curriculum_probe_measures_the_later_starts_with_the_deterministic_policy(tmp_path):
    """With curriculum_probe the curriculum counts probe episodes only (both arms at the
    boxes, both holding them), made at each evaluation, not the training episodes."""
    config = curriculum_config(starts={"curriculum": 0.5, "probe": 4})
    trainer = Trainer.start(config, tmp_path / "run", progress=False)
    trainer.run()
    trainer.close()
    recent = trainer.curriculum.recent
    assert len(recent[0]) == 0                                    # no training episode counted
    assert len(recent[1]) == len(recent[2]) == 8                  # 2 evaluations x 4 probes
    assert set(trainer.probes.vecs) == {1, 2}
    assert (trainer.probes.vecs[2].starts() == 2).all()
    with pytest.raises(ValueError, match="probe measures the curriculum"):
        curriculum_config(starts={"probe": 4})


def test_far_action_l2_weighs_the_penalty_by_the_distance_to_the_box(tmp_path):
    config = curriculum_config(near_box={"far_action_l2": 0.001, "radius": 0.05}, episodes=8,
                               algo=DADDPGConfig(hidden=(16, 16), action_l2=0.5, batch_size=16,
                                                 warmup_steps=50))
    trainer = Trainer.start(config, tmp_path / "run", progress=False)
    try:
        obs = torch.as_tensor(box_offset_obs(config, trainer.vec.obs_size, [
            [[0.03, 0.0, 0.0]] * 2,                              # 3 cm from the box: near
            [[0.0, 0.04, 0.04]] * 2,                             # 5.7 cm: far
            [[0.0, 0.0, -0.2], [0.0, 0.0, 0.0]]]), dtype=torch.float32)  # left far, right at the box
        w = trainer.updates.shaping.penalty_weight(obs)
        assert w.shape == (3, 2)
        torch.testing.assert_close(w, torch.tensor([[0.5, 0.5], [0.001, 0.001], [0.001, 0.5]]))
        seen = []
        update = trainer.agent.update
        trainer.agent.update = lambda batch, rows=0: seen.append(batch["penalty_weight"]) or update(batch, rows)
        trainer.run()
        assert seen and all(b.shape == (16, 2) for b in seen)
    finally:
        trainer.close()
    with pytest.raises(ValueError, match="near_box: far_action_l2 must be"):
        curriculum_config(near_box={"far_action_l2": -1.0})
    with pytest.raises(ValueError, match="near_box: radius"):
        curriculum_config(near_box={"radius": 0.0})


def exploring_arguments(trainer, name: str) -> list:
    """Run ``trainer`` to its end, recording the keyword argument ``name`` of every exploring
    ``agent.act`` call (None where the loop did not pass it)."""
    seen, act = [], trainer.agent.act

    def spy(obs, rng=None, explore=False, **kw):
        if explore:
            seen.append(kw.get(name))
        return act(obs, rng, explore, **kw)

    trainer.agent.act = spy
    trainer.run()
    return seen


def test_near_random_eps_sets_the_share_of_random_actions_near_the_box(tmp_path):
    config = curriculum_config(near_box={"random_eps": 0.0, "radius": 0.05}, episodes=8,
                               algo=DADDPGConfig(hidden=(16, 16), random_eps=0.3, batch_size=16,
                                                 warmup_steps=50))
    trainer = Trainer.start(config, tmp_path / "run", progress=False)
    try:
        obs = box_offset_obs(config, trainer.vec.obs_size, [
            [[0.03, 0.0, 0.0]] * 2,                              # both near
            [[0.0, 0.0, -0.2], [0.0, 0.0, 0.0]]])                # left far, right at the box
        np.testing.assert_allclose(trainer.exploration.random_eps(obs), [[0.0, 0.0], [0.3, 0.0]])
        explored = exploring_arguments(trainer, "random_eps")
        assert explored and all(e is not None and e.shape == (4, 2) for e in explored)
        assert any((e == 0.0).any() for e in explored) and any((e == 0.3).any() for e in explored)
    finally:
        trainer.close()
    plain = Trainer.start(curriculum_config(episodes=8), tmp_path / "plain", progress=False)
    try:
        assert plain.exploration.random_eps(obs) is None
    finally:
        plain.close()
    with pytest.raises(ValueError, match="near_box: random_eps must be"):
        curriculum_config(near_box={"random_eps": 1.5})


def test_approach_shaping_is_potential_based_on_the_grip_to_box_distance(tmp_path):
    """gamma * phi(s') * (1 - done) - phi(s) with phi = -k * distance, per arm; in the batches
    the learner updates on."""
    config = curriculum_config(shaping={"approach": 2.0}, episodes=8)
    trainer = Trainer.start(config, tmp_path / "run", progress=False)
    try:
        # left 0.5 m from its box, then 0.1 m; right stays 0.2 m away
        obs, nxt = (torch.as_tensor(box_offset_obs(config, trainer.vec.obs_size,
                                                   [[left, [0.2, 0.0, 0.0]]] * 2),
                                    dtype=torch.float32)
                    for left in ([0.0, 0.3, 0.4], [0.0, 0.0, 0.1]))
        done = torch.tensor([0.0, 1.0])
        g = config.algo.gamma
        shaping = trainer.updates.shaping.shaping({"obs": obs, "next_obs": nxt, "done": done})
        torch.testing.assert_close(shaping, torch.tensor(
            [[g * -0.2 + 1.0, g * -0.4 + 0.4], [1.0, 0.4]]))
        seen = []
        update = trainer.agent.update
        trainer.agent.update = lambda batch, demo_rows=0: seen.append(batch) or update(batch, demo_rows)
        trainer.run()
        assert seen and all(b["shaping"].shape == (config.algo.batch_size, 2) for b in seen)
    finally:
        trainer.close()
    with pytest.raises(ValueError, match="shaping: approach must be"):
        curriculum_config(shaping={"approach": -1.0})


def test_a_rounds_batches_are_drawn_together_replay_rows_first_then_demonstration_rows(tmp_path):
    """GradientUpdates.batches: k batches of B replay rows then D demonstration rows each,
    different rows in each, shaping applied to all of them."""
    from dualarm.rl.replay import ReplayBuffer

    config = curriculum_config(shaping={"approach": 2.0}, episodes=8)
    trainer = Trainer.start(config, tmp_path / "run", progress=False)
    try:
        trainer.run()
        buffer = trainer.buffer
        o, u = buffer.data["obs"].shape[-1], buffer.data["act"].shape[-1]
        demos = ReplayBuffer(50, 2, o, u)
        n = 20
        demos.add(np.ones((n, 2, o)), np.full((n, 2, u), 0.5), np.zeros((n, 2)), np.ones((n, 2, o)),
                  np.zeros(n), np.zeros(n))
        trainer.updates.demos = demos
        b = config.algo.batch_size
        batches = trainer.updates.batches(5, 3)
        assert len(batches) == 5
        for batch in batches:
            assert batch["obs"].shape == (b + 3, 2, o) and batch["shaping"].shape == (b + 3, 2)
            assert (batch["act"][b:] == 0.5).all() and not (batch["act"][:b] == 0.5).all(dim=(1, 2)).any()
        assert not torch.equal(batches[0]["obs"][:b], batches[1]["obs"][:b])
    finally:
        trainer.close()


def test_carry_shaping_adds_a_potential_on_the_box_to_target_distance(tmp_path):
    """shaping.carry k: phi gains -k * |target - box| per arm, beside shaping.approach's term;
    a box that does not move adds the constant -(1 - gamma) phi."""
    from dualarm.envs.rules import observation_layout

    config = curriculum_config(shaping={"approach": 2.0, "carry": 3.0}, episodes=8)
    layout = observation_layout(config.task_config().observes_joint_angles)
    trainer = Trainer.start(config, tmp_path / "run", progress=False)
    try:
        obs, nxt = (box_offset_obs(config, trainer.vec.obs_size, [[[0.0, 0.0, 0.1]] * 2])
                    for _ in range(2))                     # both grips 0.1 m from their boxes
        obs[0, :, layout["target_pos"]] = [[0.4, 0.0, 0.0], [0.0, 0.2, 0.0]]
        nxt[0, :, layout["target_pos"]] = [[0.1, 0.0, 0.0], [0.0, 0.2, 0.0]]   # left carried 0.3 m
        batch = {"obs": torch.as_tensor(obs, dtype=torch.float32),
                 "next_obs": torch.as_tensor(nxt, dtype=torch.float32), "done": torch.zeros(1)}
        g = config.algo.gamma
        phi = lambda d_box, d_target: -2.0 * d_box - 3.0 * d_target  # noqa: E731
        torch.testing.assert_close(trainer.updates.shaping.shaping(batch), torch.tensor(
            [[g * phi(0.1, 0.1) - phi(0.1, 0.4), g * phi(0.1, 0.2) - phi(0.1, 0.2)]]))
    finally:
        trainer.close()
    with pytest.raises(ValueError, match="shaping: carry must be"):
        curriculum_config(shaping={"carry": -0.5})


def test_mirror_episodes_stores_each_episode_and_its_mirror_image(tmp_path):
    """With replay.mirror the replay holds every real episode followed by its mirror image
    (dualarm.envs.mirror), guide term recomputed; episodes and returns count the real ones
    only, and a resumed run gives the uninterrupted run's rows."""
    from dualarm.envs.mirror import TaskMirror

    config = curriculum_config(condition="multi", replay={"mirror": True}, episodes=8, eval_every=4,
                               task={"max_episode_steps": 20, "joint_angles_in_obs": True})
    trainer = Trainer.start(config, tmp_path / "ref", progress=False)
    trainer.run()
    trainer.close()
    b = trainer.buffer
    assert len(b) == 2 * trainer.env_steps and trainer.episodes == 8
    mirror = TaskMirror(config.task_config(), config.load_constraints())
    data = {k: v[:len(b)] for k, v in b.data.items()}
    starts = np.flatnonzero(np.r_[True, data["left"][:-1] == 0])   # each stored episode's first row
    assert len(starts) == 16
    moved = 0
    for real, image in zip(starts[0::2], starts[1::2]):
        t = int(data["left"][real]) + 1
        assert image == real + t
        r, m = slice(real, real + t), slice(image, image + t)
        np.testing.assert_allclose(data["obs"][m], mirror.obs(data["obs"][r]))
        np.testing.assert_allclose(data["act"][m], mirror.act(data["act"][r]))
        np.testing.assert_allclose(data["rew"][m], mirror.reward(data["rew"][r], data["next_obs"][r]),
                                   atol=1e-6)
        moved += int(not np.allclose(data["rew"][m], data["rew"][r][:, ::-1]))
    assert moved > 0, "the guide term never differed between the arms"
    train(config.with_(episodes=4), tmp_path / "run", progress=False)
    resume(tmp_path / "run", episodes=8, progress=False)
    assert rows(tmp_path / "run" / "metrics.csv") == rows(tmp_path / "ref" / "metrics.csv")
    with pytest.raises(ValueError, match="joint angles"):
        curriculum_config(condition="multi", replay={"mirror": True},
                          task={"joint_angles_in_obs": False})


def test_curriculum_options_are_checked(tmp_path):
    with pytest.raises(ValueError, match="starts: curriculum must be in"):
        TrainConfig.paper().with_(starts={"probs": (0.2, 0.2, 0.6), "curriculum": 1.5})
    with pytest.raises(ValueError, match="curriculum moves the start states"):
        TrainConfig.paper().with_(starts={"curriculum": 0.5})
    with pytest.raises(ValueError, match="replay: her_share"):
        TrainConfig.paper().with_(replay={"her_share": 1.5})
    with pytest.raises(Exception, match="starts"):
        Trainer.start(small_toy_config(starts={"probs": (0.0, 0.0, 1.0)}), tmp_path / "toy",
                      make_env=TwoPointMassEnv, progress=False)
