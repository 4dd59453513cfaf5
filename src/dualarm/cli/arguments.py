"""argparse value types shared by the `dualarm` subcommands (one clear message per bad value)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from dualarm.locks import LOCK_NAME
from dualarm.task import MAX_SEED


def _number(text: str, kind=float):
    try:
        value = kind(text)
    except ValueError:
        what = "an integer" if kind is int else "a number"
        raise argparse.ArgumentTypeError(f"not {what}: {text!r}") from None
    if kind is float and not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return value


def positive_int(text: str) -> int:
    """An integer >= 1 (episodes, workers, counts)."""
    value = _number(text, int)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {text!r}")
    return value


def seed_number(text: str) -> int:
    """A seed: an integer in 0..``MAX_SEED``."""
    value = _number(text, int)
    if not 0 <= value <= MAX_SEED:
        raise argparse.ArgumentTypeError(f"must be in 0..{MAX_SEED}, got {text!r}")
    return value


def _at_most(value, bound, unit: str, text: str):
    """``value`` if it is at most ``bound`` (the work or the file grows with it), else the
    argument error naming the bound in ``unit``."""
    if value > bound:
        raise argparse.ArgumentTypeError(f"must be at most {bound} {unit}, got {text!r}")
    return value


def pixels(text: str) -> int:
    """An image side in pixels: an integer in 1..``MAX_PIXELS``."""
    return _at_most(positive_int(text), MAX_PIXELS, "pixels", text)


def frame_rate(text: str) -> float:
    """Frames per second of a video: a finite number in (0, ``MAX_FPS``]."""
    return _at_most(positive(text), MAX_FPS, "frames per second", text)


#: Bounds of the rendering options: the work and the file grow with them.
MAX_PIXELS, MAX_FPS = 4096, 240


def non_negative(text: str) -> float:
    """A finite number >= 0 (seconds, radians, hertz)."""
    value = _number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a number >= 0, got {text!r}")
    return value


def positive(text: str) -> float:
    """A finite number > 0."""
    value = _number(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be a number > 0, got {text!r}")
    return value


def limit_scale(text: str) -> float:
    """A fraction of the robot's limits: a number in [``MIN_SCALE``, 1]."""
    from dualarm.export.retime import MIN_SCALE

    value = _number(text)
    if not MIN_SCALE <= value <= 1:
        raise argparse.ArgumentTypeError(f"must be in [{MIN_SCALE}, 1], got {text!r}")
    return value


def sample_rate(text: str) -> float:
    """Samples per second of an exported trajectory: a number in (0, ``MAX_RATE_HZ``]."""
    return _at_most(positive(text), MAX_RATE_HZ, "Hz", text)


#: Fastest export rate: 10 times Baxter's 100 Hz joint_recorder, and more than any command
#: interface takes.
MAX_RATE_HZ = 1000.0


def rate(text: str) -> float:
    """A success rate in (0, 1]."""
    value = _number(text)
    if not 0 < value <= 1:
        raise argparse.ArgumentTypeError(f"must be a success rate in (0, 1], got {text!r}")
    return value


def stop_rate(text: str) -> float | str:
    """A run's ``stop_at``: a success rate in (0, 1], or "none" (train every episode)."""
    return "none" if text.strip().lower() == "none" else rate(text)


# ------------------------------------------------------------------ paths
# Path arguments say what they are by their type, so that one check in `main` (``check_paths``)
# covers every command: an output is never one of the command's inputs, never another of its
# outputs, never one of a run directory's own files, and a file where a folder is wanted (or the
# reverse) is named before anything runs.
_ConcretePath = type(Path())


class InputPath(_ConcretePath):
    """A file or folder the command reads."""


class OutputFile(_ConcretePath):
    """A file the command writes (replacing it if it exists)."""


class VideoFile(OutputFile):
    """A video the command writes: ``.mp4`` or ``.gif``, refused before any rendering."""

    def __new__(cls, *args):
        path = super().__new__(cls, *args)
        if path.suffix.lower() not in (".mp4", ".gif"):
            raise argparse.ArgumentTypeError(f"{path}: a video must end in .mp4 or .gif")
        return path


#: Figure formats every figure writer here can produce (matplotlib's raster and vector ones).
FIGURE_SUFFIXES = (".png", ".pdf", ".svg")


class FigureFile(OutputFile):
    """A figure the command writes: ``.png``, ``.pdf`` or ``.svg``, refused before any work."""

    def __new__(cls, *args):
        path = super().__new__(cls, *args)
        if path.suffix.lower() not in FIGURE_SUFFIXES:
            raise argparse.ArgumentTypeError(f"{path}: a figure must end in "
                                             f"{', '.join(FIGURE_SUFFIXES)}")
        return path


class NewOutput(OutputFile):
    """A file or folder the command creates; refused if anything exists there already."""


class OutputDir(_ConcretePath):
    """A folder the command writes into (created if missing)."""


#: Names a run directory keeps for itself (dualarm.training.run_dir.RunPaths), and folders of
#: its own whose every file is the run's.
#: Written out rather than read from RunPaths, which would import torch into every command;
#: tests/test_hostile.py checks that the two agree.
RUN_FILES = ("config.yaml", "metrics.csv", "eval.csv", "curves.png", "constraints.yaml", LOCK_NAME,
             "done.yaml")
RUN_FOLDERS = ("checkpoints", "events")


def _run_directory_of(path: Path) -> Path | None:
    """The run directory that owns ``path`` (a resolved path), or None."""
    parent = path.parent
    if path.name in RUN_FILES and (parent / "config.yaml").is_file():
        return parent
    for folder in path.parents:
        if folder.name in RUN_FOLDERS and (folder.parent / "config.yaml").is_file():
            return folder.parent
    return None


def option_names(parser: argparse.ArgumentParser) -> dict[str, str]:
    """dest -> how a user spells it ("--output", "INPUT"), over a parser and its subcommands."""
    names: dict[str, str] = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                for dest, name in option_names(sub).items():
                    names.setdefault(dest, name)
        elif action.dest not in names:
            names[action.dest] = (action.option_strings[-1] if action.option_strings
                                  else str(action.metavar or action.dest))
    return names


def check_paths(args: argparse.Namespace, names: dict[str, str] | None = None) -> None:
    """Refuse, naming the option, an output path that would destroy what the command reads
    or what a run directory holds, before the command starts.

    Raises:
        InputError: a path that cannot be resolved (a symlink loop), an output that
            resolves to an input, to another output, to a file of a run
            directory, or to a folder where a file is wanted (or the reverse).
    """
    from dualarm.errors import InputError

    def flag(dest: str) -> str:
        return (names or {}).get(dest, dest)

    found: list[tuple[str, Path]] = []
    for name, value in vars(args).items():
        for item in (value if isinstance(value, list) else [value]):
            if isinstance(item, (InputPath, OutputFile, OutputDir)):
                found.append((name, item))
    def resolve(name: str, path: Path) -> Path:
        try:
            return path.resolve()
        except (OSError, RuntimeError) as exc:         # RuntimeError: a symlink loop
            raise InputError(f"{path}: {flag(name)} cannot be resolved ({exc})") from None

    inputs = [(n, p, resolve(n, p)) for n, p in found if isinstance(p, InputPath)]
    outputs = [(n, p, resolve(n, p)) for n, p in found if not isinstance(p, InputPath)]
    for k, (name, path, real) in enumerate(outputs):
        for other, source, source_real in inputs:
            if real == source_real:
                raise InputError(f"{path}: {flag(name)} is also the input {flag(other)} ({source}); "
                                 "write the output elsewhere (nothing was changed)")
        for other, second, second_real in outputs[k + 1:]:
            if real == second_real:
                raise InputError(f"{path}: {flag(name)} and {flag(other)} name the same file "
                                 "(nothing was written)")
        if isinstance(path, OutputFile):
            owner = _run_directory_of(real)
            if owner is not None:
                raise InputError(f"{path}: {flag(name)} is a file of the run directory {owner}; "
                                 "write the output elsewhere (nothing was changed)")
            if isinstance(path, NewOutput) and (real.exists() or real.is_symlink()):
                raise InputError(f"{path}: {flag(name)} exists already; name a new file or "
                                 "folder (nothing was changed)")
            if real.is_dir():
                raise InputError(f"{path}: {flag(name)} is a folder; it names a file to write")
        elif real.exists() and not real.is_dir():
            raise InputError(f"{path}: {flag(name)} is an existing file; it names a folder to "
                             "write into")


def run_options(p: argparse.ArgumentParser) -> None:
    """The run directory and checkpoint of commands that use a learned policy (eval, play)."""
    p.add_argument("run", type=InputPath, metavar="DIR", help="a run directory of dualarm train")
    p.add_argument("--checkpoint", choices=("best", "latest"), default="best",
                   help="the best evaluated policy or the last checkpoint (default: best)")


def calibration_arguments(p: argparse.ArgumentParser) -> None:
    """The options of the calibration that turns a recording into joint angles (every command
    that maps recordings takes them, spelled and explained alike)."""
    p.add_argument("--calib-seconds", type=positive, default=1.0, metavar="S",
                   help="length of the calibration window, s (default: 1.0)")
    p.add_argument("--calib-start", type=non_negative, default=0.0, metavar="S",
                   help="start of the calibration window, s after the first sample (default: 0)")
    p.add_argument("--calib-pose", choices=("npose", "tpose"), default="npose",
                   help="the pose held in the calibration window: npose, the zero pose (arms hanging "
                        "by the sides), or tpose (arms out to the sides, as BVH and MVNX recordings "
                        "often start) (default: npose)")
    p.add_argument("--heading", choices=("auto", "off"), default="auto",
                   help="fit the elbow and wrist as hinges and correct what they reveal: sensor "
                        "heading offsets, the arm's facing, the forearm twist (default: auto)")
