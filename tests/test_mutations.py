"""Property tests: valid input files mutated at random (a line deleted or repeated, a value of
another type, NaN, a truncation, bytes that are not UTF-8) are either still read, or refused
with the project's one-line input error, never with another exception."""

from __future__ import annotations

import gzip
import shutil

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dualarm.cli.main import main
from dualarm.demos.labels import read_labels
from dualarm.constraints.constraint_set import ConstraintSet, default_constraints_path
from dualarm.errors import DualarmError
from dualarm.training import TrainConfig

DEMOS = default_constraints_path("multi").parent.parent / "demos"
CONFIG = ("condition: single\nepisodes: 40\nseed: 3\nnum_envs: 4\nstarts: {probs: [0.5, 0.25, 0.25]}\n"
          "replay: {her_share: 0.5}\ntask: {max_episode_steps: 20, guide_c0: [0.01, 0.01, 0.05]}\n"
          "algo: {hidden: [64, 64], gamma: 0.98, reward_scale: 0.01, twin_critics: true}\n")
REPLACEMENTS = [b"", b"x", b"nan", b".nan", b"inf", b"-1", b"0", b"1e400", b"true", b"[1, 2]",
                b"{a: 1}", b"null", b",", b"\"", b"\xff\xfe", b"\x00", b"   "]
SETTINGS = settings(max_examples=40, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])


@st.composite
def mutated(draw, original: bytes) -> bytes:
    """``original`` with one random edit."""
    lines = original.split(b"\n")
    kind = draw(st.sampled_from(["delete", "repeat", "replace", "truncate", "insert"]))
    k = draw(st.integers(0, len(lines) - 1))
    if kind == "delete":
        del lines[k]
    elif kind == "repeat":
        lines.insert(k, lines[k])
    elif kind == "truncate":
        return original[:draw(st.integers(0, len(original) - 1))]
    else:
        line = lines[k]
        cells = line.replace(b":", b",").split(b",")
        j = draw(st.integers(0, max(0, len(cells) - 1)))
        new = draw(st.sampled_from(REPLACEMENTS))
        if kind == "replace" and cells[j]:
            start = line.find(cells[j])
            lines[k] = line[:start] + new + line[start + len(cells[j]):]
        else:
            at = draw(st.integers(0, len(line)))
            lines[k] = line[:at] + new + line[at:]
    return b"\n".join(lines)


def survives(call) -> None:
    """``call()`` succeeds or raises the project's input error; anything else fails the test."""
    try:
        call()
    except DualarmError as exc:
        assert "\n" not in str(exc).strip(), str(exc)


def runs_or_refuses(argv: list[str], out) -> None:
    """The command succeeds (0) or refuses its input (2) and then leaves no partial ``out``."""
    out.unlink(missing_ok=True)            # tmp_path is shared by the examples
    code = main(argv)
    assert code in (0, 2)
    if code == 2:
        assert not out.exists()


def short_recording() -> bytes:
    """The first 3 s of a shipped demonstration (IMU quaternions at 100 Hz, 6 sensors)."""
    lines = gzip.decompress((DEMOS / "demo_00.csv.gz").read_bytes()).split(b"\n")
    return b"\n".join(lines[:301]) + b"\n"


@SETTINGS
@given(data=st.data())
def test_a_mutated_recording_maps_or_is_refused(data, tmp_path):
    path = tmp_path / "rec.csv"
    path.write_bytes(data.draw(mutated(short_recording())))
    out = tmp_path / "joints.csv"
    runs_or_refuses(["mocap", "joints", str(path), "-o", str(out), "-q"], out)


@SETTINGS
@given(data=st.data())
def test_a_mutated_labels_file_reads_or_is_refused(data, tmp_path):
    path = tmp_path / "labels.csv"
    path.write_bytes(data.draw(mutated((DEMOS / "labels.csv").read_bytes())))
    survives(lambda: read_labels(path))


@SETTINGS
@given(data=st.data())
def test_a_mutated_constraints_file_loads_or_is_refused(data, tmp_path):
    path = tmp_path / "c.yaml"
    path.write_bytes(data.draw(mutated(default_constraints_path("multi").read_bytes())))
    survives(lambda: ConstraintSet.load(path))


@SETTINGS
@given(data=st.data())
def test_a_mutated_training_config_loads_or_is_refused(data, tmp_path):
    path = tmp_path / "config.yaml"
    path.write_bytes(data.draw(mutated(CONFIG.encode())))
    survives(lambda: TrainConfig.load(path).task_config())


VARIANT = "extends: base.yaml\nepisodes: 30\nalgo: {batch_size: 64}\ntask: {max_episode_steps: 30}\n"
# Edits the config reader's own paths meet: a base that names itself or a missing file, anchors,
# aliases and merge keys (refused: an alias bomb expands a few lines into billions of values).
CONFIG_EDITS = [b"extends: variant.yaml", b"extends: missing.yaml", b"extends: paper", b"extends: ..",
                b"&a", b"*a", b"<<: *a", b"extends: [base.yaml]", b"extends: {a: 1}"]


@st.composite
def mutated_config(draw, original: bytes) -> bytes:
    """``original`` with one random edit, or with a line of the reader's own edits inserted."""
    if draw(st.booleans()):
        return draw(mutated(original))
    lines = original.split(b"\n")
    lines.insert(draw(st.integers(0, len(lines))), draw(st.sampled_from(CONFIG_EDITS)))
    return b"\n".join(lines)


@SETTINGS
@given(data=st.data())
def test_a_mutated_extends_chain_loads_or_is_refused(data, tmp_path):
    """A variant file and the base it extends, either one mutated (the extends line included)."""
    base, variant = tmp_path / "base.yaml", tmp_path / "variant.yaml"
    texts = {base: CONFIG.encode(), variant: VARIANT.encode()}
    target = data.draw(st.sampled_from([base, variant]))
    texts[target] = data.draw(mutated_config(texts[target]))
    for path, text in texts.items():
        path.write_bytes(text)
    survives(lambda: TrainConfig.load(variant).task_config())


def trajectory_csv() -> bytes:
    """A valid 2-s trajectory of 11 points in our CSV layout (joints within Baxter's limits)."""
    import numpy as np

    from dualarm.export.trajectory import JointTrajectory, trajectory_csv_text

    t = np.linspace(0.0, 2.0, 11)
    q = np.outer(np.sin(np.pi * t / 2.0), np.full(14, 0.3)) + np.r_[[0.0] * 3, [0.5], [0.0] * 6, [0.5], [0.0] * 3]
    g = np.stack([t > 1.0, t > 1.2], axis=1).astype(float)
    return trajectory_csv_text(JointTrajectory(t, q, g)).encode()


@SETTINGS
@given(data=st.data())
def test_a_mutated_trajectory_exports_or_is_refused(data, tmp_path):
    path = tmp_path / "traj.csv"
    path.write_bytes(data.draw(mutated(trajectory_csv())))
    out = tmp_path / "baxter.csv"
    runs_or_refuses(["export", str(path), "--format", "baxter", "-o", str(out)], out)


def suit_files(tmp_path) -> dict[str, bytes]:
    """A valid short BVH and MVNX recording (the writers of tests/test_suits.py)."""
    from test_suits import joint_path, write_bvh, write_mvnx

    t, q = joint_path("tpose", seconds=1.5, hold=1.0)
    write_bvh(tmp_path / "orig.bvh", t, q)
    write_mvnx(tmp_path / "orig.mvnx", t, q)
    return {ext: (tmp_path / f"orig{ext}").read_bytes() for ext in (".bvh", ".mvnx")}


@SETTINGS
@given(data=st.data())
def test_a_mutated_suit_recording_reads_or_is_refused(data, tmp_path):
    from dualarm.mocap.io import read_recording

    originals = suit_files(tmp_path)
    ext = data.draw(st.sampled_from(sorted(originals)))
    path = tmp_path / f"rec{ext}"
    path.write_bytes(data.draw(mutated(originals[ext])))
    survives(lambda: read_recording(path))


@pytest.mark.parametrize("name", ["rec.csv"])
def test_the_unmutated_files_are_valid(name, tmp_path):
    """The originals themselves load (so that the properties above test the mutations)."""
    (tmp_path / name).write_bytes(short_recording())
    assert main(["mocap", "joints", str(tmp_path / name), "-o", str(tmp_path / "j.csv"), "-q"]) == 0
    (tmp_path / "c.yaml").write_text(CONFIG)
    assert TrainConfig.load(tmp_path / "c.yaml").starts.probs == (0.5, 0.25, 0.25)
    assert len(read_labels(DEMOS / "labels.csv")) == 10
    shutil.copy(default_constraints_path("multi"), tmp_path / "m.yaml")
    assert ConstraintSet.load(tmp_path / "m.yaml").name == "multi"
    (tmp_path / "base.yaml").write_text(CONFIG)
    (tmp_path / "variant.yaml").write_text(VARIANT)
    assert TrainConfig.load(tmp_path / "variant.yaml").task_config().max_episode_steps == 30
    (tmp_path / "traj.csv").write_bytes(trajectory_csv())
    assert main(["export", str(tmp_path / "traj.csv"), "--format", "baxter", "-o", str(tmp_path / "b.csv")]) == 0
    from dualarm.mocap.io import read_recording

    for ext, text in suit_files(tmp_path).items():
        (tmp_path / f"s{ext}").write_bytes(text)
        assert read_recording(tmp_path / f"s{ext}").n_samples == 90
