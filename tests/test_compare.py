"""`dualarm compare`: every (condition, seed) trained as `dualarm train` trains it, in
parallel on local processes or Ray tasks; resume, conflicts and failed runs."""

import csv
import os
import shutil


import pytest
import yaml

from dualarm.cli.main import main
from dualarm.constraints.constraint_set import default_constraints_path
from dualarm.errors import InputError
from dualarm.experiments.backends import RayBackend, execute, read_done
from dualarm.experiments.compare import (CompareRequest, compare, episode_budget, load_manifest,
                                         prepare, run_state, task_for)
from dualarm.training import TrainConfig, Trainer, train

TINY = {"num_envs": 2, "eval_every": 2, "eval_episodes": 2, "checkpoint_every": 2,
        "algo": {"hidden": [32, 32], "batch_size": 32, "warmup_steps": 0, "buffer_size": 5000},
        "task": {"max_episode_steps": 10}}
EPISODES = 4


def rows(path, drop=("wall_time_s",)):
    with open(path, newline="") as f:
        return [{k: v for k, v in r.items() if k not in drop} for r in csv.DictReader(f)]


def episodes_of(run_dir):
    return [int(r["episode"]) for r in rows(run_dir / "metrics.csv")]


def snapshot(run_dir):
    """Every file of a run directory: its bytes and modification time (ns)."""
    return {p.relative_to(run_dir): (p.read_bytes(), p.stat().st_mtime_ns)
            for p in sorted(run_dir.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def base_yaml(tmp_path_factory):
    path = tmp_path_factory.mktemp("base") / "base.yaml"
    path.write_text(yaml.safe_dump({"extends": "paper", **TINY}))
    return path


@pytest.fixture(scope="module")
def local(tmp_path_factory, base_yaml):
    """A finished comparison of 3 conditions x 2 seeds on 2 local worker processes."""
    out = tmp_path_factory.mktemp("local") / "cmp"
    code = main(["compare", "--conditions", "none,single,multi", "--seeds", "0,1",
                 "--episodes", str(EPISODES), "--workers", "2", "--config", str(base_yaml),
                 "--poll", "0.2", "-o", str(out)])
    return out, code


def reference(tmp_path, condition, seed, episodes=EPISODES):
    """The same run trained by `dualarm train`'s code path, in this process."""
    config = TrainConfig.from_dict(TINY, base=TrainConfig.paper()).with_(condition=condition, seed=seed, episodes=episodes)
    train(config, tmp_path / f"ref-{condition}-{seed}", progress=False)
    return rows(tmp_path / f"ref-{condition}-{seed}" / "metrics.csv")


def test_local_backend_trains_every_condition_and_seed(local, tmp_path):
    out, code = local
    assert code == 0
    manifest = yaml.safe_load((out / "comparison.yaml").read_text())
    assert manifest["conditions"] == ["none", "single", "multi"] and manifest["seeds"] == [0, 1]
    assert manifest["episodes"] == EPISODES and manifest["base"]["algo"]["hidden"] == [32, 32]
    names = sorted(p.name for p in (out / "runs").iterdir())
    assert names == sorted(f"{c}-seed{s}" for c in ("none", "single", "multi") for s in (0, 1))
    for name in names:
        run = out / "runs" / name
        config = yaml.safe_load((run / "config.yaml").read_text())
        assert f"{config['condition']}-seed{config['seed']}" == name
        assert config["episodes"] == EPISODES
        if config["condition"] == "none":
            assert config["constraints"] is None
        else:       # the run keeps its own copy of the shipped file
            assert config["constraints"] == "constraints.yaml"
            assert ((run / "constraints.yaml").read_bytes()
                    == default_constraints_path(config["condition"]).read_bytes())
        assert episodes_of(run) == list(range(1, EPISODES + 1))
        assert read_done(run)["episodes"] == EPISODES and (run / "curves.png").exists()
        assert run_state(run, EPISODES) == "finished" and run_state(run, EPISODES + 1) == "partial"
    # each run is exactly the run `dualarm train` makes with the same settings
    assert rows(out / "runs" / "multi-seed1" / "metrics.csv") == reference(tmp_path, "multi", 1)
    assert rows(out / "runs" / "none-seed0" / "metrics.csv") != rows(out / "runs" / "none-seed1" / "metrics.csv")


def test_conflicting_arguments_name_the_field_and_change_nothing(local, base_yaml, tmp_path, capsys):
    out, _ = local
    before = (out / "comparison.yaml").read_bytes()
    other = tmp_path / "other.yaml"
    other.write_text(yaml.safe_dump({"extends": "paper", **TINY, "algo": {**TINY["algo"], "hidden": [64, 64]}}))
    capsys.readouterr()
    assert main(["compare", "--config", str(other), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "comparison.yaml" in err and "'algo.hidden'" in err and "[32, 32]" in err
    assert main(["compare", "--episodes", "2", "-o", str(out)]) == 2
    assert "'episodes'" in capsys.readouterr().err
    shutil.copytree(default_constraints_path("multi").parent, tmp_path / "cons")
    assert main(["compare", "--constraints-dir", str(tmp_path / "cons"), "-o", str(out)]) == 2
    assert "constraints_dir" in capsys.readouterr().err
    assert main(["compare", "--seeds", "0,x", "-o", str(out)]) == 2
    assert "--seeds" in capsys.readouterr().err
    assert main(["compare", "--stop-at", "0.9", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "'stop_at' is None" in err and "0.9 in --stop-at" in err
    assert (out / "comparison.yaml").read_bytes() == before
    # the same arguments again: nothing to train, nothing rewritten but the manifest
    runs = {p.name: snapshot(p) for p in (out / "runs").iterdir()}
    assert main(["compare", "--config", str(base_yaml), "-o", str(out)]) == 0
    assert {p.name: snapshot(p) for p in (out / "runs").iterdir()} == runs
    assert "6 already finished" in capsys.readouterr().out


def test_a_run_that_reached_its_stop_is_finished_whatever_the_budget(tmp_path):
    """``--stop-at`` goes into every run's config; a run whose done marker says it stopped at
    its target is finished even below the comparison's (or a larger) episodes."""
    from dualarm.experiments.compare import CompareRequest, prepare

    comparison = prepare(tmp_path / "cmp", CompareRequest(conditions=("none",), seeds=(0,),
                                                          episodes=50, stop_at=0.85))
    assert comparison.base.stop_at == 0.85 and comparison.run_config("none", 0).stop_at == 0.85
    run = tmp_path / "cmp" / "runs" / "none-seed0"
    run.mkdir(parents=True)
    comparison.run_config("none", 0).save(run / "config.yaml")
    (run / "done.yaml").write_text("episodes: 32\nstopped: true\n")
    assert run_state(run, 50) == run_state(run, 5000) == "finished"
    (run / "done.yaml").write_text("episodes: 32\nstopped: false\n")
    assert run_state(run, 50) == "partial"


def test_constraints_dir_is_copied_and_a_changed_file_conflicts(tmp_path):
    cons = tmp_path / "cons"
    shutil.copytree(default_constraints_path("multi").parent, cons)
    base = TrainConfig.from_dict(TINY, base=TrainConfig.paper())
    comparison = prepare(tmp_path / "cmp", CompareRequest(conditions=("none", "multi"), seeds=(0,),
                                                          episodes=2, base=base, constraints_dir=cons))
    copy = tmp_path / "cmp" / "constraints" / "multi.yaml"
    assert copy.read_bytes() == (cons / "multi.yaml").read_bytes()
    assert comparison.run_config("multi", 0).constraints == str(copy)
    assert comparison.run_config("none", 0).constraints is None
    assert not (tmp_path / "cmp" / "constraints" / "single.yaml").exists()   # not needed (yet)
    (cons / "multi.yaml").write_text((cons / "multi.yaml").read_text().replace("multi", "multi2", 1))
    with pytest.raises(InputError, match=r"constraints\.multi.*differs"):
        prepare(tmp_path / "cmp", CompareRequest(constraints_dir=cons))
    (cons / "single.yaml").unlink()
    with pytest.raises(InputError, match="single.yaml"):   # adding a condition needs its file
        prepare(tmp_path / "cmp", CompareRequest(conditions=("single",)))
    assert load_manifest(tmp_path / "cmp").conditions == ("none", "multi")


def test_rerun_skips_finished_resumes_partial_and_reports_failed(tmp_path, base_yaml, capsys):
    """A finished run is left alone, a run stopped after its checkpoint at episode 2 (with a
    row logged after it) ends with episodes 1..4 exactly as an uninterrupted run, and a run
    whose checkpoint is corrupt fails with its error while the others finish."""
    out = tmp_path / "cmp"
    comparison = prepare(out, CompareRequest(conditions=("none",), seeds=(0, 1, 2), episodes=EPISODES,
                                             base=TrainConfig.from_dict(TINY, base=TrainConfig.paper())))
    plans = {p.seed: p for p in comparison.runs()}
    assert {p.state for p in plans.values()} == {"new"}
    assert execute(task_for(comparison, plans[0]), in_place=True).ok
    for seed in (1, 2):                    # stopped runs: checkpoint after 2 of 4 episodes
        Trainer.start(plans[seed].config.with_(episodes=2), plans[seed].path, progress=False).run()
    metrics = plans[1].path / "metrics.csv"
    last = metrics.read_text().splitlines()[-1].split(",")
    with open(metrics, "a") as f:                        # a row logged after the checkpoint
        f.write(",".join(["3", *last[1:]]) + "\n")
    (plans[2].path / "checkpoints" / "latest.pt").write_bytes(b"not a checkpoint")
    assert [p.state for p in comparison.runs()] == ["finished", "partial", "partial"]
    finished = snapshot(plans[0].path)

    capsys.readouterr()
    assert main(["compare", "--workers", "2", "--poll", "0.2", "-o", str(out)]) == 1
    captured = capsys.readouterr()
    assert "1 finished, 2 to resume" in captured.err
    assert "none-seed1: done, 4 episodes" in captured.err
    assert "none-seed2: FAILED" in captured.err and "CheckpointError" in captured.err
    assert "latest.pt" in captured.err
    assert "1 failed (none-seed2)" in captured.out
    assert snapshot(plans[0].path) == finished
    assert rows(plans[1].path / "metrics.csv") == reference(tmp_path, "none", 1)
    assert read_done(plans[2].path) is None and episodes_of(plans[2].path) == [1, 2]


def test_a_second_comparison_on_the_same_directory_is_refused(tmp_path, capsys):
    from dualarm.locks import DirectoryLock

    with DirectoryLock(tmp_path / "cmp", "dualarm compare"):
        assert main(["compare", "--conditions", "none", "--seeds", "0", "-o", str(tmp_path / "cmp")]) == 2
    assert f"in use by dualarm compare, pid {os.getpid()}" in capsys.readouterr().err


@pytest.fixture(scope="module")
def ray_instance():
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False)
    yield ray
    ray.shutdown()


def test_ray_backend_makes_the_same_run_directories(ray_instance, local, base_yaml, tmp_path):
    out = tmp_path / "cmp"
    assert main(["compare", "--backend", "ray", "--conditions", "none,multi", "--seeds", "1",
                 "--episodes", str(EPISODES), "--config", str(base_yaml), "--poll", "0.2",
                 "-o", str(out)]) == 0
    assert ray_instance.is_initialized()          # an instance it did not start is left running
    assert sorted(p.name for p in (out / "runs").iterdir()) == ["multi-seed1", "none-seed1"]
    for name in ("none-seed1", "multi-seed1"):
        assert rows(out / "runs" / name / "metrics.csv") == rows(local[0] / "runs" / name / "metrics.csv")
        assert read_done(out / "runs" / name)["episodes"] == EPISODES


def test_ray_without_a_shared_filesystem_ships_run_directories(ray_instance, local, tmp_path):
    """Forced off-place: a partial run goes to the task as a tar, is resumed in a node-local
    directory and comes back as a tar; a --constraints-dir file is found by its path."""
    cons = tmp_path / "cons"
    shutil.copytree(default_constraints_path("multi").parent, cons)
    out = tmp_path / "cmp"
    comparison = prepare(out, CompareRequest(conditions=("none", "multi"), seeds=(0,), episodes=EPISODES,
                                             base=TrainConfig.from_dict(TINY, base=TrainConfig.paper()), constraints_dir=cons))
    none_run = out / "runs" / "none-seed0"
    Trainer.start(comparison.run_config("none", 0).with_(episodes=2), none_run, progress=False).run()
    result = compare(out, CompareRequest(), RayBackend(shared_fs=False), poll_s=0.2, progress=False)
    assert [o.ok for o in result.outcomes] == [True, True]
    assert rows(none_run / "metrics.csv") == rows(local[0] / "runs" / "none-seed0" / "metrics.csv")
    multi = yaml.safe_load((out / "runs" / "multi-seed0" / "config.yaml").read_text())
    assert multi["constraints"] == "constraints.yaml"      # the run's copy of the comparison's
    assert ((out / "runs" / "multi-seed0" / "constraints.yaml").read_bytes()
            == (out / "constraints" / "multi.yaml").read_bytes())
    assert rows(out / "runs" / "multi-seed0" / "metrics.csv") == rows(
        local[0] / "runs" / "multi-seed0" / "metrics.csv")     # the same file's content
    assert not list((out / "runs").glob(".*"))    # no leftovers of the swaps


def test_a_new_comparison_without_a_base_trains_the_recipe(tmp_path):
    comparison = prepare(tmp_path / "cmp", CompareRequest(conditions=("none", "multi"), seeds=(3,)))
    recipe = TrainConfig.recipe()
    assert comparison.episodes == recipe.episodes == 10000
    assert comparison.run_config("none", 3) == recipe.with_(condition="none", seed=3, constraints=None)
    assert comparison.run_config("multi", 3).algo == recipe.algo       # twin critics, averaged actors...
    assert load_manifest(tmp_path / "cmp").base == comparison.base       # recorded as such


def test_the_demos_condition_runs_the_recordings_on_the_multi_constraints(tmp_path):
    """--demos DIR (or --conditions ...,demos) adds the fourth condition: the base config with
    the multi guide term, the multi constraints and the recordings as demonstrations; its
    folder is checked (scene included) before anything is written, and stays the comparison's."""
    from dualarm.demos.formats import DEFAULT_DEMO_DIR

    cons = tmp_path / "cons"
    shutil.copytree(default_constraints_path("multi").parent, cons)
    base = TrainConfig.from_dict({**TINY, "task": {"max_episode_steps": 40}}, base=TrainConfig.paper())
    no_scene = tmp_path / "no-scene"
    shutil.copytree(DEFAULT_DEMO_DIR, no_scene)
    (no_scene / "scene.csv").unlink()
    with pytest.raises(InputError, match="scene"):
        prepare(tmp_path / "bad", CompareRequest(conditions=("none",), base=base, demos_dir=no_scene))
    assert not (tmp_path / "bad").exists()
    with pytest.raises(InputError, match="--demos DIR"):
        prepare(tmp_path / "bad", CompareRequest(base=base.with_(demos={"folder": str(DEFAULT_DEMO_DIR)})))
    comparison = prepare(tmp_path / "cmp", CompareRequest(conditions=("none",), seeds=(0,), episodes=2,
                                                          base=base, constraints_dir=cons,
                                                          demos_dir=DEFAULT_DEMO_DIR))
    assert comparison.conditions == ("none", "demos")
    run = comparison.run_config("demos", 0)
    assert (run.condition, run.compared_condition, run.demos.folder) == ("multi", "demos", str(DEFAULT_DEMO_DIR))
    assert run.constraints == str(tmp_path / "cmp" / "constraints" / "multi.yaml")
    assert comparison.run_config("none", 0).demos.folder is None
    assert load_manifest(tmp_path / "cmp").demos_dir == DEFAULT_DEMO_DIR
    with pytest.raises(InputError, match="demos_dir"):
        prepare(tmp_path / "cmp", CompareRequest(demos_dir=no_scene))


def test_a_constraints_file_that_does_not_fit_its_condition_is_refused_before_anything_is_written(tmp_path):
    cons = tmp_path / "cons"
    cons.mkdir()
    shutil.copy(default_constraints_path("multi"), cons / "single.yaml")   # two segments
    with pytest.raises(InputError, match="needs one segment"):
        prepare(tmp_path / "cmp", CompareRequest(conditions=("single",), seeds=(0,), episodes=1,
                                                 constraints_dir=cons))
    assert not (tmp_path / "cmp").exists()


def test_the_progress_total_drops_what_runs_stopped_at_success_did_not_need():
    # three runs of 1,000 episodes: one ended at 0.85 after 480, one still going at 300, one
    # not started; the bar shows 780 done of at most 2,480, not of 3,000
    logged = {"none-seed0": 480, "multi-seed0": 300, "demos-seed0": 0}
    assert episode_budget(logged, {"none-seed0"}, 1000) == (780, 2480)
    # a run that ended on its budget counts it whole; nothing ended: the full budget
    assert episode_budget({"a": 1000, "b": 5}, {"a"}, 1000) == (1005, 2000)
    assert episode_budget(logged, set(), 1000) == (780, 3000)
