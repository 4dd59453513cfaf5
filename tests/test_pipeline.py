"""`dualarm pipeline`: demonstrations -> constraints -> comparison -> report, and its resume."""

import yaml

from dualarm.cli.main import main
from dualarm.constraints.constraint_set import ConstraintSet
from dualarm.experiments.compare import load_manifest

TINY = {"num_envs": 2, "eval_every": 2, "eval_episodes": 2,
        "algo": {"hidden": [16, 16], "batch_size": 16, "warmup_steps": 0, "buffer_size": 2000},
        "task": {"max_episode_steps": 5}}


def test_pipeline_extracts_trains_reports_and_resumes(tmp_path, capsys):
    base = tmp_path / "base.yaml"
    base.write_text(yaml.safe_dump(TINY))
    out = tmp_path / "pipe"
    argv = ["pipeline", "-o", str(out), "--episodes", "2", "--conditions", "none,multi",
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
    for name in ("none-seed0", "multi-seed0"):
        lines = (out / "runs" / name / "metrics.csv").read_text().splitlines()
        assert len(lines) == 1 + 2
    html = (out / "report" / "index.html").read_text()
    assert "fig6_return.png" in html and (out / "report" / "table.csv").exists()
    capsys.readouterr()
    # again: nothing to train, the report is rewritten
    assert main(argv) == 0
    assert "2 finished" in capsys.readouterr().err


def test_pipeline_stops_at_the_failing_step_and_names_it(tmp_path, capsys):
    out = tmp_path / "pipe"
    assert main(["pipeline", "-o", str(out), "--demo-dir", str(tmp_path / "missing")]) == 2
    err = capsys.readouterr().err
    assert "stopped at step 1" in err and "missing" in err
    assert not (out / "runs").exists()
