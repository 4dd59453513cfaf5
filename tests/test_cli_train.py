"""`dualarm train | eval | play | export` as a user runs them."""

import csv
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from dualarm.cli.main import main

SMALL = {"extends": "paper", "algo": {"hidden": [16, 16], "batch_size": 32, "warmup_steps": 100, "buffer_size": 5000},
         "eval_episodes": 4, "task": {"max_episode_steps": 10}}


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("cli")
    config = root / "small.yaml"
    config.write_text(yaml.safe_dump(SMALL))
    out = root / "run"
    assert main(["train", "--condition", "none", "--episodes", "8", "--num-envs", "4",
                 "--config", str(config), "--out", str(out)]) == 0
    return out


def test_train_writes_the_run_directory(run_dir, capsys):
    saved = yaml.safe_load((run_dir / "config.yaml").read_text())
    assert saved["episodes"] == 8 and saved["algo"]["hidden"] == [16, 16]
    with open(run_dir / "metrics.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["episode"]) for r in rows] == list(range(1, 9))
    assert {"return_left", "return_right", "return_total", "success", "subtask_left",
            "distance_left", "guide_right", "coordinate_left"} <= set(rows[0])
    assert (run_dir / "checkpoints" / "latest.pt").exists()
    assert len((run_dir / "eval.csv").read_text().splitlines()) == 2


def test_resume_continues_and_refuses_a_second_start(run_dir, tmp_path, capsys):
    run_dir = Path(shutil.copytree(run_dir, tmp_path / "run"))   # the module's run stays at 8 episodes
    assert main(["train", "--resume", str(run_dir), "--episodes", "12"]) == 0
    with open(run_dir / "metrics.csv", newline="") as f:
        assert [int(r["episode"]) for r in csv.DictReader(f)] == list(range(1, 13))
    capsys.readouterr()
    assert main(["train", "--condition", "none", "--out", str(run_dir)]) == 2
    assert "already holds a run" in capsys.readouterr().err


def test_eval_prints_success_and_return(run_dir, capsys):
    assert main(["eval", str(run_dir), "--episodes", "3"]) == 0
    out = capsys.readouterr().out
    assert "success rate" in out and "/3)" in out and "starting at" not in out


def test_eval_with_the_target_actors_acts_with_the_latest_checkpoints_averages(tmp_path, capsys):
    """--actor target evaluates the Polyak-averaged actors of the latest checkpoint, which
    after training differ from the actors themselves."""
    import torch

    from dualarm.training.policy import load_learner, load_target_policy

    config = tmp_path / "small.yaml"
    config.write_text(yaml.safe_dump({**SMALL, "algo": {**SMALL["algo"], "warmup_steps": 20}}))
    run_dir = tmp_path / "run"
    assert main(["train", "--condition", "none", "--episodes", "16", "--num-envs", "4",
                 "--config", str(config), "--out", str(run_dir)]) == 0
    _, learner, _ = load_learner(run_dir)
    assert learner.updates > 0
    _, target, info = load_target_policy(run_dir)
    assert info["checkpoint"].name == "latest.pt"
    for mine, theirs in zip(target.actor.parameters(), learner.actor_target.parameters()):
        assert torch.equal(mine, theirs)
    assert not all(torch.equal(a, b) for a, b in zip(learner.actor_target.parameters(),
                                                     learner.actor.parameters()))
    obs = np.random.default_rng(0).normal(size=(3, 2, learner.obs_size))
    normalized = learner.normalizer.normalize(torch.as_tensor(obs, dtype=torch.float32))  # (N, A, O)
    averaged = learner.actor_target(normalized.transpose(0, 1)).transpose(0, 1)           # (N, A, U)
    assert np.allclose(target.act(obs), averaged.detach().numpy() * learner.action_mask[:, 0].numpy(),
                       atol=1e-6)
    assert main(["eval", str(run_dir), "--episodes", "3", "--actor", "target"]) == 0
    out = capsys.readouterr().out
    assert "latest.pt" in out and "target actors" in out and "/3)" in out

    # a run whose own policy is the target actors acts with them from every checkpoint
    # unless told otherwise; the online actors then come from the latest checkpoint
    from dualarm.training.policy import load_actors, load_policy
    (run_dir / "config.yaml").write_text((run_dir / "config.yaml").read_text()
                                         .replace("eval_actor: online", "eval_actor: target"))
    for which in ("latest", "best"):
        _, own, info = load_actors(run_dir, which)
        assert info["actors"] == "target"
    _, own, _ = load_policy(run_dir, "latest")
    assert np.allclose(own.act(obs), target.act(obs), atol=1e-6)
    _, online, info = load_actors(run_dir, "best", "online")
    assert info["checkpoint"].name == "latest.pt" and info["actors"] == "online"
    own_actors = learner.actor(normalized.transpose(0, 1)).transpose(0, 1)
    assert np.allclose(online.act(obs), own_actors.detach().numpy() * learner.action_mask[:, 0].numpy(),
                       atol=1e-6)
    assert not np.allclose(online.act(obs), target.act(obs), atol=1e-4)


def test_eval_from_later_starts_puts_both_arms_there(run_dir, capsys, monkeypatch):
    """--start align: every evaluation episode begins with both arms holding their boxes;
    several starts give one evaluation each, in order (as diagnose's --start)."""
    from dualarm.training import evaluation

    starts = []
    real = evaluation.evaluate

    def spy(act, vec, episodes, *a, **k):
        result = real(act, vec, episodes, *a, **k)
        starts.append(vec.starts())
        return result

    monkeypatch.setattr(evaluation, "evaluate", spy)
    assert main(["eval", str(run_dir), "--episodes", "3", "--start", "align"]) == 0
    assert "both arms starting at align" in capsys.readouterr().out
    assert (starts[0] == 2).all()
    assert main(["eval", str(run_dir), "--episodes", "2", "--start", "grasp", "align"]) == 0
    out = capsys.readouterr().out
    assert out.count("success rate") == 2 and out.index("at grasp") < out.index("at align")
    assert (starts[1] == 1).all() and (starts[2] == 2).all()


def test_diagnose_counts_each_arms_outcome_from_each_start(run_dir, capsys):
    assert main(["diagnose", str(run_dir), "--episodes", "2", "--start", "reach", "align"]) == 0
    out = capsys.readouterr().out
    assert "from the normal reset: success" in out and "from both arms at align" in out
    assert "from both arms at grasp" not in out
    rows = [line.split() for line in out.splitlines() if line.startswith("  ")
            and "outcome" not in line and "(median)" not in line]
    # each start's table counts 2 episodes per arm
    assert sum(int(r[-2]) for r in rows) == 4 and sum(int(r[-1]) for r in rows) == 4


def test_diagnose_runs_the_actors_asked_for(run_dir, capsys):
    """--actor target diagnoses the target actors (named in the heading); averaged actors a
    run without them does not have are refused with the run's name, exit status 2."""
    assert main(["diagnose", str(run_dir), "--episodes", "2", "--start", "align",
                 "--actor", "target"]) == 0
    assert "target actors" in capsys.readouterr().out
    assert main(["diagnose", str(run_dir), "--episodes", "2", "--actor", "average"]) == 2
    assert "no averaged actors" in capsys.readouterr().err


def test_export_writes_time_joints_and_grip(run_dir, tmp_path, capsys):
    out = tmp_path / "trajectory.csv"
    assert main(["export", str(run_dir), "-o", str(out), "--seed", "4"]) == 0
    with open(out, newline="") as f:
        reader = csv.reader(f)
        header = next(reader)
        data = np.array([[float(x) for x in row] for row in reader])
    assert header[0] == "time" and header[1] == "left_s0" and header[-2:] == ["grip_left", "grip_right"]
    assert data.shape == (11, 17)                        # 10 steps + the start
    np.testing.assert_allclose(np.diff(data[:, 0]), 0.02, atol=1e-9)
    assert np.all((data[:, -2:] >= 0) & (data[:, -2:] <= 1))
    assert np.abs(np.diff(data[:, 1:15], axis=0)).max() > 0    # the arms moved


def test_export_of_a_run_in_every_format(run_dir, tmp_path, capsys):
    """A run's episode as a Baxter file and a ROS 2 bag (time-parameterised, replayed in the
    simulator), and its policy as ONNX checked against PyTorch."""
    assert main(["export", str(run_dir), "-o", str(tmp_path / "b.csv"), "--format", "baxter",
                 "--seed", "4", "--replay"]) == 0
    out = capsys.readouterr().out
    assert "time-parameterised" in out and "replayed in the simulator" in out
    with open(tmp_path / "b.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) > 11 and float(rows[-1]["time"]) > 0.2     # slower than 10 steps of 20 ms
    assert main(["export", str(run_dir), "-o", str(tmp_path / "bag"), "--format", "ros2"]) == 0
    assert (tmp_path / "bag" / "metadata.yaml").exists()
    capsys.readouterr()
    assert main(["export", str(run_dir), "-o", str(tmp_path / "p.onnx"), "--format", "onnx"]) == 0
    line = capsys.readouterr().out
    assert "over 1000 observations" in line
    assert float(line.rsplit(" ", 1)[1]) < 1e-5


def test_export_help_names_every_format(capsys):
    with pytest.raises(SystemExit):
        main(["export", "--help"])
    text = capsys.readouterr().out
    assert all(name in text for name in ("csv", "baxter", "ros2", "onnx"))


def test_play_renders_a_video(run_dir, tmp_path, capsys):
    out = tmp_path / "play.gif"
    assert main(["play", str(run_dir), "-o", str(out), "--width", "64", "--height", "48",
                 "--fps", "10"]) == 0
    assert out.stat().st_size > 0


def test_bad_inputs_name_what_is_wrong(tmp_path, capsys):
    assert main(["eval", str(tmp_path / "nowhere")]) == 2
    assert "not a run directory" in capsys.readouterr().err
    bad = tmp_path / "bad.yaml"
    bad.write_text("algo: {learning_rate: 0.1}\n")
    assert main(["train", "--config", str(bad), "--condition", "none", "--out", str(tmp_path / "r")]) == 2
    assert "learning_rate" in capsys.readouterr().err
    assert main(["train", "--condition", "single", "--constraints", str(tmp_path / "missing.yaml"),
                 "--out", str(tmp_path / "r2")]) == 2
    assert "missing.yaml" in capsys.readouterr().err
    assert not (tmp_path / "r2").exists()                 # nothing written for a bad start


def test_train_without_a_config_uses_the_recipe(tmp_path, capsys):
    """`dualarm train` with no --config trains with the recipe (``TrainConfig()``), whose
    conditions all observe the joint angles; the options given override it."""
    from dualarm.training import TrainConfig

    out = tmp_path / "run"
    assert main(["train", "--condition", "none", "--episodes", "4", "--num-envs", "4",
                 "--out", str(out)]) == 0
    saved = TrainConfig.load(out / "config.yaml")
    assert saved == TrainConfig.recipe().with_(condition="none", episodes=4, num_envs=4)
    assert saved.replay.her_share == 0.8 and saved.algo.twin_critics and saved.shaping.approach == 1.0
    assert saved.shaping.carry == 1.0 and saved.algo.twin_min_weight == 0.5
    assert saved.algo.eval_actor == "average" and saved.algo.policy_average > 0
    assert saved.task_config().observes_joint_angles          # none observes them too
    assert TrainConfig.paper().with_(condition="none").task_config().observes_joint_angles is False


def test_shipped_expert_demos_config_trains(tmp_path, capsys):
    """configs/expert-demos.yaml, the settings of docs/training.md's fourth round, stays a
    valid --config: demonstrations recorded, the twin critics and reward scale in force."""
    shipped = Path(__file__).resolve().parents[1] / "configs" / "expert-demos.yaml"
    out = tmp_path / "run"
    assert main(["train", "--config", str(shipped), "--episodes", "16", "--out", str(out)]) == 0
    saved = yaml.safe_load((out / "config.yaml").read_text())
    assert saved["condition"] == "multi" and saved["demos"]["episodes"] == 256
    assert saved["task"]["reach_funnel"] == 1.0
    assert saved["algo"]["twin_critics"] and saved["algo"]["reward_scale"] == 0.0025
    with open(out / "metrics.csv", newline="") as f:
        assert len(list(csv.DictReader(f))) == 16


def test_shipped_reset_starts_config_places_nothing():
    """configs/reset-starts.yaml is the recipe with every training episode at the normal reset
    (docs/human-demos, section 7): no placed sub-task starts, no curriculum to move them, no
    approach starts; the learner's settings stay the recipe's."""
    from dualarm.training.config import TrainConfig

    config = TrainConfig.load(Path(__file__).resolve().parents[1] / "configs" / "reset-starts.yaml")
    recipe = TrainConfig.recipe()
    assert not config.starts.later and config.starts.probs == (1.0, 0.0, 0.0)
    assert config.starts.curriculum == 0 and not config.starts.approach and config.starts.probe == 0
    assert recipe.starts.later                      # the one change is the starts
    assert config.algo == recipe.algo and config.replay == recipe.replay
    assert config.stop_at == 0.85


@pytest.mark.parametrize("name", sorted(p.name for p in (Path(__file__).resolve().parents[1]
                                                         / "configs").glob("*.yaml")))
def test_every_shipped_config_is_a_valid_train_config(name):
    """Each file in configs/ loads as a TrainConfig (fields, types, cross-checks), so a
    README command that names it does not fail at its first line."""
    from dualarm.training.config import TrainConfig

    config = TrainConfig.load(Path(__file__).resolve().parents[1] / "configs" / name)
    assert config.episodes >= 1


def test_a_config_that_extends_the_recipe_changes_only_what_it_names(tmp_path):
    """``extends: recipe`` starts from the shipped recipe; the groups, ``algo`` and ``task``
    merge key by key, other fields replace the base's."""
    from dualarm.training.config import TrainConfig

    variant = tmp_path / "variant.yaml"
    variant.write_text("extends: recipe\nstarts: {curriculum: 0.3}\nalgo:\n  batch_size: 64\n"
                       "task:\n  max_episode_steps: 80\n")
    recipe, config = TrainConfig.recipe(), TrainConfig.load(variant)
    assert config.starts.curriculum == 0.3 and recipe.starts.curriculum != 0.3
    assert config.starts.probs == recipe.starts.probs
    assert config.algo.batch_size == 64 and config.task["max_episode_steps"] == 80
    assert config.algo.twin_critics and config.algo.hidden == recipe.algo.hidden
    assert config.task["joint_angles_in_obs"] is True           # kept from the recipe's task
    changed = {k for k, v in config.to_dict().items() if recipe.to_dict()[k] != v}
    assert changed == {"starts", "algo", "task"}


def test_a_file_layers_on_the_recipe_unless_it_extends_the_paper(tmp_path):
    """A file without ``extends`` changes the recipe (its task merged key by key, so the joint
    angles stay observed); ``extends: paper`` and ``--config paper`` give the paper's DDPG."""
    from dualarm.training.config import TrainConfig

    plain = tmp_path / "plain.yaml"
    plain.write_text("task: {max_episode_steps: 80}\nalgo: {batch_size: 64}\n")
    config = TrainConfig.load(plain)
    assert config.task == {"joint_angles_in_obs": True, "max_episode_steps": 80}
    assert config.algo == TrainConfig().algo.with_(batch_size=64)
    assert config.with_(task=TrainConfig().task, algo=TrainConfig().algo) == TrainConfig()
    paper = tmp_path / "paper.yaml"
    paper.write_text("extends: paper\nalgo: {batch_size: 64}\n")
    assert TrainConfig.load(paper) == TrainConfig.paper().with_(algo=TrainConfig.paper().algo.with_(batch_size=64))
    assert TrainConfig.load("paper") == TrainConfig.paper() != TrainConfig()
    assert not TrainConfig.paper().algo.twin_critics and TrainConfig.paper().replay.her_share == 0
    for preset in (TrainConfig(), TrainConfig.paper()):           # what a run writes reads back
        assert TrainConfig.from_dict(preset.to_dict()) == preset
        assert TrainConfig.from_dict(preset.to_dict(), base=TrainConfig.paper()) == preset


def test_a_run_config_written_before_the_recipe_was_the_default_reads_as_it_ran(tmp_path):
    """A run's config.yaml of the flat layout (before the groups) that lacks the fields added
    since (written when the defaults were the paper's) takes the paper's values for them, the
    values that run used."""
    from dualarm.training.config import TrainConfig
    from dualarm.training.config_groups import FLAT_FIELDS

    grouped = TrainConfig.paper().with_(condition="none").to_dict()
    old = {k: v for k, v in grouped.items() if k not in ("starts", "replay", "shaping",
                                                         "near_box", "demos", "task")}
    old.update({flat: grouped[group][name] for flat, (group, name) in FLAT_FIELDS.items()
                if flat not in ("mirror_episodes", "recombine_share") and name in grouped[group]})
    old["demo_following"] = "time"                     # an option that has left since
    old["demos"] = None
    old["algo"] = {k: v for k, v in old["algo"].items() if k not in ("policy_average", "eval_actor")}
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump(old))
    saved = TrainConfig.load_saved(path)
    assert saved == TrainConfig.paper().with_(condition="none")
    assert not saved.task_config().observes_joint_angles


def test_flat_layout_files_load_into_the_groups(tmp_path):
    """Files of the flat layout (every run directory made before the groups, and the run logs
    under docs/) still load, or name the removed option a screen turned on: each old name lands in its group, ``demos: DIR`` is the folder, a
    flat base and a grouped variant merge key by key, and a group given both ways is refused
    naming both spellings."""
    from dualarm.errors import InputError
    from dualarm.training.config import TrainConfig

    root = Path(__file__).resolve().parents[1]
    saved = sorted(root.glob("docs/*/runs/*/config.yaml"))
    assert saved, "no run logs under docs/"
    flat = [p for p in saved if "start_probs" in p.read_text()]
    assert flat, "no flat-layout run log under docs/"
    loaded = 0
    for path in flat:
        try:
            config = TrainConfig.load_saved(path)
        except InputError as exc:      # a screen of an option that has since left the code
            assert "is no longer an option" in str(exc), exc
            continue
        loaded += 1
        old = yaml.safe_load(path.read_text())
        assert config.starts.probs == tuple(old["start_probs"]), path
        assert config.replay.her_share == old["her_share"], path
        assert config.seed == old["seed"] and config.episodes == old["episodes"], path
        if old.get("demos"):
            assert Path(config.demos.folder) == (path.parent / old["demos"]), path
    assert loaded > len(flat) / 2
    base = tmp_path / "base.yaml"
    base.write_text("start_probs: [0.5, 0.25, 0.25]\nher_share: 0.5\ndemo_episodes: 7\n")
    variant = tmp_path / "variant.yaml"
    variant.write_text("extends: base.yaml\nstarts: {curriculum: 0.25}\ndemos: rec\n")
    config = TrainConfig.load(variant)
    assert config.starts == TrainConfig().starts.with_(probs=(0.5, 0.25, 0.25), curriculum=0.25)
    assert config.replay.her_share == 0.5 and config.demos.episodes == 7
    assert config.demos.folder == str(tmp_path / "rec")
    both = tmp_path / "both.yaml"
    both.write_text("her_share: 0.5\nreplay: {her_share: 0.4}\n")
    with pytest.raises(InputError, match="replay.her_share or its old name her_share"):
        TrainConfig.load(both)


def test_removed_options_load_at_their_off_value_and_are_refused_at_any_other(tmp_path):
    """Options measured and not adopted left the code; a run directory that lists them at
    their off value (every run made before) still loads, a file that turns one on is refused
    with one line naming it."""
    from dualarm.errors import InputError
    from dualarm.training.config import REMOVED_FIELDS, TrainConfig
    from dualarm.rl.config import REMOVED_FIELDS as ALGO_REMOVED

    old = TrainConfig.paper().to_dict()
    old.update({name: value for name, value in REMOVED_FIELDS.items()})
    old["algo"].update({"grip_hold_eps": 0.0, "grip_hold_steps": 8, "free_grip": False,
                        "critic_layer_norm": False, "random_grip": True, "policy_delay": 1})
    assert set(old["algo"]) - set(TrainConfig.paper().algo.to_dict()) <= set(ALGO_REMOVED)
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump(old))
    assert TrainConfig.load_saved(path) == TrainConfig.paper()
    for text, field in (("grasp_spread: 0.03\n", "grasp_spread"),
                        ("algo: {policy_delay: 2}\n", "policy_delay"),
                        ("reach_action_l2: 0.01\n", "reach_action_l2")):
        path.write_text(text)
        with pytest.raises(InputError, match=f"{field}: .* is no longer an option"):
            TrainConfig.load(path)


def test_extends_chains_and_resolves_constraints_against_the_file_that_names_them(tmp_path):
    from dualarm.constraints.constraint_set import default_constraints_path
    from dualarm.training.config import TrainConfig

    base_dir = tmp_path / "base"
    base_dir.mkdir()
    (base_dir / "multi.yaml").write_bytes(default_constraints_path("multi").read_bytes())
    (base_dir / "base.yaml").write_text("condition: multi\nconstraints: multi.yaml\nepisodes: 50\n"
                                        "algo:\n  hidden: [32, 32]\n  batch_size: 16\n")
    (tmp_path / "middle.yaml").write_text("extends: base/base.yaml\nalgo:\n  batch_size: 8\n")
    (tmp_path / "top.yaml").write_text("extends: middle.yaml\nepisodes: 70\n")
    config = TrainConfig.load(tmp_path / "top.yaml")
    assert (config.episodes, config.algo.hidden, config.algo.batch_size) == (70, (32, 32), 8)
    assert Path(config.constraints) == base_dir / "multi.yaml"
    assert len(config.load_constraints().segments) == 2


@pytest.mark.parametrize("files, message, culprit", [
    ({"a.yaml": "extends: a.yaml\n"}, "loops back", "a.yaml"),
    ({"a.yaml": "extends: b.yaml\n", "b.yaml": "extends: a.yaml\n"}, "loops back", "b.yaml"),
    ({"a.yaml": "extends: missing.yaml\n"}, "no config file", "a.yaml"),
    ({"a.yaml": "extends: [recipe]\n"}, "must name a config file", "a.yaml"),
    ({"a.yaml": "extends: b.yaml\n", "b.yaml": "- 1\n"}, "expected a mapping", "b.yaml"),
    ({"a.yaml": "extends: b.yaml\n", "b.yaml": "batch: 3\n"}, "unknown field", "b.yaml"),
    ({"a.yaml": "extends: b.yaml\nepisodes: 5\n", "b.yaml": "algo:\n  hiden: [8]\n"},
     r"algo: unknown DADDPG field\(s\) \['hiden'\]", "b.yaml"),
    ({"a.yaml": "extends: b.yaml\nepsiodes: 5\n", "b.yaml": "episodes: 4\n"},
     r"unknown field\(s\) \['epsiodes'\]", "a.yaml"),
])
def test_a_bad_extends_is_refused_naming_the_file(tmp_path, files, message, culprit):
    """Each error names the file at fault: a base's misspelt field is the base's."""
    from dualarm.errors import InputError
    from dualarm.training.config import TrainConfig

    for name, text in files.items():
        (tmp_path / name).write_text(text)
    with pytest.raises(InputError, match=message) as info:
        TrainConfig.load(tmp_path / "a.yaml")
    assert str(info.value).startswith(str(tmp_path / culprit) + ":")


def test_load_learner_restores_the_critics_that_load_policy_leaves_untrained(tmp_path):
    """load_policy restores the actors only; a critic read from it is its initial weights.
    load_learner restores the critics too (the same actors either way). The run is its own,
    with updates: the module's run has none in its first 8 episodes (80 steps, 100 of warm-up)."""
    import torch

    from dualarm.training.policy import load_learner, load_policy

    config = tmp_path / "small.yaml"
    config.write_text(yaml.safe_dump({**SMALL, "algo": {**SMALL["algo"], "warmup_steps": 20}}))
    run_dir = tmp_path / "run"
    assert main(["train", "--condition", "none", "--episodes", "8", "--num-envs", "4",
                 "--config", str(config), "--out", str(run_dir)]) == 0
    _, policy_only, _ = load_policy(run_dir, "latest")
    _, learner, info = load_learner(run_dir)
    assert info["episodes"] == 8 and learner.updates > 0
    for a, b in zip(policy_only.actor.parameters(), learner.actor.parameters()):
        assert torch.equal(a, b)
    assert not all(torch.equal(a, b) for a, b in
                   zip(policy_only.critic.parameters(), learner.critic.parameters()))


def test_critic_returns_add_the_shaping_of_a_potential(run_dir):
    """With a constant potential c, a step's shaping is gamma c - c, so an episode cut off
    after T steps returns -c (1 - gamma^(T - t)) more from step t than without it."""
    from dualarm.training.diagnostics import critic_vs_returns
    from dualarm.training.vector import make_vector_env
    from dualarm.training.policy import load_learner

    config, learner, _ = load_learner(run_dir)
    c, gamma, steps = 0.3, learner.config.gamma, config.task["max_episode_steps"]
    reports = []
    for potential in (None, lambda obs: np.full(obs.shape[:-1], c)):
        vec = make_vector_env(config, 4, constraints=config.load_constraints())
        reports.append(critic_vs_returns(learner, vec, 4, potential=potential))
        vec.close()
    plain, shaped = reports
    assert (plain.episodes_by_step == 4).all() and len(plain.episodes_by_step) == steps
    np.testing.assert_allclose(shaped.q_by_step, plain.q_by_step)
    expected = -c * (1 - gamma ** (steps - np.arange(steps)))
    np.testing.assert_allclose(shaped.return_by_step - plain.return_by_step,
                               np.stack([expected] * 2, axis=1), atol=1e-9)


def test_diagnose_critic_prints_q_next_to_the_observed_return_by_step(run_dir, capsys):
    assert main(["diagnose", str(run_dir), "--critic", "--episodes", "4", "--start", "reach"]) == 0
    out = capsys.readouterr().out
    assert "from the normal reset: Q - G over all 40 steps" in out
    rows = [line.split() for line in out.splitlines() if line.strip()[:1].isdigit()]
    assert [int(r[0]) for r in rows] == [0, 5]                   # steps 0 and 5 of 10
    assert all(int(r[1]) == 4 and len(r) == 6 for r in rows)


def test_train_writes_where_o_output_or_out_says(tmp_path):
    """Every command that writes takes -o/--output; train keeps --out as an alias."""
    from dualarm.cli.main import build_parser

    parser = build_parser()
    for flag in ("-o", "--output", "--out"):
        args = parser.parse_args(["train", flag, str(tmp_path / "r")])
        assert str(args.out) == str(tmp_path / "r")


def test_the_recipe_block_in_the_docs_is_the_recipe(tmp_path):
    """docs/training.md lists the recipe value by value on the paper's base, each with its
    reason: that block, loaded as a config file, is ``TrainConfig()``, and it stays short."""
    from dualarm.training.config import TrainConfig

    text = (Path(__file__).resolve().parents[1] / "docs" / "training.md").read_text()
    block = text.split("<!-- recipe -->\n```yaml\n", 1)[1].split("```", 1)[0]
    (tmp_path / "recipe.yaml").write_text(block)
    assert TrainConfig.load(tmp_path / "recipe.yaml") == TrainConfig()
    values = [line for line in block.splitlines() if ":" in line and not line.rstrip().endswith(":")
              and not line.startswith("extends")]
    assert len(values) <= 30
    assert all("#" in line for line in values), "a recipe value without its reason"
