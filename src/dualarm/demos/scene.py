"""Each demonstration's scene: where the two boxes stood and where their targets were.

A demonstration folder may hold ``SCENE_NAME`` beside its recordings and labels: one row per
demonstration, positions in metres in the simulator's world frame (x forward from Baxter's
base, y to its left, z up; the table top at ``SceneConfig.table_height``)::

    demo,left_box_x,left_box_y,left_box_z,right_box_x,...,left_target_x,...,right_target_z
    demo_00,0.6865,0.1381,0.7750,0.5879,-0.2670,0.7750,0.7358,0.1084,0.9509,0.7358,-0.0916,0.9509

The generator writes it (it knows the placements it used); a user enters the positions they
measured. The constraints do not need it; replaying a recording in the simulator does.
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dualarm.demos.formats import SCENE_NAME
from dualarm.errors import InputError
from dualarm.task import ARMS

#: Its columns after ``demo``: box then target, arm by arm (left first), x, y, z.
SCENE_COLUMNS = tuple(f"{arm}_{what}_{axis}" for what in ("box", "target") for arm in ARMS
                      for axis in "xyz")
#: Decimal places written (0.1 mm).
SCENE_DECIMALS = 4


@dataclass(frozen=True)
class Scene:
    """One demonstration's placements, m, world frame.

    Attributes:
        boxes: (2, 3) the resting centres of the left and right arm's boxes.
        targets: (2, 3) where each box was brought.
    """

    boxes: np.ndarray
    targets: np.ndarray


@dataclass(frozen=True)
class Workspace:
    """Where a scene may place things, m: x and y within the region the grip sites reach,
    boxes resting on the table (their centre ``rest_z``, within ``rest_tolerance``), targets
    above the table top and below ``max_z``. The Baxter task's is ``TaskConfig.workspace()``."""

    x_range: tuple[float, float]
    y_range: tuple[float, float]
    rest_z: float
    rest_tolerance: float
    table_z: float
    max_z: float

    def problem(self, scene: Scene) -> tuple[str, str] | None:
        """(column, what is wrong) for the first position outside the workspace, or None."""
        for what, points in (("box", scene.boxes), ("target", scene.targets)):
            for arm, p in zip(ARMS, points):
                for axis, value, (low, high) in (("x", p[0], self.x_range), ("y", p[1], self.y_range)):
                    if not low <= value <= high:
                        return (f"{arm}_{what}_{axis}", f"{value:g} m is outside the workspace "
                                f"[{low:g}, {high:g}] m")
                if what == "box" and abs(p[2] - self.rest_z) > self.rest_tolerance:
                    return (f"{arm}_box_z", f"{p[2]:g} m: a box rests on the table with its centre "
                            f"at {self.rest_z:g} m (within {self.rest_tolerance:g} m)")
                if what == "target" and not self.table_z < p[2] <= self.max_z:
                    return (f"{arm}_target_z", f"{p[2]:g} m is outside ({self.table_z:g}, "
                            f"{self.max_z:g}] m, between the table top and the highest grip")
        return None


def scene_csv_text(scenes: dict[str, Scene]) -> str:
    """The scene file's text for demo name -> ``Scene``, rows in the given order."""
    lines = [",".join(("demo", *SCENE_COLUMNS))]
    for name, scene in scenes.items():
        values = np.concatenate([np.ravel(scene.boxes), np.ravel(scene.targets)])
        lines.append(",".join([name, *(f"{v:.{SCENE_DECIMALS}f}" for v in values)]))
    return "\n".join(lines) + "\n"


def read_scenes(path: str | os.PathLike, workspace: Workspace) -> dict[str, Scene]:
    """Read and validate a scene file (format in the module docstring).

    Args:
        path: the file, usually ``DEMO_DIR/scene.csv``.
        workspace: where positions may lie (``TaskConfig.workspace()`` for the Baxter task).

    Returns:
        demo name -> ``Scene``, in file order.

    Raises:
        InputError: a missing or unreadable file, a missing column, a value that is not a
            finite number, a demonstration given twice, or a position outside the workspace;
            naming the file, row and column.
    """
    source, p = str(path), Path(path)
    if not p.is_file():
        raise InputError("scene file not found: a demonstration folder needs one row per "
                         f"demonstration with {', '.join(SCENE_COLUMNS[:3])}, ... (m)"
                         if not p.exists() else "not a file", source=source)
    try:
        with open(p, newline="", encoding="utf-8-sig") as f:
            rows = [[c.strip() for c in r] for r in csv.reader(f) if any(c.strip() for c in r)]
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"cannot read the scene file: {exc}", source=source) from None
    if not rows:
        raise InputError("empty scene file", source=source)
    header = [c.lower() for c in rows[0]]
    for name in ("demo", *SCENE_COLUMNS):
        if name not in header:
            raise InputError("missing column", source=source, column=name)
    at = {name: header.index(name) for name in ("demo", *SCENE_COLUMNS)}
    scenes: dict[str, Scene] = {}
    for r, cells in enumerate(rows[1:], start=1):
        if len(cells) != len(header):
            raise InputError(f"row has {len(cells)} cells, the header {len(header)}", source=source, row=r)
        demo = cells[at["demo"]]
        if not demo or demo in scenes:
            raise InputError("empty demo name" if not demo else f"demonstration {demo!r} given twice",
                             source=source, row=r, column="demo")
        values = []
        for name in SCENE_COLUMNS:
            try:
                value = float(cells[at[name]])
            except ValueError:
                value = float("nan")
            if not np.isfinite(value):
                raise InputError(f"expected a finite number of metres, got {cells[at[name]]!r}",
                                 source=source, row=r, column=name)
            values.append(value)
        v = np.array(values).reshape(2, 2, 3)
        scene = Scene(boxes=v[0], targets=v[1])
        problem = workspace.problem(scene)
        if problem is not None:
            raise InputError(problem[1], source=source, row=r, column=problem[0])
        scenes[demo] = scene
    if not scenes:
        raise InputError("no scene rows after the header", source=source)
    return scenes


def demo_scenes(demo_dir: str | os.PathLike, names, workspace: Workspace) -> dict[str, Scene]:
    """The scenes of the demonstrations ``names`` of a folder (its ``SCENE_NAME``).

    Raises:
        InputError: the file is missing or bad (``read_scenes``), or lacks a row for one of
            ``names``, naming the demonstration.
    """
    path = Path(demo_dir) / SCENE_NAME
    scenes = read_scenes(path, workspace)
    missing = [n for n in names if n not in scenes]
    if missing:
        raise InputError(f"no scene row for demonstration(s) {', '.join(missing)}", source=str(path),
                         column="demo")
    return {n: scenes[n] for n in names}
