"""`dualarm pipeline`: demonstrations -> constraints -> comparison -> report, and its resume."""

from pathlib import Path

import yaml

from dualarm.cli.main import main
from dualarm.demos.formats import DEFAULT_DEMO_DIR
from dualarm.constraints.constraint_set import ConstraintSet
from dualarm.experiments.compare import load_manifest
from dualarm.training import TrainConfig

TINY = {"num_envs": 2, "eval_every": 2, "eval_episodes": 2,
        "algo": {"hidden": [16, 16], "batch_size": 16, "warmup_steps": 0, "buffer_size": 2000},
        "task": {"max_episode_steps": 40}}       # the recordings are retimed to 40 steps


def test_pipeline_extracts_trains_reports_and_resumes(tmp_path, capsys):
    base = tmp_path / "base.yaml"
    base.write_text(yaml.safe_dump({"extends": "paper", **TINY}))
    out = tmp_path / "pipe"
    argv = ["pipeline", "-o", str(out), "--episodes", "2", "--conditions", "none,multi,demos",
            "--seeds", "0", "--workers", "2", "--config", str(base)]
    assert main(argv) == 0
    # constraints extracted from the shipped demonstrations: C1 one segment, C2&C3 two
    single = ConstraintSet.load(out / "constraints" / "single.yaml")
    multi = ConstraintSet.load(out / "constraints" / "multi.yaml")
    assert [s.subtasks for s in single.segments] == [("reach", "grasp", "align")]
    assert [s.subtasks for s in multi.segments] == [("reach", "grasp"), ("align",)]
    # the comparison used them (a copy in the comparison) and trained both runs
    comparison = load_manifest(out)
    assert comparison.constraints_dir == (out / "constraints").resolve()
    for name in ("none-seed0", "multi-seed0", "demos-seed0"):
        lines = (out / "runs" / name / "metrics.csv").read_text().splitlines()
        assert len(lines) == 1 + 2
    # demos: the shipped recordings on the multi constraints
    demos = TrainConfig.load_saved(out / "runs" / "demos-seed0" / "config.yaml")
    assert (demos.condition, demos.compared_condition) == ("multi", "demos")
    assert Path(demos.demos.folder) == DEFAULT_DEMO_DIR and demos.demos.episodes > 0
    html = (out / "report" / "index.html").read_text()
    assert "recordings as demonstrations" in html
    assert "fig6_return.png" in html and (out / "report" / "table.csv").exists()
    capsys.readouterr()
    # again: nothing to train, the report is rewritten
    assert main(argv) == 0
    assert "3 finished" in capsys.readouterr().err


def test_pipeline_stops_at_the_failing_step_and_names_it(tmp_path, capsys):
    out = tmp_path / "pipe"
    assert main(["pipeline", "-o", str(out), "--demos", str(tmp_path / "missing")]) == 2
    err = capsys.readouterr().err
    assert "stopped at step 1" in err and "missing" in err
    assert not (out / "runs").exists()


def test_pipeline_defaults_fill_a_new_comparison_and_leave_an_existing_one_alone(tmp_path):
    from dualarm.demos.formats import DEFAULT_DEMO_DIR
    from dualarm.experiments.compare import CompareRequest, prepare
    from dualarm.experiments.pipeline import (DEFAULT_EPISODES, DEFAULT_SEEDS, DEFAULT_STOP_AT,
                                              pipeline_request, planned_grid)

    out = tmp_path / "pipe"
    new = pipeline_request(out, CompareRequest())
    assert (new.seeds, new.episodes) == (DEFAULT_SEEDS, DEFAULT_EPISODES) == ((0,), 6000)
    assert new.stop_at == DEFAULT_STOP_AT == 0.85              # each run ends at the target
    assert pipeline_request(out, CompareRequest(stop_at="none")).stop_at == "none"
    assert planned_grid(out, new) == (("none", "single", "multi", "demos"), (0,))
    assert new.demos_dir == DEFAULT_DEMO_DIR                   # the recordings of the constraints
    plain = tmp_path / "plain"                                 # recordings without their scene
    plain.mkdir()
    assert planned_grid(out, pipeline_request(out, CompareRequest(), plain))[0] == (
        "none", "single", "multi")
    given = pipeline_request(out, CompareRequest(seeds=(4, 5), episodes=30))
    assert (given.seeds, given.episodes) == ((4, 5), 30)
    from dualarm.training import TrainConfig
    with_base = pipeline_request(out, CompareRequest(base=TrainConfig.paper().with_(episodes=40)))
    assert (with_base.seeds, with_base.episodes) == ((0,), None)     # the base's 40 stand
    assert with_base.stop_at is None                                 # ... and its stop_at
    prepare(out, CompareRequest(conditions=("none",), seeds=(1, 2), episodes=10000))
    # an existing comparison keeps its grid and budget (6000 would shorten its runs)
    assert pipeline_request(out, CompareRequest()) == CompareRequest()
    assert planned_grid(out, CompareRequest()) == (("none",), (1, 2))
    assert planned_grid(out, CompareRequest(conditions=("multi",), seeds=(0,))) == (
        ("none", "multi"), (0, 1, 2))


def test_pipeline_trains_every_run_at_once_by_default(tmp_path, monkeypatch, capsys):
    import dualarm.experiments.backends as backends

    asked = []

    def refuse(kind, workers=None, address=None):
        asked.append(workers)
        raise backends.InputError("stop here")

    monkeypatch.setattr(backends, "make_backend", refuse)
    monkeypatch.setattr("os.cpu_count", lambda: 2)
    assert main(["pipeline", "-o", str(tmp_path / "a")]) == 2
    assert main(["pipeline", "-o", str(tmp_path / "b"), "--seeds", "0,1"]) == 2
    assert main(["pipeline", "-o", str(tmp_path / "c"), "--conditions", "none"]) == 2
    assert main(["pipeline", "-o", str(tmp_path / "d"), "--workers", "1"]) == 2
    assert asked == [4, 8, 2, 1]            # the paper's three and demos, per seed
    assert "stop here" in capsys.readouterr().err
