"""Demonstration sets of the reach-grasp-align task: the shipped default set and its generator.

No public IMU recording of this task exists, so the project makes one the way a motion
capture session would, starting from motions that are known to solve the task:

1. **Task motion.** The scripted expert (:mod:`dualarm.envs.expert`) solves the task in the
   MuJoCo scene for a seeded object and target placement; its Baxter joint trajectory
   (50 Hz, about 0.5 s) and each arm's sub-task are recorded.
2. **Human variability.** Each arm, independently:

   * *elbow swivel*: the arm is moved along its self-motion manifold (the null space of
     Baxter's 6x7 hand Jacobian, the same D-H chain as the human arm's) by a swivel
     offset drawn per demonstration, drifting slowly over the task; the hand pose is kept
     (to about 1e-6 m and rad at the expert's samples);
   * *speed and timing*: the expert's time is warped onto a human pace: each sub-task
     gets its own duration (reach and align about 1-1.5 s, grasp about 0.5-0.8 s, all
     divided by a per-demonstration speed factor), each arm starts after its own short
     lag, and the warp is a monotone C1 cubic (PCHIP) through the sub-task boundaries,
     with zero speed at the start and the end; the joint curves between the expert's
     samples come from a cubic spline, so the motion is smooth;
   * *tremor*: band-limited (8-12 Hz) noise on every joint, 0.025 degree RMS at the
     shoulder, 1.5x at the elbow, 2x at the wrist: under a millimetre at the hand, as
     physiological tremor is.

   Before the task the person stands in the zero pose (arms hanging, q = 0) for the
   calibration window, then raises the arms to the robot's start posture (a minimum-jerk
   move) and pauses; after it they hold the final posture.
3. **IMU recording.** The joint angles are the human's (the paper's mapping is the
   identity, :mod:`dualarm.mocap.retarget`); through the human model they become the
   orientations of the upper arm, forearm and hand (:func:`dualarm.mocap.synthetic.
   segment_orientations`), seen by six sensors with uniformly random mountings and white
   orientation noise, sampled at 100 Hz.
4. **Labels.** The start and end time of each arm's reach, grasp and align, in seconds
   after the first sample: the images of the expert's sub-task changes under the time warp,
   so they agree exactly with the environment's definition of the sub-tasks.

Files (written by :func:`write_demo_set`, read by :func:`dualarm.mocap.io.read_recording`
and :func:`dualarm.demos.labels.read_labels`): ``demo_00.csv.gz`` ... in the CSV
format of ``dualarm mocap joints`` (``time`` and ``S_qw..S_qz`` per sensor, six decimals)
plus two columns ``left_grip, right_grip`` (1 while the hand is closed: the gripper events,
as a glove, a button or a video annotation would give them; other readers ignore them),
and ``labels.csv`` (see :mod:`dualarm.demos.labels`), and ``scene.csv``, each demonstration's box
and target positions (:mod:`dualarm.demos.scene`). Gzip headers carry no name or
time stamp, so the same arguments give the same bytes.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline, PchipInterpolator
from scipy.signal import butter, sosfiltfilt

from dualarm.atomic import atomic_open
from dualarm.demos.formats import LABELS_NAME, QUAT_DECIMALS, demo_csv_text, gzip_bytes
from dualarm.demos.labels import labels_csv_text
from dualarm.demos.scene import SCENE_NAME, Scene, scene_csv_text
from dualarm.errors import InputError
from dualarm.kinematics import baxter_arm
from dualarm.mocap.recording import SENSORS, Recording
from dualarm.mocap.synthetic import random_mountings, sensor_quaternions
from dualarm.task import JOINTS_PER_ARM

#: Number of demonstrations in the default set (the paper recorded 10).
DEFAULT_COUNT = 10
#: Seed of the default set.
DEFAULT_SEED = 0

_N_ARM = JOINTS_PER_ARM


@dataclass(frozen=True)
class HumanModel:
    """How the simulated demonstrator and the sensors vary; ranges are (low, high), drawn uniformly.

    Times in s, angles in rad, rates in Hz.

    Attributes:
        rate_hz: sampling rate of the IMU recording.
        calib_s: length of the still zero-pose window at the start.
        raise_delay_s: pause after the calibration window before raising the arms.
        raise_s: duration of the minimum-jerk move from the zero pose to the start posture.
        hold_s: pause in the start posture before the task.
        onset_lag_s: per arm, delay of its start after the task start.
        reach_s, grasp_s, align_s: per arm, duration of each sub-task at speed 1.
        speed: per demonstration, pace factor (durations are divided by it).
        end_hold_s: time the final posture is held after the slower arm finishes.
        swivel_rad: per arm, self-motion offset (joint-space arc length along the null
            space; positive turns the elbow about the shoulder-to-wrist axis).
        swivel_drift_rad: per arm, largest change of the swivel from the start to the end.
        tremor_rad: RMS tremor of the shoulder joints; the elbow gets 1.5x, the wrist 2x.
        tremor_band_hz: band of the tremor.
        noise_rad: standard deviation of the white orientation noise of each sensor, per axis.
    """

    rate_hz: float = 100.0
    calib_s: float = 1.5
    raise_delay_s: tuple[float, float] = (0.2, 0.5)
    raise_s: tuple[float, float] = (1.0, 1.4)
    hold_s: tuple[float, float] = (0.4, 0.7)
    onset_lag_s: tuple[float, float] = (0.0, 0.25)
    reach_s: tuple[float, float] = (1.0, 1.5)
    grasp_s: tuple[float, float] = (0.5, 0.8)
    align_s: tuple[float, float] = (1.0, 1.5)
    speed: tuple[float, float] = (0.8, 1.25)
    end_hold_s: float = 0.6
    swivel_rad: tuple[float, float] = (-0.3, 0.3)
    swivel_drift_rad: float = 0.1
    tremor_rad: float = np.deg2rad(0.025)
    tremor_band_hz: tuple[float, float] = (8.0, 12.0)
    noise_rad: float = np.deg2rad(0.15)


@dataclass(frozen=True)
class Demonstration:
    """One generated demonstration and the truth behind it.

    Attributes:
        name: file stem, e.g. "demo_03".
        env_seed: reset seed of the expert episode (object and target placement).
        time: (T,) s from 0.
        q: (T, 14) the generating human joint angles (rad), left q1..q7 then right; equal
            to the Baxter joint vector they map to.
        grip: (T, 2) int, 1 while the left/right hand is closed.
        windows: (2, 3, 2) s, [arm, sub-task (reach, grasp, align), start/end].
        recording: the IMU recording of ``q`` (six sensors, quaternions as written to file).
        expert_q: (steps + 1, 14) the expert's Baxter joint trajectory (rad), at 50 Hz.
        expert_subtasks: (steps, 2) the expert's sub-task per arm after each step.
        scene: where the boxes stood and their targets were (m, world frame).
    """

    name: str
    env_seed: int
    time: np.ndarray
    q: np.ndarray
    grip: np.ndarray
    windows: np.ndarray
    recording: Recording
    expert_q: np.ndarray = field(repr=False)
    expert_subtasks: np.ndarray = field(repr=False)
    scene: Scene | None = field(default=None, repr=False)


# --------------------------------------------------------------------------- expert episodes

def expert_episode(env, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Run the scripted expert once; None unless it succeeds with each arm's sub-task never going back.

    Returns:
        q (steps + 1, 14) rad from the reset on; subtasks (steps, 2) after each step;
        grip (steps + 1, 2) int, the grip command (1 close) in force after each sample
        (the last sample repeats the last command).
    """
    from dualarm.envs.rollout import make_policy, run_episode

    expert = make_policy("expert", env)
    commands = []

    def policy(obs):
        action = expert(obs)
        commands.append(action[:, -1] > 0)
        return action

    episode = run_episode(env, policy, seed)
    sub = episode.subtasks
    if not episode.success or np.any(np.diff(sub, axis=0) < 0) or np.any(sub[-1] != 2):
        return None
    grip = np.array(commands + commands[-1:], dtype=np.int64)
    return episode.joint_angles.copy(), sub.copy(), grip


def subtask_change_steps(subtasks: np.ndarray) -> np.ndarray:
    """(steps, 2) sub-task after each step -> (2, 2) sample index at which each arm enters grasp, align.

    Sample j is the state after step j (sample 0 is the reset, in reach).
    """
    out = np.empty((2, 2), dtype=np.int64)
    for a in range(2):
        for n in (1, 2):
            out[a, n - 1] = int(np.argmax(subtasks[:, a] >= n)) + 1
    return out


# --------------------------------------------------------------------------- elbow swivel

def _hand_pose_error(model, q: np.ndarray, target: np.ndarray) -> np.ndarray:
    """(N, 6) position (m) and rotation-vector (rad) error of the hand frame from ``target`` (N, 4, 4)."""
    pose = model.forward(q)[..., -1, :, :]
    dp = pose[:, :3, 3] - target[:, :3, 3]
    dR = pose[:, :3, :3] @ np.swapaxes(target[:, :3, :3], -1, -2)
    w = 0.5 * np.stack([dR[:, 2, 1] - dR[:, 1, 2], dR[:, 0, 2] - dR[:, 2, 0], dR[:, 1, 0] - dR[:, 0, 1]], axis=1)
    return np.concatenate([dp, w], axis=1)


def hand_jacobian(model, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Geometric Jacobian of the hand frame by central differences.

    Args:
        model: a :class:`dualarm.kinematics.ArmModel`.
        q: (N, 7) joint angles, rad.
    Returns:
        (N, 6, 7): rows linear velocity (m/rad), angular velocity (rad/rad) in the world frame.
    """
    q = np.asarray(q, dtype=float)
    n = q.shape[0]
    steps = np.eye(_N_ARM) * h
    plus = (q[:, None, :] + steps).reshape(-1, _N_ARM)
    minus = (q[:, None, :] - steps).reshape(-1, _N_ARM)
    ref = np.repeat(model.forward(q)[:, -1], _N_ARM, axis=0)
    J = (_hand_pose_error(model, plus, ref) - _hand_pose_error(model, minus, ref)) / (2 * h)
    return np.swapaxes(J.reshape(n, _N_ARM, 6), 1, 2)


def _swivel_direction(model, q: np.ndarray) -> np.ndarray:
    """(N, 7) unit null-space direction of the hand Jacobian, signed so that the elbow turns
    positively (right-hand rule) about the shoulder-to-wrist axis."""
    J = hand_jacobian(model, q)
    _, _, vt = np.linalg.svd(J)
    n = vt[:, -1, :]
    p = model.joint_positions(q)
    shoulder, elbow, wrist = p[:, 1], p[:, 3], p[:, 5]
    axis = wrist - shoulder
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    offset = elbow - shoulder
    offset -= (offset * axis).sum(axis=1, keepdims=True) * axis
    h = 1e-6
    moved = model.joint_positions(q + h * n)[:, 3] - model.joint_positions(q - h * n)[:, 3]
    turn = (np.cross(axis, offset) * moved).sum(axis=1)
    return n * np.where(turn >= 0, 1.0, -1.0)[:, None]


def swivel(model, q: np.ndarray, amount: np.ndarray, substeps: int = 12) -> np.ndarray:
    """Move each joint vector along the arm's self-motion by ``amount``, keeping the hand pose.

    Integrates the unit null-space direction of the hand Jacobian (signed so that positive
    amounts turn the elbow about the shoulder-to-wrist axis by the right-hand rule) with
    ``substeps`` midpoint steps, then removes the drift of the hand pose with two
    Gauss-Newton steps. The arm must be bent (the elbow off the shoulder-wrist axis).

    Args:
        model: a 7-joint :class:`dualarm.kinematics.ArmModel` (Baxter's chain).
        q: (N, 7) joint angles, rad.
        amount: (N,) or scalar joint-space arc length, rad.
    Returns:
        (N, 7) joint angles, rad (not clipped to any limits).
    """
    q = np.array(q, dtype=float)
    amount = np.broadcast_to(np.asarray(amount, dtype=float), q.shape[:1])
    target = model.forward(q)[:, -1]
    h = amount / substeps
    for _ in range(substeps):
        mid = q + 0.5 * h[:, None] * _swivel_direction(model, q)
        q = q + h[:, None] * _swivel_direction(model, mid)
    for _ in range(2):
        J = hand_jacobian(model, q)
        err = _hand_pose_error(model, q, target)
        q = q - np.einsum("nij,nj->ni", np.linalg.pinv(J), err)
    return q


# --------------------------------------------------------------------------- human timing

def _min_jerk(u: np.ndarray) -> np.ndarray:
    u = np.clip(u, 0.0, 1.0)
    return u ** 3 * (10 - 15 * u + 6 * u * u)


def time_warp(t: np.ndarray, human_knots: np.ndarray, expert_knots: np.ndarray) -> np.ndarray:
    """Expert time at human times ``t``: monotone PCHIP through the knots, flat outside them.

    Args:
        t: (T,) human time, s.
        human_knots: (K,) increasing human times, s.
        expert_knots: (K,) non-decreasing expert times, s.
    Returns:
        (T,) expert time, s: ``expert_knots[0]`` before the first knot, ``expert_knots[-1]``
        after the last; zero slope at both ends.
    """
    pad = 1.0
    x = np.concatenate([[human_knots[0] - pad], human_knots, [human_knots[-1] + pad]])
    y = np.concatenate([[expert_knots[0]], expert_knots, [expert_knots[-1]]])
    warp = PchipInterpolator(x, y)
    return np.where(t <= human_knots[0], expert_knots[0],
                    np.where(t >= human_knots[-1], expert_knots[-1], warp(np.clip(t, x[0], x[-1]))))


def tremor(rng: np.random.Generator, n: int, rate_hz: float, rms: np.ndarray,
           band_hz: tuple[float, float]) -> np.ndarray:
    """(n, len(rms)) band-limited noise with the given RMS per column (rad)."""
    rms = np.asarray(rms, dtype=float)
    lo, hi = band_hz
    pad = int(rate_hz)  # filter transients fall outside the kept samples
    white = rng.standard_normal((n + 2 * pad, rms.size))
    if hi >= rate_hz / 2:
        raise ValueError(f"tremor band {band_hz} Hz needs a rate above {2 * hi} Hz, got {rate_hz}")
    sos = butter(2, [lo, hi], btype="bandpass", fs=rate_hz, output="sos")
    x = sosfiltfilt(sos, white, axis=0)[pad:pad + n]
    return x / np.sqrt(np.mean(x * x, axis=0)) * rms


# --------------------------------------------------------------------------- one demonstration

def human_demonstration(rng: np.random.Generator, expert_q: np.ndarray, expert_subtasks: np.ndarray,
                        expert_grip: np.ndarray, control_period: float,
                        human: HumanModel = HumanModel()) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The human version of one expert episode.

    Args:
        rng: source of every random choice.
        expert_q: (S + 1, 14) Baxter joint angles from the reset on, rad.
        expert_subtasks: (S, 2) sub-task per arm after each step.
        expert_grip: (S + 1, 2) grip command (1 close) after each sample.
        control_period: s per expert step.
        human: the variability model.
    Returns:
        time (T,) s; q (T, 14) rad; grip (T, 2) int; windows (2, 3, 2) s
        ([arm, sub-task, start/end], seconds after the first sample).
    """
    h = human
    n_samples = expert_q.shape[0]
    tau = np.arange(n_samples) * control_period
    change = subtask_change_steps(expert_subtasks) * control_period       # (2, 2) expert s
    speed = rng.uniform(*h.speed)
    t_raise = h.calib_s + rng.uniform(*h.raise_delay_s)
    raise_s = rng.uniform(*h.raise_s)
    t_task = t_raise + raise_s + rng.uniform(*h.hold_s)
    durations = np.stack([rng.uniform(*r, size=2) for r in (h.reach_s, h.grasp_s, h.align_s)], axis=1) / speed
    onsets = t_task + rng.uniform(*h.onset_lag_s, size=2)
    swivel0 = rng.uniform(*h.swivel_rad, size=2)
    drift = rng.uniform(-h.swivel_drift_rad, h.swivel_drift_rad, size=2)
    ends = onsets + durations.sum(axis=1)
    t_end = ends.max() + h.end_hold_s
    time = np.arange(int(np.floor(t_end * h.rate_hz)) + 1) / h.rate_hz

    model = baxter_arm("left")  # both arms share the D-H table; only the base differs
    q = np.zeros((time.size, 14))
    grip = np.zeros((time.size, 2), dtype=np.int64)
    windows = np.empty((2, 3, 2))
    for a in range(2):
        cols = slice(_N_ARM * a, _N_ARM * (a + 1))
        amount = swivel0[a] + drift[a] * tau / tau[-1]
        arm_q = swivel(model, expert_q[:, cols], amount)
        knots_h = onsets[a] + np.concatenate([[0.0], np.cumsum(durations[a])])
        knots_e = np.array([0.0, change[a, 0], change[a, 1], tau[-1]])
        windows[a, :, 0] = knots_h[:3]
        windows[a, :, 1] = knots_h[1:]
        t_e = time_warp(time, knots_h, knots_e)
        spline = CubicSpline(tau, arm_q, axis=0)
        task = spline(t_e)
        start = arm_q[0]
        rise = _min_jerk((time - t_raise) / raise_s)[:, None] * start
        q[:, cols] = np.where((time < onsets[a])[:, None], rise, task)
        step = np.clip(np.floor(t_e / control_period + 1e-9).astype(np.int64), 0, n_samples - 1)
        grip[:, a] = np.where(time >= onsets[a], expert_grip[step, a], 0)
    scale = np.array([1.0, 1.0, 1.0, 1.5, 1.5, 2.0, 2.0] * 2)
    q += tremor(rng, time.size, h.rate_hz, h.tremor_rad * scale, h.tremor_band_hz)
    return time, q, grip, windows


def imu_recording(rng: np.random.Generator, time: np.ndarray, q: np.ndarray, noise_rad: float,
                  source: str) -> Recording:
    """Six-sensor IMU recording of human joint angles ``q`` (T, 14) rad: random mountings,
    white orientation noise of ``noise_rad`` per axis, quaternions rounded to ``QUAT_DECIMALS``."""
    from scipy.spatial.transform import Rotation

    quats = sensor_quaternions(q, random_mountings(rng))
    out = {}
    for s in SENSORS:
        qs = quats[s]
        if noise_rad > 0:
            noise = Rotation.from_rotvec(rng.normal(0.0, noise_rad, (len(qs), 3)))
            qs = (Rotation.from_quat(qs, scalar_first=True) * noise).as_quat(scalar_first=True)
        qs = qs * np.where(qs[:, :1] < 0, -1.0, 1.0)  # w >= 0: one sign, for readable files
        out[s] = np.round(qs, QUAT_DECIMALS) + 0.0  # + 0.0: no "-0.000000" in files
    return Recording(np.round(time, 9), out, source=source)


def demo_name(k: int) -> str:
    """File stem of demonstration ``k`` (0-based): demo_00, demo_01, ..."""
    return f"demo_{k:02d}"


def generate_demos(count: int = DEFAULT_COUNT, seed: int = DEFAULT_SEED, human: HumanModel = HumanModel(),
                   progress: bool = False) -> list[Demonstration]:
    """Generate ``count`` demonstrations, deterministically from ``seed``.

    Each takes an expert episode at a fresh placement (reset seeds drawn from the generator;
    episodes where the expert fails or a sub-task goes back are skipped) and turns it into a
    human demonstration and its IMU recording (see the module docstring).

    Args:
        count: number of demonstrations, >= 1.
        seed: seed of everything random.
        human: the variability model.
        progress: show a tqdm progress bar on stderr.
    """
    if not isinstance(count, (int, np.integer)) or count < 1:
        raise InputError(f"count: expected a positive integer, got {count!r}")
    from dualarm.envs import make_core

    env = make_core()
    rng = np.random.default_rng(seed)
    demos = []
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=count, desc="demonstrations", unit="demo", file=sys.stderr)
    attempts = 0
    try:
        while len(demos) < count:
            attempts += 1
            if attempts > 20 * count:
                raise RuntimeError(f"the scripted expert solved only {len(demos)} of {attempts - 1} episodes; "
                                   f"is the task configuration changed?")
            env_seed = int(rng.integers(0, 2 ** 31 - 1))
            episode = expert_episode(env, env_seed)
            if episode is None:
                continue
            expert_q, subtasks, grip = episode
            scene = Scene(boxes=env.box_start.copy(), targets=env.targets.copy())
            name = demo_name(len(demos))
            demo_rng = np.random.default_rng([seed, env_seed])
            time, q, human_grip, windows = human_demonstration(
                demo_rng, expert_q, subtasks, grip, env.config.control_period, human)
            rec = imu_recording(demo_rng, time, q, human.noise_rad, source=name)
            demos.append(Demonstration(name, env_seed, time, q, human_grip, windows, rec, expert_q,
                                       subtasks, scene))
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
        env.close()
    return demos


def write_demo_set(demos: list[Demonstration], out_dir: str | os.PathLike) -> list[Path]:
    """Write ``demo_XX.csv.gz`` per demonstration, ``labels.csv`` and ``scene.csv`` (when
    every demonstration has its scene), each atomically.

    Returns:
        the paths written, demonstrations first, then labels and the scene.
    """
    out = Path(out_dir)
    paths = []
    for d in demos:
        path = out / f"{d.name}.csv.gz"
        with atomic_open(path) as f:
            f.write(gzip_bytes(demo_csv_text(d.recording, d.grip)))
        paths.append(path)
    path = out / LABELS_NAME
    with atomic_open(path) as f:
        f.write(labels_csv_text({d.name: d.windows for d in demos}).encode("utf-8"))
    paths.append(path)
    if all(d.scene is not None for d in demos):
        path = out / SCENE_NAME
        with atomic_open(path) as f:
            f.write(scene_csv_text({d.name: d.scene for d in demos}).encode("utf-8"))
        paths.append(path)
    return paths
