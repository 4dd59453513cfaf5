"""Read BVH (Biovision hierarchy) motion capture, as Noitom, Rokoko, Vicon, OptiTrack and
the CMU database export it, as a `Recording` of the six arm segments.

The hierarchy (joints, offsets, channels, frame time) is parsed by bvhio, a maintained BVH
library. Before bvhio sees a file, :func:`_check_layout` checks that the file is complete,
because bvhio 1.5 waits forever for a line that a truncated file never gives, and reads
every frame line into numbers, checked finite; those numbers become each joint's local
rotation per frame with SciPy (intrinsic Euler angles in channel order, in degrees, as the
format specifies and bvhio reads them), so no frame is parsed twice. The world rotation of a
joint is the product of its ancestors' local rotations; at all-zero channels (the rest pose,
usually a T-pose) every joint frame is the file's world frame.

The trunk is the lowest common ancestor of the two upper arms (the chest); its "up" is the
rest-pose direction from the root (hips) to it, its "left" from the right to the left
upper arm (:mod:`dualarm.mocap.segments`).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from dualarm.errors import InputError, require_file
from dualarm.mocap.recording import SENSORS, Recording
from dualarm.mocap.segments import match_segments, segment_recording, trunk_to_body


def read_bvh(path: str | os.PathLike, *, sensor_map: Mapping[str, str] | None = None) -> Recording:
    """Read a ``.bvh`` file.

    Args:
        path: the file. Segment names are matched as in :mod:`dualarm.mocap.segments`
            (``LeftArm``, ``LeftForeArm``, ``LeftHand``, ...).
        sensor_map: file's joint name -> sensor, for skeletons named otherwise.

    Returns:
        The recording, T frames at ``i * Frame Time`` s: each arm segment's orientation
        relative to the chest, in the body frame (x forward, y left, z up).

    Raises:
        InputError: naming the file and, where it applies, the line or frame.
    """
    with warnings.catch_warnings():  # bvhio's "import glm" warns of PyGLM's future rename
        warnings.simplefilter("ignore", PendingDeprecationWarning)
        import bvhio

    source = str(path)
    values = _check_layout(_read(path), source)
    try:
        bvh = bvhio.readAsBvh(str(path), loadKeyFrames=False)
    except SyntaxError as e:
        line = e.args[1][1] if len(e.args) > 1 and isinstance(e.args[1], tuple) else None
        raise InputError(f"not a valid BVH file: {e.args[0]}", source=source, row=line) from None
    except (ValueError, IndexError, UnicodeDecodeError) as e:
        raise InputError(f"not a valid BVH file ({type(e).__name__}: {e})", source=source) from None

    joints = _flatten(bvh.Root)
    names = [j.Name for j, _ in joints]
    if len(set(names)) != len(names):
        twice = next(n for n in names if names.count(n) > 1)
        raise InputError(f"joint name {twice!r} appears more than once in the hierarchy", source=source)
    chosen = match_segments(names, sensor_map, source)
    parent = {j.Name: p for j, p in joints}
    rest = _rest_positions(joints)
    trunk = _common_ancestor(chosen["left_upper_arm"], chosen["right_upper_arm"], parent)
    if parent[trunk] is None:
        raise InputError(f"the upper arms {chosen['left_upper_arm']!r} and {chosen['right_upper_arm']!r} "
                         "meet only at the root: no chest joint to measure the arms from", source=source)
    body = trunk_to_body(rest[trunk] - rest[names[0]],
                         rest[chosen["left_upper_arm"]] - rest[chosen["right_upper_arm"]], source)

    if not (np.isfinite(bvh.FrameTime) and bvh.FrameTime > 0):
        raise InputError(f"Frame Time must be a positive number of seconds, got {bvh.FrameTime}", source=source)
    world = _world_rotations(joints, values, source)
    time = np.arange(len(values)) * bvh.FrameTime
    return segment_recording(time, world[trunk], {s: world[chosen[s]] for s in SENSORS}, body, source)


def _read(path: str | os.PathLike) -> str:
    require_file(path)
    p = Path(path)
    try:
        return p.read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise InputError(f"not a text file (byte {e.start} is not UTF-8)", source=str(path)) from None
    except OSError as e:
        raise InputError(f"cannot read file ({type(e).__name__}: {e.strerror or e})", source=str(path)) from None


def _check_layout(text: str, source: str) -> np.ndarray:
    """Check the file is complete before bvhio reads it; return its frames' channel values
    (N, channels), in the order of the file.

    A complete file has a HIERARCHY whose braces balance, then MOTION, ``Frames: N``,
    ``Frame Time: dt`` and N lines of one finite number per channel.
    """
    lines = text.splitlines()
    numbered = [(i + 1, line.split()) for i, line in enumerate(lines) if line.strip()]
    if not numbered or numbered[0][1] != ["HIERARCHY"]:
        raise InputError("not a BVH file: the first line must be HIERARCHY", source=source)
    motion = next((k for k, (_, tok) in enumerate(numbered) if tok == ["MOTION"]), None)
    if motion is None:
        raise InputError("no MOTION section: the file is cut short or not BVH", source=source)
    hierarchy = [t for _, tok in numbered[1:motion] for t in tok]
    if hierarchy.count("{") != hierarchy.count("}"):
        raise InputError("the HIERARCHY's braces do not balance", source=source,
                         row=numbered[motion][0])
    channels = 0
    for k, t in enumerate(hierarchy):
        if t == "CHANNELS":
            try:
                channels += int(hierarchy[k + 1])
            except (IndexError, ValueError):
                raise InputError("CHANNELS must be followed by a count", source=source) from None
    head = numbered[motion + 1:motion + 3]
    if len(head) < 2 or head[0][1][:1] != ["Frames:"] or head[1][1][:2] != ["Frame", "Time:"]:
        raise InputError("MOTION must be followed by 'Frames: N' and 'Frame Time: SECONDS'", source=source,
                         row=numbered[motion][0])
    try:
        frames = int(head[0][1][1])
    except (IndexError, ValueError):
        raise InputError("Frames: must be followed by a whole number", source=source, row=head[0][0]) from None
    data = numbered[motion + 3:]
    if frames < 1:
        raise InputError(f"the file has {frames} frames", source=source, row=head[0][0])
    if len(data) < frames:
        raise InputError(f"Frames: says {frames}, the file holds {len(data)} frame lines (cut short?)",
                         source=source, row=head[0][0])
    for number, tok in data[:frames]:
        if len(tok) != channels:
            raise InputError(f"frame line has {len(tok)} numbers, the hierarchy {channels} channels",
                             source=source, row=number)
    values = np.array([x for _, tok in data[:frames] for x in tok], dtype=object)
    try:
        numbers = values.astype(float)
    except ValueError:
        for number, tok in data[:frames]:
            for x in tok:
                try:
                    float(x)
                except ValueError:
                    raise InputError(f"not a number: {x!r}", source=source, row=number) from None
        raise
    bad = np.flatnonzero(~np.isfinite(numbers))
    if bad.size:
        row = data[int(bad[0]) // max(channels, 1)][0]
        raise InputError("a channel value is NaN or infinite", source=source, row=row)
    return numbers.reshape(frames, channels)


def _flatten(root) -> list[tuple[object, str | None]]:
    """(joint, parent name) depth first, the root first."""
    out, stack = [], [(root, None)]
    while stack:
        joint, parent = stack.pop()
        out.append((joint, parent))
        stack.extend((child, joint.Name) for child in reversed(joint.Children))
    return out


def _rest_positions(joints) -> dict[str, np.ndarray]:
    """Joint name -> (3,) position in the rest pose (every rotation zero), file units."""
    pos: dict[str, np.ndarray] = {}
    for joint, parent in joints:
        offset = np.array([joint.Offset.x, joint.Offset.y, joint.Offset.z])
        pos[joint.Name] = offset if parent is None else pos[parent] + offset
    return pos


def _common_ancestor(a: str, b: str, parent: Mapping[str, str | None]) -> str:
    chain = []
    while a is not None:
        chain.append(a)
        a = parent[a]
    while b not in chain:
        b = parent[b]
    return b


def _world_rotations(joints, values: np.ndarray, source: str) -> dict[str, np.ndarray]:
    """Joint name -> (T, 3, 3) world rotation, the product of the local rotations above it.

    ``values`` (T, channels) holds the joints' channels in the hierarchy's order (depth first,
    as ``joints``); a joint's rotation channels, e.g. ``Zrotation Xrotation Yrotation``, are
    intrinsic Euler angles in that order, degrees; a joint without any is not rotated.
    """
    world: dict[str, np.ndarray] = {}
    column = 0
    for joint, parent in joints:
        channels = [c.lower() for c in joint.Channels]
        rotation = [(k, c[0].upper()) for k, c in enumerate(channels) if c.endswith("rotation")]
        if len(rotation) > 3:
            raise InputError(f"joint {joint.Name}: {len(rotation)} rotation channels, at most 3",
                             source=source)
        block = values[:, column:column + len(channels)]
        column += len(channels)
        if rotation:
            order = "".join(axis for _, axis in rotation)
            local = Rotation.from_euler(order, block[:, [k for k, _ in rotation]], degrees=True).as_matrix()
        else:
            local = np.broadcast_to(np.eye(3), (len(values), 3, 3))
        world[joint.Name] = local if parent is None else world[parent] @ local
    return world
