"""Does a learned policy's motion survive time parameterisation? Success of the policy's own
episodes against success of their retimed trajectories followed by the joint servos.

Usage: python benchmarks/export_replay.py RUN [--placements 50] [--strip FILE.png]
                                             [--plot FILE.png] [--checkpoint best|latest]

For each of ``--placements`` placements (reset seeds 0..N-1): one episode of the run's
deterministic policy in its own task (cartesian control), its joint trajectory and grips
retimed within Baxter's limits (``dualarm.export.retime``), then replayed from the same
reset in the joint-control simulator, the position servos following the retimed joints
at every physics step (``dualarm.export.replay``). Prints both success rates, the durations
and the peak ratios to the limits; ``--strip`` writes frames of placement 0's replay,
``--plot`` its check plot.
"""

from __future__ import annotations

import argparse

import imageio.v3 as iio
import numpy as np
from tqdm import tqdm

from dualarm.atomic import atomic_open
from dualarm.training.policy import policy_episode
from dualarm.export.plots import plot_retimed
from dualarm.export.replay import replay
from dualarm.export.retime import retime
from dualarm.export.trajectory import from_episode


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("run")
    p.add_argument("--placements", type=int, default=50)
    p.add_argument("--checkpoint", default="best")
    p.add_argument("--strip")
    p.add_argument("--plot")
    p.add_argument("--frames", type=int, default=6)
    args = p.parse_args()
    policy_ok, replay_ok, durations, source, peaks = [], [], [], [], []
    for seed in tqdm(range(args.placements), desc="placements"):
        env, episode, _ = policy_episode(args.run, args.checkpoint, seed)
        trajectory = from_episode(episode, env.config.control_period)
        r = retime(trajectory)
        rep = r.report()
        camera = "front" if (seed == 0 and args.strip) else None
        ok, frames = replay(r, env.config, seed, camera=camera, frame_every_s=r.duration / (args.frames - 1))
        policy_ok.append(episode.success)
        replay_ok.append(ok)
        durations.append(r.duration)
        source.append(trajectory.duration)
        peaks.append((rep["velocity_ratio"].max(), rep["acceleration_ratio"].max()))
        if seed == 0 and args.plot:
            plot_retimed(r, args.plot)
        if camera:
            strip = np.concatenate(frames[:args.frames], axis=1)
            with atomic_open(args.strip) as f:
                iio.imwrite(f, strip, extension=".png")
    policy_ok, replay_ok = np.array(policy_ok), np.array(replay_ok)
    peaks = np.array(peaks)
    n = args.placements
    print(f"{args.run} ({args.checkpoint}), {n} placements")
    print(f"  the policy's own episodes:  success {policy_ok.mean():.2f} ({policy_ok.sum()}/{n}), "
          f"{np.mean(source):.2f} s of simulated motion on average")
    print(f"  retimed and replayed:       success {replay_ok.mean():.2f} ({replay_ok.sum()}/{n}); "
          f"of the policy's successes {replay_ok[policy_ok].sum()}/{policy_ok.sum()}")
    print(f"  retimed duration            {np.mean(durations):.2f} s mean, {np.max(durations):.2f} s max")
    print(f"  peak |velocity| / limit     {peaks[:, 0].max():.3f}; |acceleration| / limit {peaks[:, 1].max():.3f}")


if __name__ == "__main__":
    main()
