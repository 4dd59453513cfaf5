"""Training speed of whole rounds: episodes per second, split into stepping the environments,
choosing actions, storing transitions and gradient updates, with the update's GFLOP/s next
to the matrix-multiply roofline measured in the same run.

Run:  python benchmarks/train_speed.py [--config FILE.yaml] [--episodes N] [--no-eval] [--threads 1]

It trains a fresh run (in a temporary directory) for ``--episodes`` episodes after a
warm-up of ``--warmup`` episodes that is not counted, and reads the trainer's own timers
(``Trainer.timing``). Evaluations (and curriculum probes) run as the config sets them, so
the figure is a whole run's; ``--no-eval`` times the training rounds alone. The last line
extrapolates to a 10,000-episode run at the measured rate.
"""

from __future__ import annotations

import argparse
import platform
import tempfile
import time
from pathlib import Path

import torch

from dualarm.training.config import TrainConfig
from dualarm.training.loop import Trainer
from update_speed import matmul_gflops   # this folder is on the path when run as a script


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", type=Path, help="TrainConfig fields (YAML), as `dualarm train --config`")
    parser.add_argument("--episodes", type=int, help="timed episodes (default: twice the "
                        "config's eval_every, or 160 without evaluations)")
    parser.add_argument("--warmup", type=int, help="untimed episodes first (default: eval_every, "
                        "or 64 without evaluations)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (default 1)")
    parser.add_argument("--no-eval", action="store_true",
                        help="turn evaluations and curriculum probes off: the training rounds alone")
    args = parser.parse_args()
    # the config as `dualarm train --config` reads it (``extends`` included), then the
    # benchmark's own settings
    config = TrainConfig.load(args.config) if args.config else TrainConfig()
    config = config.with_(torch_threads=args.threads, checkpoint_minutes=1e6)
    if args.no_eval:
        config = config.with_(eval_every=0, starts={"probe": 0})
    every = config.eval_every
    episodes = args.episodes or (2 * every if every else 160)
    warmup = args.warmup or (every if every else 64)
    if every and (episodes % every or warmup % every):
        # a run evaluates every eval_every episodes and at its end: multiples of eval_every
        # time exactly one evaluation per eval_every episodes
        parser.error(f"--episodes {episodes} and --warmup {warmup} must be multiples of the "
                     f"config's eval_every ({every}), or give --no-eval")
    config = config.with_(episodes=warmup)
    print(f"torch {torch.__version__}, {args.threads} thread(s), "
          f"{platform.processor() or platform.machine()}; condition {config.condition}, "
          f"{config.num_envs} copies, hidden {config.algo.hidden}, batch {config.algo.batch_size}, "
          f"{config.algo.updates_per_step} updates/step; evaluation every {config.eval_every} "
          f"episodes ({config.eval_episodes} episodes, {config.starts.probe} probes per later start)")
    with tempfile.TemporaryDirectory() as tmp:
        trainer = Trainer.start(config, Path(tmp) / "run", progress=False)
        trainer.run()                                   # warm-up: replay fills, updates start
        before = dict(trainer.timing)
        trainer.config = config.with_(episodes=warmup + episodes)
        start = time.perf_counter()
        trainer.run()
        total = time.perf_counter() - start
        t = {k: trainer.timing[k] - before[k] for k in before}
    env = t["collect_s"] - t["act_s"] - t["store_s"]
    other = total - t["collect_s"] - t["update_s"] - t["eval_s"]
    flops = trainer.agent.update_flops() * t["updates"]
    update_rate = flops / t["update_s"] / 1e9 if t["update_s"] else float("nan")
    h = config.algo.hidden[-1]
    roofline = matmul_gflops(2 * config.algo.batch_size, h, h, 1.0)
    print(f"episodes {t['episodes']}, env steps {t['env_steps']}, updates {t['updates']}, "
          f"{total:.1f} s: {t['episodes'] / total:.2f} episodes/s, {t['env_steps'] / total:.0f} env steps/s")
    for name, seconds in (("environment stepping", env), ("acting (policy + noise)", t["act_s"]),
                          ("storing transitions", t["store_s"]), ("gradient updates", t["update_s"]),
                          ("evaluations, probes", t["eval_s"]), ("logging, checkpoints", other)):
        print(f"  {name:<26} {seconds:7.1f} s  {100 * seconds / total:5.1f} %")
    print(f"  update: {1e3 * t['update_s'] / max(t['updates'], 1):.2f} ms, {update_rate:.1f} GFLOP/s "
          f"against a {roofline:.1f} GFLOP/s matmul roofline ({update_rate / roofline:.2f})")
    print(f"10,000 episodes at this rate: {10_000 / (t['episodes'] / total) / 60:.1f} min")


if __name__ == "__main__":
    main()
