"""Hostile and careless input, command by command: one line, exit 2, nothing changed on disk.

Each case is one row of ``CASES``: the command line (run in a copy of a small world of
valid files: a recording, a constraints file, a finished run, a config), files to add or
break first, the phrase the one-line error must contain, and the exit code. Unless a case
says otherwise, every file of the world must be byte for byte what it was (the lock file,
which records its latest holder, aside). Add a case in one line.
"""

from __future__ import annotations

import contextlib
import hashlib
import shlex
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import pytest

from dualarm.cli.main import main
from dualarm.constraints.constraint_set import default_constraints_path
from dualarm.locks import LOCK_NAME, DirectoryLock
from dualarm.mocap.io import write_csv
from dualarm.mocap.synthetic import example_recording
from dualarm.training import TrainConfig, train

TINY = {"num_envs": 2, "episodes": 2, "eval_every": 2, "eval_episodes": 2,
        "algo": {"hidden": [16, 16], "batch_size": 16, "warmup_steps": 0, "buffer_size": 2000},
        "task": {"max_episode_steps": 5}}
GOOD_CONFIG = "extends: paper\nnum_envs: 2\neval_every: 0\nepisodes: 1\nalgo: {hidden: [16, 16], batch_size: 16}\n"


@pytest.fixture(scope="module")
def world(tmp_path_factory) -> Path:
    """The valid files every case starts from."""
    root = tmp_path_factory.mktemp("world")
    write_csv(example_recording(), root / "rec.csv")
    shutil.copy(default_constraints_path("multi"), root / "c.yaml")
    (root / "good.yaml").write_text(GOOD_CONFIG)
    train(TrainConfig.from_dict(TINY, base=TrainConfig.paper()), root / "run", progress=False)
    return root


def snapshot(root: Path) -> dict[str, str]:
    """Relative path -> sha256 of every file under ``root`` (lock files aside)."""
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file() and p.name != LOCK_NAME}


def hold_lock(folder: str) -> Callable[[Path], contextlib.AbstractContextManager]:
    """A case's ``during``: another writer holds ``folder`` while the command runs."""
    return lambda root: DirectoryLock(root / folder, "dualarm train")


@dataclass
class Case:
    id: str
    argv: str                          # the command line after `dualarm`, run in the case's folder
    phrase: str                        # must be in the one-line error
    files: dict[str, str | bytes | None] = field(default_factory=dict)   # None deletes
    during: Callable[[Path], contextlib.AbstractContextManager] | None = None
    code: int = 2


def config(text: str) -> dict[str, str]:
    return {"bad.yaml": text}


CASES = [
    # ---- train: every field of a config file is type-checked at load, named with the file
    Case("train-episodes-zero", "train --episodes 0 --out r", "must be at least 1"),
    Case("train-episodes-word", "train --episodes ten --out r", "not an integer"),
    Case("config-episodes-float", "train --config bad.yaml --out r", "bad.yaml: episodes: expected an integer, got 2.5",
         config("episodes: 2.5\n")),
    Case("config-episodes-string", "train --config bad.yaml --out r", "episodes: expected an integer, got 'ten'",
         config("episodes: ten\n")),
    Case("config-episodes-bool", "train --config bad.yaml --out r", "episodes: expected an integer, got true",
         config("episodes: true\n")),
    Case("config-episodes-negative", "train --config bad.yaml --out r", "episodes must be at least 1",
         config("episodes: -1\n")),
    Case("config-episodes-list", "train --config bad.yaml --out r", "episodes: expected an integer",
         config("episodes: [1]\n")),
    Case("config-num-envs-zero", "train --config bad.yaml --out r", "num_envs must be at least 1",
         config("num_envs: 0\n")),
    Case("config-seed-string", "train --config bad.yaml --out r", "seed: expected an integer", config("seed: x\n")),
    Case("config-condition", "train --config bad.yaml --out r", "condition must be one of", config("condition: maybe\n")),
    Case("config-unknown-field", "train --config bad.yaml --out r", "unknown field(s) ['epsiodes']",
         config("epsiodes: 3\n")),
    Case("config-not-mapping", "train --config bad.yaml --out r", "expected a mapping", config("- 1\n- 2\n")),
    Case("config-not-yaml", "train --config bad.yaml --out r", "YAML syntax error at line 2", config("episodes: [\n")),
    Case("config-not-utf8", "train --config bad.yaml --out r", "bad.yaml", config(b"episodes: \xff\xfe\n")),
    Case("config-missing", "train --config nope.yaml --out r", "nope.yaml"),
    Case("train-seed-negative", "train --seed -1 --out r", "seed must be in 0..4294967295"),
    Case("train-seed-huge", "train --seed 18446744073709551616 --out r", "seed must be in 0.."),
    Case("demos-generate-seed-negative", "demos generate -o d --seed -1", "--seed: must be in 0..4294967295"),
    Case("constraints-analyze-seed-negative", "constraints analyze c.yaml --seed -1",
         "--seed: must be in 0..4294967295"),
    Case("video-extension", "env video -o v.avi", "a video must end in .mp4 or .gif"),
    Case("video-width-zero", "env video --width 0 -o v.mp4", "--width: must be at least 1"),
    Case("video-height-huge", "env video --height 100000 -o v.mp4", "at most 4096 pixels"),
    Case("video-fps-nan", "env video --fps nan -o v.mp4", "--fps: must be finite"),
    Case("play-fps-zero", "play run -o v.gif --fps 0", "--fps: must be a number > 0"),
    Case("config-eval-every-float", "train --config bad.yaml --out r", "eval_every: expected an integer",
         config("eval_every: 0.5\n")),
    Case("config-checkpoint-minutes", "train --config bad.yaml --out r", "checkpoint_minutes must be > 0",
         config("checkpoint_minutes: 0\n")),
    Case("config-her-share", "train --config bad.yaml --out r", "replay: her_share must be in [0, 1]", config("replay: {her_share: 2}\n")),
    Case("config-start-probs-short", "train --config bad.yaml --out r", "starts: probs: expected a list of 3 numbers",
         config("starts: {probs: [0.5, 0.5]}\n")),
    Case("config-start-probs-sum", "train --config bad.yaml --out r", "sum to 1", config("starts: {probs: [0.5, 0.6, 0.1]}\n")),
    Case("config-algo-scalar", "train --config bad.yaml --out r", "algo: expected a mapping", config("algo: 5\n")),
    Case("config-algo-hidden", "train --config bad.yaml --out r", "algo: hidden: expected a list of integers",
         config("algo: {hidden: [64, x]}\n")),
    Case("config-algo-gamma", "train --config bad.yaml --out r", "algo: gamma: invalid value 1.5",
         config("algo: {gamma: 1.5}\n")),
    Case("config-algo-nan", "train --config bad.yaml --out r", "algo: actor_lr: expected a number, got nan",
         config("algo: {actor_lr: .nan}\n")),
    Case("config-algo-unknown", "train --config bad.yaml --out r", "unknown DADDPG field(s) ['lr']",
         config("algo: {lr: 0.1}\n")),
    Case("config-task-c0", "train --config bad.yaml --out r", "task: guide_c0: expected a list of 3 numbers",
         config("task: {guide_c0: [1, 2]}\n")),
    Case("config-task-control", "train --config bad.yaml --out r", "task: control must be one of",
         config("task: {control: warp}\n")),
    Case("config-task-unknown", "train --config bad.yaml --out r", "not supported", config("task: {scene: 1}\n")),
    Case("config-task-bool", "train --config bad.yaml --out r", "task: terminate_on_success: expected true or false",
         config("task: {terminate_on_success: 1}\n")),
    Case("train-constraints-missing", "train --condition multi --constraints nope.yaml --out r", "nope.yaml"),
    Case("train-multi-constraints-for-single", "train --condition single --constraints c.yaml --out r",
         "c.yaml: condition 'single' needs one segment"),
    Case("train-constraints-for-none", "train --condition none --constraints c.yaml --out r", "needs --condition"),
    Case("train-constraints-not-yaml", "train --condition multi --constraints bad.yaml --out r", "bad.yaml",
         {"bad.yaml": "segments: [\n"}),
    Case("train-out-is-file", "train --config good.yaml --out rec.csv", "is an existing file"),
    Case("train-out-holds-run", "train --config good.yaml --out run", "already holds a run"),
    Case("train-out-busy", "train --config good.yaml --out fresh", "in use by dualarm train", during=hold_lock("fresh")),
    # ---- resume: continues the same run exactly, or changes nothing and says why
    Case("resume-nothing", "train --resume nowhere", "no run to resume"),
    Case("resume-fewer-episodes", "train --resume run --episodes 1", "has done 2 episodes, more than --episodes 1"),
    Case("resume-metrics-deleted", "train --resume run --episodes 3", "metrics.csv is missing",
         {"run/metrics.csv": None}),
    Case("resume-metrics-interleaved", "train --resume run --episodes 3", "out of order",
         {"run/metrics.csv": lambda text: _swap_rows(text)}),
    Case("resume-metrics-short", "train --resume run --episodes 3", "complete rows",
         {"run/metrics.csv": lambda text: "\n".join(text.splitlines()[:2]) + "\n"}),
    Case("resume-eval-columns", "train --resume run --episodes 3", "columns",
         {"run/eval.csv": "a,b\n1,2\n"}),
    Case("resume-checkpoint-corrupt", "train --resume run --episodes 3", "latest.pt: not a checkpoint",
         {"run/checkpoints/latest.pt": b"not a checkpoint"}),
    Case("resume-config-edited", "train --resume run --episodes 3", "different settings (seed)",
         {"run/config.yaml": lambda text: text.replace("seed: 0", "seed: 5")}),
    Case("resume-config-broken", "train --resume run --episodes 3", "config.yaml: episodes: expected an integer",
         {"run/config.yaml": lambda text: text.replace("episodes: 2", "episodes: two")}),
    Case("resume-constraints-deleted", "train --resume run --episodes 3", "constraints.yaml",
         {"run/constraints.yaml": None}),
    Case("resume-busy", "train --resume run --episodes 3", "in use by dualarm train", during=hold_lock("run")),
    # ---- outputs never destroy inputs or run files
    Case("joints-onto-input", "mocap joints rec.csv -o rec.csv", "--output is also the input INPUT"),
    Case("joints-two-outputs", "mocap joints rec.csv -o a.csv --residuals a.csv", "name the same file"),
    Case("joints-output-folder", "mocap joints rec.csv -o run", "is a folder"),
    Case("joints-into-run", "mocap joints rec.csv -o run/metrics.csv", "is a file of the run directory"),
    Case("joints-missing-input", "mocap joints nope.csv -o a.csv", "nope.csv"),
    Case("joints-not-utf8", "mocap joints bad.csv -o a.csv", "bad.csv", {"bad.csv": b"time,\xff\xfe\n1,2\n"}),
    Case("joints-empty-input", "mocap joints bad.csv -o a.csv", "bad.csv", {"bad.csv": ""}),
    Case("plot-output-is-file", "mocap plot rec.csv -o c.yaml", "is an existing file"),
    Case("example-into-run", "mocap example -o run/eval.csv", "is a file of the run directory"),
    Case("example-into-checkpoints", "mocap example -o run/checkpoints/x.csv", "is a file of the run directory"),
    Case("quickstart-output-is-file", "quickstart -o rec.csv", "is an existing file"),
    Case("export-onto-metrics", "export run -o run/metrics.csv", "is a file of the run directory"),
    Case("export-onto-config", "export run -o run/config.yaml", "is a file of the run directory"),
    Case("export-onto-run", "export run -o run", "is also the input RUN_OR_CSV"),
    Case("export-onto-existing", "export run -o rec.csv --format baxter", "exists already"),
    Case("export-bag-onto-folder", "export run -o run/checkpoints --format ros2", "exists already"),
    Case("export-onnx-of-a-file", "export rec.csv -o p.onnx --format onnx", "exports a run's policy"),
    Case("play-onto-curves", "play run -o run/events/v.gif", "is a file of the run directory"),
    Case("eval-not-a-run", "eval rec.csv", "not a run directory"),
    Case("eval-best-corrupt", "eval run", "best_policy.pt: not a checkpoint", {"run/checkpoints/best_policy.pt": b"\x00" * 10}),
    Case("constraints-plot-onto-input", "constraints plot c.yaml -o c.yaml", "is also the input"),
    Case("constraints-plot-missing", "constraints plot nope.yaml -o f.png", "nope.yaml"),
    Case("constraints-plot-inverted", "constraints plot bad.yaml -o f.png", "bad.yaml",
         {"bad.yaml": lambda _: _inverted_constraints()}),
    Case("constraints-analyze-output-file", "constraints analyze c.yaml -o rec.csv", "is an existing file"),
    Case("compare-output-is-file", "compare --conditions none --seeds 0 -o rec.csv", "is an existing file"),
    Case("compare-bad-seeds", "compare --seeds x -o cmp", "expected integers"),
    Case("compare-bad-condition", "compare --conditions bogus -o cmp", "bogus"),
    Case("compare-bad-config", "compare --config bad.yaml -o cmp", "bad.yaml: episodes: expected an integer",
         config("episodes: 2.5\n")),
    Case("compare-busy", "compare --conditions none --seeds 0 -o cmp", "in use by", during=hold_lock("cmp")),
    Case("demos-generate-output-is-file", "demos generate -o rec.csv --count 1", "is an existing file"),
    Case("demos-generate-count-zero", "demos generate -o d --count 0", "must be at least 1"),
    Case("demos-segment-labels-onto-labels", "demos segment --labels labels.csv -o labels.csv", "is also the input",
         {"labels.csv": "demo,arm,subtask,start_s,end_s\n"}),
    Case("extract-onto-run-file", "constraints extract -o run/constraints.yaml", "is a file of the run directory"),
    Case("extract-labels-missing", "constraints extract --labels nope.csv -o x.yaml", "nope.csv"),
    Case("extract-bad-segments", "constraints extract --segments reach+fly -o x.yaml", "fly"),
    Case("env-video-onto-run-file", "env video -o run/checkpoints/v.mp4", "is a file of the run directory"),
    Case("env-strip-output-folder", "env strip -o run", "is a folder"),
    Case("env-constraints-missing", "env strip --condition multi --constraints nope.yaml -o s.png", "nope.yaml"),
    Case("pipeline-output-is-file", "pipeline -o rec.csv", "is an existing file"),
    Case("report-onto-input", "report run -o run", "is also the input"),
    # ---- sizes: numbers that decide the work are bounded before anything is allocated
    Case("export-rate-huge", "export run -o o.csv --format baxter --rate 1e15", "at most 1000.0 Hz"),
    Case("export-velocity-scale-tiny", "export run -o o.csv --format baxter --velocity-scale 1e-300",
         "must be in [0.01, 1]"),
    Case("export-time-span-huge", "export span.csv -o o.csv --format baxter", "span.csv: column time spans 1e+09 s",
         {"span.csv": "time," + ",".join(f"{a}_{j}" for a in ("left", "right")
                                          for j in ("s0", "s1", "e0", "e1", "w0", "w1", "w2"))
          + ",grip_left,grip_right\n0" + ",0" * 16 + "\n1e9" + ",0.1" * 14 + ",0,0\n"}),
    Case("config-hidden-huge", "train --config bad.yaml --out r", "hidden: invalid value (1000000000000,) (1 to 8 layers",
         config("algo: {hidden: [1000000000000]}\n")),
    Case("config-buffer-huge", "train --config bad.yaml --out r", "buffer_size: invalid value",
         config("algo: {buffer_size: 100000000000}\n")),
    Case("report-missing", "report nowhere", "nowhere"),
]


def _swap_rows(text: str) -> str:
    lines = text.splitlines()
    lines[1], lines[2] = lines[2], lines[1]
    return "\n".join(lines) + "\n"


def _inverted_constraints() -> str:
    text = default_constraints_path("multi").read_text()
    start = text.index("lower:")
    return text[:start] + "lower: [3" + text[text.index(",", start):]


def _apply(root: Path, files: dict) -> None:
    for name, content in files.items():
        path = root / name
        if content is None:
            path.unlink()
        elif callable(content):
            path.write_text(content(path.read_text() if path.exists() else ""))
        elif isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content)


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_hostile_input_gets_one_line_and_changes_nothing(case, world, tmp_path, monkeypatch, capsys):
    root = tmp_path / "w"
    shutil.copytree(world, root)
    _apply(root, case.files)
    before = snapshot(root)
    monkeypatch.chdir(root)
    holder = case.during(root) if case.during else contextlib.nullcontext()
    with holder:
        try:
            code = main(shlex.split(case.argv))
        except SystemExit as exc:          # argparse's own errors
            code = exc.code
    err = capsys.readouterr().err
    assert code == case.code, err
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.startswith("dualarm")]
    assert lines and case.phrase in lines[-1], err
    assert snapshot(root) == before
    if case.during is None:           # and no lock file left where there was no folder
        assert not (root / "r").exists() and not (root / "fresh").exists()


def test_there_are_enough_hostile_cases():
    assert len(CASES) >= 60 and len({c.id for c in CASES}) == len(CASES)


def test_a_run_resumes_from_anywhere_after_being_moved(world, tmp_path, monkeypatch):
    """A run started with a relative --constraints path keeps its own copy, so it resumes
    from another working directory after being moved (issue: a run that cannot move)."""
    start, other = tmp_path / "start", tmp_path / "other"
    start.mkdir(), other.mkdir()
    shutil.copy(world / "c.yaml", tmp_path / "base.yaml")
    (start / "tiny.yaml").write_text(GOOD_CONFIG.replace("episodes: 1", "episodes: 2"))
    monkeypatch.chdir(start)
    assert main(["train", "--config", "tiny.yaml", "--condition", "multi", "--constraints",
                 "../base.yaml", "--out", "r"]) == 0
    shutil.move(start / "r", tmp_path / "moved")
    (tmp_path / "base.yaml").unlink()                       # the original is gone too
    monkeypatch.chdir(other)
    assert main(["train", "--resume", str(tmp_path / "moved"), "--episodes", "4"]) == 0
    lines = (tmp_path / "moved" / "metrics.csv").read_text().splitlines()[1:]
    assert [int(line.split(",")[0]) for line in lines] == [1, 2, 3, 4]
    assert ((tmp_path / "moved" / "constraints.yaml").read_bytes()
            == (world / "c.yaml").read_bytes())


def test_the_command_line_knows_every_file_of_a_run_directory(world):
    """cli_types spells out a run directory's own names (to keep torch out of its imports):
    they must be RunPaths' names, and the done marker's."""
    from dualarm.cli.arguments import RUN_FILES, RUN_FOLDERS
    from dualarm.experiments.backends import DONE_MARKER
    from dualarm.training.run_dir import RunPaths

    paths = RunPaths(world / "run")
    own = {p.name for p in vars(paths).values() if isinstance(p, Path) and p.parent == paths.root}
    assert own == set(RUN_FILES + RUN_FOLDERS) - {LOCK_NAME, DONE_MARKER}
    assert {p.name for p in (world / "run").iterdir()} <= set(RUN_FILES + RUN_FOLDERS)


def test_config_reader_refuses_nul_paths_endless_extends_and_yaml_aliases(tmp_path):
    """One line naming the file for an `extends` holding NUL, a chain of bases deeper than
    MAX_EXTENDS_DEPTH, and a YAML alias (a few lines of nested aliases expand into billions of
    values); nothing is written."""
    from dualarm.errors import InputError
    from dualarm.training.config import MAX_EXTENDS_DEPTH

    (tmp_path / "nul.yaml").write_text('extends: "base\\0.yaml"\n')
    for i in range(MAX_EXTENDS_DEPTH + 5):
        (tmp_path / f"c{i}.yaml").write_text(f"extends: c{i + 1}.yaml\n")
    (tmp_path / f"c{MAX_EXTENDS_DEPTH + 5}.yaml").write_text("episodes: 3\n")
    (tmp_path / "bomb.yaml").write_text("a: &a [1, 1, 1, 1, 1, 1, 1, 1, 1]\n"
                                        "episodes: [*a, *a, *a, *a, *a, *a, *a, *a, *a]\n")
    for name, message in (("nul.yaml", "NUL"), ("c0.yaml", "chain of bases"),
                          ("bomb.yaml", "aliases")):
        out = tmp_path / f"run-{name}"
        with pytest.raises(InputError, match=message) as caught:
            TrainConfig.load(tmp_path / name)
        assert name in str(caught.value) or f"c{MAX_EXTENDS_DEPTH}" in str(caught.value)
        assert main(["train", "--config", str(tmp_path / name), "--episodes", "1",
                     "--out", str(out)]) == 2
        assert not out.exists()


def test_symlink_loops_and_empty_checkpoints_get_one_line(tmp_path, capsys):
    """A symlink loop given as any path, and a zero-byte checkpoint, end in one line naming
    the path (the error's own message code once failed on the empty message)."""
    (tmp_path / "loop1").symlink_to(tmp_path / "loop2")
    (tmp_path / "loop2").symlink_to(tmp_path / "loop1")
    loop = str(tmp_path / "loop1")
    for argv in (["eval", loop], ["train", "--out", f"{loop}/x", "--episodes", "1"],
                 ["train", "--resume", loop], ["report", loop], ["mocap", "example", "-o", loop]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "cannot be resolved" in err and "loop1" in err, err
    from dualarm.training.run_dir import CheckpointError, load_checkpoint

    empty = tmp_path / "latest.pt"
    empty.write_bytes(b"")
    with pytest.raises(CheckpointError, match=r"latest\.pt: .*cannot be read \(0 bytes\)"):
        load_checkpoint(empty)


def test_compare_and_report_leave_a_training_runs_directory_alone(tmp_path, capsys):
    """compare -o RUN is refused before anything is written; report RUN writes RUN-report."""
    run = tmp_path / "run"
    assert main(["train", "--config", "paper", "--episodes", "1", "--num-envs", "1",
                 "--condition", "none", "-o", str(run)]) == 0
    before = sorted(p.name for p in run.iterdir())
    assert main(["compare", "--conditions", "none", "--seeds", "0", "--episodes", "1",
                 "-o", str(run)]) == 2
    assert "directory of a training run" in capsys.readouterr().err
    assert main(["report", str(run)]) == 0
    assert sorted(p.name for p in run.iterdir()) == before
    assert (tmp_path / "run-report" / "index.html").is_file()


def test_a_resume_clears_the_temporary_file_of_a_checkpoint_write_killed_mid_way(tmp_path):
    run = tmp_path / "run"
    assert main(["train", "--config", "paper", "--episodes", "1", "--num-envs", "1",
                 "--condition", "none", "-o", str(run)]) == 0
    litter = run / "checkpoints" / ".latest.0123456789ab.tmp.pt"
    litter.write_bytes(b"half a checkpoint")
    keep = run / "checkpoints" / "notes.tmp.txt"                    # not atomic_path's: kept
    keep.write_text("mine")
    assert main(["train", "--resume", str(run), "--episodes", "2"]) == 0
    assert not litter.exists() and keep.exists()


def test_a_failed_start_leaves_no_folders_it_made(tmp_path):
    """train -o x/y/r with a bad constraints file: no x/, no x/y/ left behind; a folder that
    was there before stays."""
    bad = tmp_path / "bad.yaml"
    bad.write_text("garbage: [\n")
    (tmp_path / "kept").mkdir()
    for out in (tmp_path / "x" / "y" / "r", tmp_path / "kept" / "y" / "r"):
        assert main(["train", "--constraints", str(bad), "-o", str(out), "--episodes", "1"]) == 2
    assert not (tmp_path / "x").exists()
    assert (tmp_path / "kept").is_dir() and not any((tmp_path / "kept").iterdir())


def test_an_unreachable_ray_cluster_is_refused_before_anything_is_written(tmp_path, capsys):
    import socket

    with socket.socket() as s:                     # a free port with nothing listening
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out = tmp_path / "cmp"
    assert main(["compare", "--backend", "ray", "--ray-address", f"127.0.0.1:{port}",
                 "--conditions", "none", "--seeds", "0", "--episodes", "1", "-o", str(out)]) == 2
    assert "nothing answers there" in capsys.readouterr().err and not out.exists()


def test_seeds_beyond_numpys_range_are_refused_where_they_are_given(tmp_path, capsys):
    """compare --seeds 2**64 (was accepted, then its worker crashed), export/play --seed -1
    (a traceback): one line each, nothing written."""
    out = tmp_path / "cmp"
    assert main(["compare", "--seeds", str(2 ** 64), "--conditions", "none", "-o", str(out)]) == 2
    assert "0..4294967295" in capsys.readouterr().err and not out.exists()
    for argv in (["export", str(tmp_path / "t.csv"), "-o", str(tmp_path / "o.csv"), "--seed", "-1"],
                 ["play", str(tmp_path), "-o", str(tmp_path / "v.mp4"), "--seed", "-1"]):
        with pytest.raises(SystemExit) as exit_:
            main(argv)
        assert exit_.value.code == 2 and "--seed: must be in 0.." in capsys.readouterr().err


def test_a_seed_range_that_runs_past_the_largest_seed_is_refused(capsys):
    """constraints analyze --seed S --episodes N uses seeds S..S+N-1: the range, not only S,
    must stay within 0..2**32-1 (was a numpy traceback after the progress bar started)."""
    from dualarm.constraints.constraint_set import default_constraints_path

    argv = ["constraints", "analyze", str(default_constraints_path("multi")), "--seed", str(2 ** 32 - 2),
            "--episodes", "3", "-q"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "4294967294..4294967296" in err and len(err.strip().splitlines()) == 1


def test_a_write_that_fails_names_its_file_and_keeps_the_previous_version(tmp_path):
    """Under a file-size limit (as on a full disk) a command's output write fails: one line
    naming the file, exit 2, and the file it would have replaced untouched."""
    import resource
    import subprocess
    import sys

    out = tmp_path / "rec.csv"
    out.write_text("the previous version\n")
    limit = lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))   # noqa: E731
    done = subprocess.run([sys.executable, "-m", "dualarm.cli.main", "mocap", "example", "-o",
                           str(tmp_path / "new.csv")],
                          capture_output=True, text=True, preexec_fn=limit, timeout=120)
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    assert "new.csv: could not be written (File too large" in done.stderr.strip().splitlines()[-1]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec.csv"]           # no litter
    from dualarm.atomic import atomic_open
    from dualarm.errors import WriteError

    def fail(*_a, **_k):
        raise OSError(27, "File too large")

    with pytest.raises(WriteError, match="rec.csv: could not be written"):
        with atomic_open(out) as f:
            f.write(b"new")
            fail()
    assert out.read_text() == "the previous version\n"
