"""Automatic segmentation: sub-task times from the hand's speed and height (Baxter forward
kinematics of the joint vector) and, when the recording has them, the gripper events;
:func:`segmentation_agreement` compares it with labels. Times in seconds, positions in metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dualarm.errors import InputError
from dualarm.kinematics import baxter_arm
from dualarm.demos.loading import lowpass
from dualarm.task import ARMS, JOINTS_PER_ARM

_N_ARM = JOINTS_PER_ARM


#: Distance (m) from Baxter's hand frame (D-H frame 7) to the grip point, along its z axis.
GRIP_OFFSET = 0.13


@dataclass(frozen=True)
class SegmentationOptions:
    """Thresholds of :func:`segment_demo`.

    Attributes:
        smooth_hz: cut-off of the zero-phase low-pass filter on the grip points before their
            speed is taken, Hz (timing is resolved to about a quarter of its period).
        rest_speed: the hand rests (pauses) below this speed, m/s.
        still_speed: a motion starts or ends where the speed crosses this (lower) speed, m/s.
        min_rest_s: shortest rest that counts, s.
        grasp_search_s: with gripper events, the box is where the hand is lowest within
            this long of the gripper's first closing, s.
        reach_m: reach ends when the hand comes within this height of the box (the
            environment's ``reach_threshold``), m.
        lift_m: grasp ends when the hand has risen this much above the box (the
            environment's ``lift_height``), m.
    """

    smooth_hz: float = 2.0
    rest_speed: float = 0.06
    still_speed: float = 0.025
    min_rest_s: float = 0.15
    grasp_search_s: float = 0.5
    reach_m: float = 0.02
    lift_m: float = 0.02


def hand_points(q: np.ndarray) -> np.ndarray:
    """Grip points of both arms through Baxter's forward kinematics.

    Args:
        q: (T, 14) Baxter joint angles, rad.
    Returns:
        (T, 2, 3) positions, m, in Baxter's frame (z up).
    """
    q = np.asarray(q, dtype=float)
    out = np.empty(q.shape[:1] + (2, 3))
    for a, arm in enumerate(ARMS):
        pose = baxter_arm(arm).forward(q[:, _N_ARM * a:_N_ARM * (a + 1)])[:, -1]
        out[:, a] = pose[:, :3, 3] + GRIP_OFFSET * pose[:, :3, 2]
    return out


def _runs(mask: np.ndarray) -> np.ndarray:
    """(R, 2) [first, last] sample index of each run of True."""
    m = np.concatenate([[False], mask, [False]]).astype(np.int8)
    d = np.diff(m)
    return np.stack([np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1], axis=1)


def segment_demo(time: np.ndarray, q: np.ndarray, grip: np.ndarray | None = None, *,
                 calib_end_s: float = 1.0, options: SegmentationOptions = SegmentationOptions(),
                 demo: str = "<demo>") -> np.ndarray:
    """Sub-task windows of one demonstration from the hand's motion (and gripper events).

    Assumes the layout of a reach-grasp-align recording: the zero-pose window, possibly a
    move to a start posture and a pause, then the task, then a pause at the end. Per arm,
    from the grip point p(t) (:func:`hand_points`, low-passed at ``smooth_hz``) and its speed v:

    * rests are runs of at least ``min_rest_s`` with v below ``rest_speed``;
    * the box is where the hand is lowest: after the calibration window, or, when the
      recording has gripper events, within ``grasp_search_s`` of the gripper's first closing;
    * the grasp starts when the hand, going down to the box, comes within ``reach_m`` of
      that height, and ends when it has risen ``lift_m`` above it (the environment's
      reach and lift thresholds);
    * reach starts where the hand sets off before that: the last sample before the grasp's
      preceding motion with v below ``still_speed``;
    * align ends where the hand comes to a stop: the first sample after the last motion
      with v below ``still_speed`` (or the last sample).

    Args:
        time: (T,) s after the first sample.
        q: (T, 14) Baxter joint angles, rad.
        grip: (T, 2) gripper events (1 closed), or None.
        calib_end_s: end of the calibration window, s; nothing starts before it.
    Returns:
        (2, 3, 2) windows, s, [arm, sub-task, start/end].
    Raises:
        InputError: naming the demonstration, when no grasp, lift or start can be found.
    """
    t = np.asarray(time, dtype=float)
    after = t >= calib_end_s
    if after.sum() < 3:
        raise InputError(f"demo {demo!r}: nothing recorded after the calibration window ({calib_end_s:g} s)")
    p = hand_points(q)
    p = lowpass(t, p.reshape(len(t), 6), options.smooth_hz, demo).reshape(p.shape)
    speed = np.linalg.norm(np.gradient(p, t, axis=0), axis=-1)           # (T, 2)
    dt = float(np.median(np.diff(t)))
    min_len = max(1, int(round(options.min_rest_s / dt)))
    first = int(np.argmax(after))
    search = max(1, int(round(options.grasp_search_s / dt)))
    out = np.empty((2, 3, 2))
    for a, arm in enumerate(ARMS):
        v = speed[:, a]
        rest_level, still_level = options.rest_speed, options.still_speed
        runs = _runs((v < rest_level) & after)
        runs = runs[runs[:, 1] - runs[:, 0] + 1 >= min_len]
        height = p[:, a, 2]
        if grip is not None:
            closing = np.flatnonzero(after[1:] & (grip[1:, a] > 0) & (grip[:-1, a] == 0)) + 1
            if closing.size == 0:
                raise InputError(f"demo {demo!r}, {arm} arm: the gripper never closes after the calibration "
                                 f"window")
            lo_i = max(first, int(closing[0]) - search)
            low = lo_i + int(np.argmin(height[lo_i:int(closing[0]) + search + 1]))
        else:
            low = first + int(np.argmin(height[first:]))
        above = np.flatnonzero(height[first:low + 1] > height[low] + options.reach_m)
        g0 = first + int(above[-1]) + 1 if above.size else first
        before = runs[runs[:, 1] < g0]
        if before.shape[0] == 0:
            raise InputError(f"demo {demo!r}, {arm} arm: no pause before the reach")
        off = int(before[-1, 1]) + 1
        still = np.flatnonzero(v[:off] < still_level)
        r0 = int(still[-1]) if still.size and still[-1] >= before[-1, 0] else int(before[-1, 1])
        rise = np.flatnonzero(height[low:] >= height[low] + options.lift_m)
        if rise.size == 0:
            raise InputError(f"demo {demo!r}, {arm} arm: the hand never rises {options.lift_m:g} m after "
                             f"the grasp")
        g1 = low + int(rise[0])
        moving = np.flatnonzero(v[g1:] >= rest_level)
        last_motion = g1 + int(moving[-1]) if moving.size else g1
        stop = np.flatnonzero(v[last_motion:] < still_level)
        a1 = last_motion + int(stop[0]) if stop.size else len(t) - 1
        out[a] = [[t[r0], t[g0]], [t[g0], t[g1]], [t[g1], t[min(max(a1, g1 + 1), len(t) - 1)]]]
    return out


def segment_demos(demos, calib_end_s: float, use_grip: bool = True) -> dict[str, np.ndarray]:
    """Demo name -> (2, 3, 2) sub-task windows (s) of every ``DemoJoints`` by
    :func:`segment_demo`, with their gripper events unless ``use_grip`` is False."""
    return {d.name: segment_demo(d.time, d.q, d.grip if use_grip else None, calib_end_s=calib_end_s,
                                 demo=d.name) for d in demos}


def segmentation_agreement(time: np.ndarray, auto: np.ndarray, labels: np.ndarray) -> dict[str, np.ndarray]:
    """How well automatic windows agree with labelled ones on one demonstration.

    Args:
        time: (T,) s.
        auto, labels: (2, 3, 2) windows, s.
    Returns:
        ``boundary_error_s``: (2, 4) |auto - label| of reach start, grasp start, align start,
        align end per arm (s); ``frame_agreement``: (2,) fraction of the samples inside the
        labelled task (reach start to align end) given the same sub-task by both.
    """
    def boundaries(w):
        return np.stack([w[:, 0, 0], w[:, 1, 0], w[:, 2, 0], w[:, 2, 1]], axis=1)

    def frame_labels(w):
        t = np.asarray(time)
        lab = np.full((2, t.size), -1)
        for n in range(3):
            lab = np.where((t >= w[:, n, 0, None]) & (t < w[:, n, 1, None]), n, lab)
        return lab

    la, ll = frame_labels(auto), frame_labels(labels)
    task = ll >= 0
    agree = ((la == ll) & task).sum(axis=1) / np.maximum(task.sum(axis=1), 1)
    return {"boundary_error_s": np.abs(boundaries(auto) - boundaries(labels)), "frame_agreement": agree}
