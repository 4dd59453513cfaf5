"""Later training starts taken from the recordings' replays (``demos.starts``,
``dualarm.envs.starts.RecordedStates``) instead of placed by the simulator."""

from __future__ import annotations

import os

import dualarm  # noqa: F401  (headless GL before mujoco loads)

import numpy as np
import pytest

from dualarm.demos.formats import DEFAULT_DEMO_DIR
from dualarm.envs.baxter import BaxterBatch
from dualarm.envs.config import TaskConfig
from dualarm.envs.starts import RecordedStates, StartDistribution
from dualarm.errors import InputError
from dualarm.training.config import TrainConfig


@pytest.fixture(scope="module")
def bank():
    """The states of the 10 shipped recordings replayed at their own scenes (condition none)."""
    from dualarm.training.demonstrations import recorded_states, successful_replays

    config = TrainConfig().with_(condition="none", demos={"folder": str(DEFAULT_DEMO_DIR), "episodes": 1})
    replays = successful_replays(config, None)
    for r in replays:                           # the replay keeps a state per step and the reset
        assert r.states["qpos"].shape == (r.steps + 1, 2, 16)
        assert r.states["subtask"][0].tolist() == [0, 0] and r.states["subtask"][-1].tolist() == [2, 2]
    return recorded_states(replays)


def _scene_index(bank: RecordedStates, env: BaxterBatch) -> int:
    """Which of the bank's episodes copy 0 of ``env`` was placed at (-1: none)."""
    for e in range(len(bank)):
        if np.allclose(bank.boxes[e], env.box_start_pos[0]) and np.allclose(bank.targets[e], env.target_pos[0]):
            return e
    return -1


@pytest.mark.parametrize("control", ["cartesian", "joint"])
def test_held_starts_come_from_a_replay_and_keep_the_box(bank, control):
    """Both arms drawn at align: the episode begins at one of the replays' scenes, each arm
    holding its box where it held it during that replay, and keeps it when it holds still."""
    env = BaxterBatch(TaskConfig(control=control), num_envs=1,
                      starts=StartDistribution((0.0, 0.0, 1.0), states=bank))
    hold = np.zeros((1, 2, env.action_size))
    hold[..., -1] = 1.0
    for seed in range(6):
        _, info = env.reset_env(0, seed)
        e = _scene_index(bank, env)
        assert e >= 0
        assert list(info["subtask"]) == [2, 2] and info["grasped"].all()
        box = env.datas[0].qpos[env.ix.box_pos]                          # (2, 3) m
        recorded = bank.qpos[e, :, :, 9:12][bank.subtask[e] == 2]          # boxes while held
        assert min(np.linalg.norm(recorded - box[0], axis=-1).min(),
                   np.linalg.norm(recorded - box[1], axis=-1).min()) < 0.01
        assert (box[:, 2] > env.box_rest_z + 0.005).any()                 # lifted, not placed
        for _ in range(8):
            step = env.step_all(hold)
            assert step.info["grasped"][0].all()
            if step.terminated[0]:
                break


def test_grasp_starts_and_the_normal_reset_with_recorded_states(bank):
    """Drawn at grasp: at the box, reached; both arms drawn at reach: the normal reset at a
    random placement, not one of the replays' scenes."""
    at_box = BaxterBatch(TaskConfig(), num_envs=1, starts=StartDistribution((0.0, 1.0, 0.0), states=bank))
    normal = BaxterBatch(TaskConfig(), num_envs=1, starts=StartDistribution((1.0, 0.0, 0.0), True, bank))
    plain = BaxterBatch(TaskConfig(), num_envs=1)
    for seed in range(5):
        _, info = at_box.reset_env(0, seed)
        assert _scene_index(bank, at_box) >= 0 and list(info["subtask"]) == [1, 1]
        _, info = normal.reset_env(0, seed)
        plain.reset_env(0, seed)
        assert list(info["subtask"]) == [0, 0] and _scene_index(bank, normal) == -1
        np.testing.assert_array_equal(normal.box_start_pos, plain.box_start_pos)
        np.testing.assert_array_equal(normal.datas[0].qpos, plain.datas[0].qpos)


def test_an_arm_drawn_at_reach_begins_at_home_or_along_its_recorded_reach(bank):
    rng = np.random.default_rng(0)
    for approach in (False, True):
        steps = np.array([bank.draw(rng, np.array([0, 2]), approach)[1] for _ in range(50)])
        assert (steps[:, 1] > 0).all()                     # the other arm is past reach
        assert (steps[:, 0] == 0).all() != approach         # at home only without approach


def test_recorded_states_are_checked():
    e, k = 2, 5
    good = dict(boxes=np.zeros((e, 2, 3)), targets=np.zeros((e, 2, 3)), qpos=np.zeros((e, k, 2, 16)),
                fingers=np.zeros((e, k, 2, 2)), subtask=np.tile([0, 1, 2, 2, -1], (e, 2, 1)).transpose(0, 2, 1))
    RecordedStates(**good)
    with pytest.raises(ValueError, match="RecordedStates.qpos"):
        RecordedStates(**{**good, "qpos": np.zeros((e, k, 2, 15))})
    never_held = good["subtask"].copy()
    never_held[1, :, 0] = [0, 1, 1, 1, -1]
    with pytest.raises(ValueError, match="never was at sub-task 2"):
        RecordedStates(**{**good, "subtask": never_held})


def test_demos_starts_is_checked_where_it_is_set():
    with pytest.raises(InputError, match="demos: starts .* give folder too"):
        TrainConfig().with_(demos={"starts": True})
    with pytest.raises(InputError, match=r"demos.starts .* starts.probs other than \(1, 0, 0\)"):
        TrainConfig().with_(demos={"folder": str(DEFAULT_DEMO_DIR), "starts": True},
                            starts={"probs": [1.0, 0.0, 0.0], "curriculum": 0.0, "probe": 0,
                                    "approach": False})


def test_the_recordings_as_start_states_alone_are_checked_and_fill_no_buffer(tmp_path):
    """``demos.buffer: false``: the recordings give the start states only; no demonstration
    rows are drawn or cloned, and without ``starts`` the option is refused."""
    from dualarm.training import Trainer

    folder = str(DEFAULT_DEMO_DIR)
    with pytest.raises(InputError, match="buffer: false leaves the recordings unused"):
        TrainConfig().with_(demos={"folder": folder, "buffer": False})
    config = TrainConfig().with_(demos={"folder": folder, "episodes": 2, "starts": True, "buffer": False},
                                 episodes=4, num_envs=4, eval_every=4, eval_episodes=2)
    assert config.algo.demo_batch_size == 0 and config.algo.bc_weight == 0
    with pytest.raises(InputError, match="demo_batch_size > 0 draws from the demonstration buffer"):
        config.with_(algo=config.algo.with_(demo_batch_size=8))
    trainer = Trainer.start(config, tmp_path / "run")
    try:
        assert trainer.demos is None and len(trainer.vec.batch.starts.states) == 12
    finally:
        trainer.close()


def test_a_run_with_demos_starts_starts_its_training_and_probes_from_the_replays(tmp_path):
    """The trainer gives the replays' states to its training copies and to the curriculum's
    probes; the evaluations keep the normal reset."""
    from dualarm.training import Trainer

    config = TrainConfig().with_(demos={"folder": str(DEFAULT_DEMO_DIR), "episodes": 4, "starts": True},
                                 episodes=16, eval_every=16, eval_episodes=4, num_envs=4,
                                 starts={"probe": 4})
    trainer = Trainer.start(config, tmp_path / "run")
    try:
        states = trainer.vec.batch.starts.states
        assert isinstance(states, RecordedStates) and len(states) == 14     # 10 own + 4 moved
        assert trainer.eval_vec.batch.starts.states is None
        trainer.run()
        probes = trainer.probes.vecs
        assert all(v.batch.starts.states is states for v in probes.values())
    finally:
        trainer.close()


def test_a_run_from_a_config_with_a_relative_demos_folder_resumes_from_anywhere(tmp_path, monkeypatch):
    """A config file names its demonstration folder relative to itself; the run directory
    keeps it as an absolute path, so resuming from another working directory finds it."""
    from dualarm.cli.main import main

    (tmp_path / "cfg").mkdir()
    folder = os.path.relpath(DEFAULT_DEMO_DIR, tmp_path / "cfg")
    (tmp_path / "cfg" / "c.yaml").write_text(
        f"extends: recipe\nnum_envs: 4\neval_every: 4\neval_episodes: 2\n"
        f"demos:\n  folder: {folder}\n  episodes: 1\n  starts: true\n")
    monkeypatch.chdir(tmp_path)
    assert main(["train", "--config", "cfg/c.yaml", "--episodes", "4", "-o", "run"]) == 0
    saved = TrainConfig.load_saved(tmp_path / "run" / "config.yaml")
    assert os.path.isabs(saved.demos.folder) and saved.demos.starts
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    assert main(["train", "--resume", str(tmp_path / "run"), "--episodes", "8"]) == 0
    assert len((tmp_path / "run" / "metrics.csv").read_text().splitlines()) == 9


def test_a_run_directory_keeps_every_path_absolute_but_its_own_files(tmp_path, monkeypatch):
    """``TrainConfig.stored_in``, the one place that writes paths into a run directory: a
    relative path from anywhere becomes absolute, a file inside the directory stays named
    relative to it (so the directory can move), and an absolute path is kept as it is."""
    monkeypatch.chdir(tmp_path)
    root = tmp_path / "run"
    config = TrainConfig().with_(constraints="c/multi.yaml", demos={"folder": "demos"})
    stored = config.stored_in("run")
    assert stored.constraints == str(tmp_path / "c" / "multi.yaml")
    assert stored.demos.folder == str(tmp_path / "demos")
    own = config.with_(constraints=str(root / "constraints.yaml")).stored_in(root)
    assert own.constraints == "constraints.yaml"
    assert os.path.isabs(own.demos.folder) and own.demos == stored.demos
    elsewhere = str(tmp_path / "shared" / "demos")
    assert config.with_(demos={"folder": elsewhere}).stored_in(root).demos.folder == elsewhere


def test_a_run_with_the_shipped_recordings_stopped_and_resumed_repeats_the_whole_run(tmp_path):
    """With the recordings as demonstrations, a run stopped after 4 episodes and resumed to 8
    writes the same metrics (but wall time) as a run of 8 in one go: the replays, the moved
    copies and the normaliser they feed are made again on resume, so they must come out the
    same in every process (numpy's arctan2 once made one recording's joint angles differ in
    the last bit from run to run; docs/benchmarks.md, "Reproducibility")."""
    import csv

    from dualarm.rl.config import DADDPGConfig
    from dualarm.training import resume, train

    algo = DADDPGConfig(hidden=(32, 32), batch_size=32, warmup_steps=100, buffer_size=5000,
                        demo_batch_size=8, bc_weight=1.0, updates_per_step=0.5)
    config = TrainConfig().with_(condition="multi", num_envs=4, episodes=8, eval_every=4,
                                 eval_episodes=2, algo=algo, seed=5,
                                 demos={"folder": str(DEFAULT_DEMO_DIR), "episodes": 2})

    def metrics(run):
        with open(run / "metrics.csv") as f:
            return [{k: v for k, v in row.items() if k != "wall_time_s"} for row in csv.DictReader(f)]

    train(config, tmp_path / "whole", progress=False)
    train(config.with_(episodes=4), tmp_path / "stopped", progress=False)
    resume(tmp_path / "stopped", episodes=8, progress=False)
    assert len(metrics(tmp_path / "whole")) == 8
    assert metrics(tmp_path / "stopped") == metrics(tmp_path / "whole")
