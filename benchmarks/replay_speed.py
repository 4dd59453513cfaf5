"""Time to replay a demonstration folder's recordings at their scenes and to move them to new
placements (what `dualarm train --demos` does once at start-up, and `dualarm demos replay
--moved`): loading and mapping the recordings, the replays, then the moved replays."""

from __future__ import annotations

import argparse
import platform
import time
from pathlib import Path

import torch

from dualarm.demos.formats import DEFAULT_DEMO_DIR
from dualarm.envs import make_core
from dualarm.sim_demos.augment import augment
from dualarm.sim_demos.replay import (DEFAULT_STEPS, load_replay_folder,
                                      replay_demonstration)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("demo_dir", nargs="?", type=Path, default=DEFAULT_DEMO_DIR,
                        help="demonstration folder (default: the shipped set)")
    parser.add_argument("--steps", type=int, default=DEFAULT_STEPS, help="retimed task window")
    parser.add_argument("--repeats", type=int, default=3, help="timed repeats; the median is printed")
    parser.add_argument("--moved", type=int, default=64,
                        help="moved episodes per repeat (train --demos makes 256)")
    args = parser.parse_args()
    env = make_core()
    loads, replays, moves, steps, wins = [], [], [], 0, 0
    for _ in range(args.repeats):
        t = time.perf_counter()
        demos, labels, scenes = load_replay_folder(args.demo_dir, env.config.workspace())
        loads.append(time.perf_counter() - t)
        t = time.perf_counter()
        results = [replay_demonstration(env, d, labels[d.name], scenes[d.name], steps=args.steps)
                   for d in demos]
        replays.append(time.perf_counter() - t)
        steps, wins = sum(r.steps for r in results), sum(r.success for r in results)
        t = time.perf_counter()
        moved = augment(env, demos, labels, scenes, args.moved, seed=1_000_003, steps=args.steps)
        moves.append(time.perf_counter() - t)
    env.close()
    load, replay = sorted(loads)[len(loads) // 2], sorted(replays)[len(replays) // 2]
    print(f"torch {torch.__version__}, {platform.processor() or platform.machine()}; "
          f"{len(demos)} recordings, K = {args.steps}, "
          f"median of {args.repeats}")
    print(f"load and map: {load:.2f} s ({1000 * load / len(demos):.0f} ms per recording)")
    print(f"replay: {replay:.2f} s, {steps} steps ({1000 * replay / steps:.2f} ms per step); "
          f"{wins} of {len(demos)} succeed")
    move = sorted(moves)[len(moves) // 2]
    print(f"moved: {move:.2f} s for {moved.attempts} placements, {len(moved.replays)} succeed "
          f"({1000 * move / moved.attempts:.0f} ms per placement)")


if __name__ == "__main__":
    main()
