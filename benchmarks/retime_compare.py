"""toppra against ruckig on the project's own trajectories: which time parameterisation to use.

Usage: python benchmarks/retime_compare.py [--episodes 10]

Trajectories: the scripted expert's episodes of the full task (seeds 0..N-1), both arms and
grips, 20 ms between waypoints. Limits: Baxter's velocity limits and our acceleration limits
(dualarm.export.retime), the grips' closure rate. For each method the script prints the mean
duration, the largest ratio of |velocity| and |acceleration| to its limit (sampled at 1 kHz),
the largest departure (rad) of the motion from the straight joint-space segment between two
waypoints, and the time to compute.

* toppra (ours): a monotone cubic through the waypoints, traversed time-optimally (TOPP-RA).
* ruckig, stop at each waypoint: one time-optimal, time-synchronised motion per segment
  from rest to rest (what ruckig's community version does without intermediate waypoints).
* ruckig, through each waypoint: per segment, the waypoint velocities are the toppra path's
  tangent scaled to the largest speed the velocity limits allow (ruckig itself picks none).

Ruckig also limits jerk; it is set high (1000 rad/s^3) so that both methods answer to the
same velocity and acceleration limits.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from dualarm.envs.baxter import BaxterReachGraspAlign
from dualarm.envs.config import TaskConfig
from dualarm.envs.rollout import make_policy, run_episode
from dualarm.export.retime import Limits, _MonotonePath, retime
from dualarm.export.trajectory import from_episode


def expert_episode(env, seed):
    episode = run_episode(env, make_policy("expert", env), seed)
    return from_episode(episode, env.config.control_period)


def chord_departure(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Largest distance (rad, 14-D) of points (N, 14) from the line through a and b."""
    d = b - a
    n = float(d @ d)
    rel = points - a
    if n < 1e-18:
        return float(np.sqrt((rel * rel).sum(1)).max())
    along = np.clip(rel @ d / n, 0, 1)
    off = rel - along[:, None] * d
    return float(np.sqrt((off * off).sum(1)).max())


def ruckig_segments(traj, limits: Limits, through: bool):
    from ruckig import InputParameter, Result, Ruckig, Trajectory

    dofs = 16
    vmax = np.concatenate([limits.velocity, [limits.grip_velocity] * 2])
    amax = np.concatenate([limits.acceleration, [limits.grip_acceleration] * 2])
    points = np.hstack([traj.joints, traj.grip])
    tangents = np.zeros_like(points)
    if through:
        path = _MonotonePath(traj.time, points)
        d = path(traj.time, 1)
        scale = np.min(np.where(np.abs(d) > 1e-12, vmax / np.maximum(np.abs(d), 1e-12), np.inf), axis=1)
        tangents = 0.999 * d * np.where(np.isfinite(scale), scale, 0.0)[:, None]
        tangents[[0, -1]] = 0.0
    otg, inp = Ruckig(dofs), InputParameter(dofs)
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = vmax, amax, np.full(dofs, 1000.0)
    total, peak_v, peak_a, departure = 0.0, 0.0, 0.0, 0.0
    for k in range(len(points) - 1):
        inp.current_position, inp.current_velocity = points[k], tangents[k]
        inp.current_acceleration = np.zeros(dofs)
        inp.target_position, inp.target_velocity = points[k + 1], tangents[k + 1]
        inp.target_acceleration = np.zeros(dofs)
        out = Trajectory(dofs)
        if otg.calculate(inp, out) not in (Result.Working, Result.Finished):
            raise RuntimeError(f"ruckig failed on segment {k}")
        ts = np.linspace(0, out.duration, 50)
        pos, vel, acc = (np.array(x) for x in zip(*(out.at_time(t) for t in ts)))
        peak_v = max(peak_v, float((np.abs(vel[:, :14]) / limits.velocity).max()))
        peak_a = max(peak_a, float((np.abs(acc[:, :14]) / limits.acceleration).max()))
        departure = max(departure, chord_departure(pos[:, :14], points[k, :14], points[k + 1, :14]))
        total += out.duration
    return total, peak_v, peak_a, departure


def toppra_stats(traj, limits):
    r = retime(traj, limits)
    rep = r.report()
    s = r.sample(1000)
    departure = 0.0
    for k in range(len(traj.time) - 1):
        inside = (s.time >= r.waypoint_time[k]) & (s.time <= r.waypoint_time[k + 1])
        if inside.any():
            departure = max(departure, chord_departure(s.joints[inside], traj.joints[k], traj.joints[k + 1]))
    return r.duration, rep["velocity_ratio"].max(), rep["acceleration_ratio"].max(), departure


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--episodes", type=int, default=10)
    args = p.parse_args()
    env = BaxterReachGraspAlign(TaskConfig(condition="none"))
    trajectories = [expert_episode(env, s) for s in range(args.episodes)]
    limits = Limits.baxter()
    methods = {"toppra (ours)": lambda t: toppra_stats(t, limits),
               "ruckig, stop at each waypoint": lambda t: ruckig_segments(t, limits, False),
               "ruckig, through each waypoint": lambda t: ruckig_segments(t, limits, True)}
    print(f"{args.episodes} expert episodes, {np.mean([len(t.time) for t in trajectories]):.1f} "
          f"waypoints each ({np.mean([t.duration for t in trajectories]):.2f} s in the simulator)")
    print(f"{'method':32s} {'duration s':>10s} {'max v/limit':>11s} {'max a/limit':>11s} "
          f"{'departure rad':>13s} {'compute ms':>10s}")
    for name, method in methods.items():
        start = time.perf_counter()
        rows = np.array([method(t) for t in trajectories])
        ms = 1000 * (time.perf_counter() - start) / len(trajectories)
        print(f"{name:32s} {rows[:, 0].mean():10.2f} {rows[:, 1].max():11.3f} {rows[:, 2].max():11.3f} "
              f"{rows[:, 3].max():13.4f} {ms:10.1f}")


if __name__ == "__main__":
    main()
