"""DADDPG update speed: updates per second and GFLOP/s, next to this machine's matmul roofline.

Run:  python benchmarks/update_speed.py [--threads 1] [--seconds 3] [--recipe]

``--recipe`` times the recipe's own learner (``RECIPE_ALGO`` with ``DEMOS_ALGO``'s demonstration
rows and cloning, as ``dualarm train --demos`` runs it) at its 128 x 128 layers in float32 and
with the hidden layers in bfloat16 (``bf16_matmuls``), and at 64 x 64, instead of the
plain-DDPG shapes below.

For each network size and batch size it times ``DADDPG.update`` on random transitions of
the Baxter task's shapes (2 agents, 29 or 36 observations, 4 actions), counts the matmul
FLOPs of one update (``DADDPG.update_flops``), and divides by the best single-matmul rate
measured in the same run at the update's own layer shapes (the roofline an update could
reach if it were nothing but matmuls).
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np
import torch

from dualarm.rl import DADDPG, DADDPGConfig
from dualarm.rl.replay import ReplayBuffer
from dualarm.training.config import DEMOS_ALGO, RECIPE_ALGO


def matmul_gflops(m: int, k: int, n: int, seconds: float, dtype: torch.dtype = torch.float32) -> float:
    """Best GFLOP/s of (m x k) @ (k x n) in ``dtype`` over repeated timed bursts."""
    a, b = torch.randn(m, k, dtype=dtype), torch.randn(k, n, dtype=dtype)
    for _ in range(10):
        a @ b
    best, end = 0.0, time.perf_counter() + seconds
    while time.perf_counter() < end:
        t = time.perf_counter()
        for _ in range(20):
            a @ b
        best = max(best, 20 * 2 * m * k * n / (time.perf_counter() - t) / 1e9)
    return best


def time_updates(config: DADDPGConfig, obs: int, seconds: float) -> tuple[float, float]:
    """Median seconds per dual-agent update, and its matmul FLOPs (demonstration rows, if
    any, are drawn from the same random transitions and counted in the batch)."""
    agent = DADDPG(config, (obs, obs), (4, 4))
    rng = np.random.default_rng(0)
    buf = ReplayBuffer(20_000, 2, obs, 4)
    n = 20_000
    buf.add(rng.normal(size=(n, 2, obs)), rng.uniform(-1, 1, (n, 2, 4)), rng.normal(size=(n, 2)),
            rng.normal(size=(n, 2, obs)), np.zeros(n))
    agent.normalizer.update(rng.normal(size=(1000, 2, obs)))
    rows = config.batch_size + config.demo_batch_size
    for _ in range(5):
        agent.update(buf.sample(rng, rows), config.demo_batch_size)
    times, end = [], time.perf_counter() + seconds
    while time.perf_counter() < end or len(times) < 5:
        t = time.perf_counter()
        agent.update(buf.sample(rng, rows), config.demo_batch_size)
        times.append(time.perf_counter() - t)
    return float(np.median(times)), agent.update_flops(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=1, help="torch intra-op threads (default 1)")
    parser.add_argument("--seconds", type=float, default=3.0, help="timing per case (default 3)")
    parser.add_argument("--obs", type=int, default=36, help="observation width per agent (default 36)")
    parser.add_argument("--recipe", action="store_true",
                        help="the recipe's learner with demonstration rows, 128 x 128 and 64 x 64")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    print(f"torch {torch.__version__}, {args.threads} thread(s), {platform.processor() or platform.machine()}")
    # (hidden, batch, options beyond the defaults)
    demos = {"demo_batch_size": 64, "bc_weight": 30.0}
    cases = [((256, 256, 256), 256, {}), ((256, 256), 256, {}), ((128, 128, 128), 256, {}),
             ((128, 128), 256, {}), ((256, 256, 256), 128, {}),
             ((256, 256), 256, {"twin_critics": True}), ((128, 128), 256, {"twin_critics": True}),
             ((256, 256), 256, demos)]
    print(f"{'hidden':>16} {'batch':>5} {'twin':>4} {'demo':>4} {'bf16':>4} {'GFLOP/upd':>9} "
          f"{'ms/upd':>7} {'upd/s':>6} {'GFLOP/s':>7} {'roofline':>8} {'ratio':>5}")
    if args.recipe:
        configs = [RECIPE_ALGO.with_(hidden=hidden, buffer_size=20_000, bf16_matmuls=bf16, **DEMOS_ALGO)
                   for hidden, bf16 in (((128, 128), False), ((128, 128), True), ((64, 64), False))]
    else:
        configs = [DADDPGConfig(hidden=hidden, batch_size=batch, buffer_size=20_000, **options)
                   for hidden, batch, options in cases]
    for config in configs:
        hidden, batch = config.hidden, config.batch_size
        flags = [config.twin_critics, config.demo_batch_size > 0, config.bf16_matmuls]
        dt, flops = time_updates(config, args.obs, args.seconds)
        # the roofline: the matmul rate of the update's hidden layer shape (batch x h @ h x h)
        peak = matmul_gflops(2 * batch, hidden[-1], hidden[-1], min(1.0, args.seconds),
                             torch.bfloat16 if config.bf16_matmuls else torch.float32)
        rate = flops / dt / 1e9
        print(f"{'x'.join(map(str, hidden)):>16} {batch:>5} "
              + " ".join(f"{'yes' if f else 'no':>4}" for f in flags)
              + f" {flops / 1e9:>9.3f} {dt * 1e3:>7.2f} {1 / dt:>6.1f} {rate:>7.1f} {peak:>8.1f} "
              f"{rate / peak:>5.2f}")
    big = matmul_gflops(1024, 1024, 1024, min(2.0, args.seconds))
    print(f"large matmul (1024^3) peak: {big:.1f} GFLOP/s")


if __name__ == "__main__":
    main()
