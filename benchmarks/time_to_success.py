"""Wall time to a success rate with the shipped recordings: the whole of `dualarm train
--demos`, from the config to the evaluation that reaches ``--stop-at`` (default 0.85), on one
torch thread, split into making the demonstrations (replays at their own scenes and moved to
new placements) and training (episodes, updates, evaluations).

Run:  python benchmarks/time_to_success.py [--seed 0] [--config FILE.yaml] [--stop-at 0.85]
                                          [--episodes 1600] [--no-demos] [--bf16]

The run is the recipe with the recordings (``TrainConfig().with_(demos=...)``; ``--config``
for another base), evaluations every 80 episodes on 50 placements, stopped at the first
evaluation that reaches ``--stop-at``. ``--bf16`` multiplies the hidden layers in bfloat16
(``algo.bf16_matmuls``; faster on a CPU with native bfloat16). Prints the machine, the episodes
and the seconds. A run that never reaches it reports the budget and says so. Nothing else
should run on the machine: the figure is one core's.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import torch

from dualarm.rl.daddpg import native_bf16
from dualarm.training.config import TrainConfig
from dualarm.training.loop import Trainer
from env_speed import machine   # this folder is on the path when run as a script

SHIPPED_DEMOS = Path(__file__).resolve().parents[1] / "src" / "dualarm" / "data" / "demos"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--config", type=Path, help="base TrainConfig (YAML; default: the recipe)")
    parser.add_argument("--demos", type=Path, default=SHIPPED_DEMOS, help="demonstration folder")
    parser.add_argument("--no-demos", action="store_true", help="the base config alone")
    parser.add_argument("--stop-at", type=float, default=0.85)
    parser.add_argument("--episodes", type=int, default=1600, help="budget (default 1600)")
    parser.add_argument("--bf16", action="store_true", help="algo.bf16_matmuls: true")
    args = parser.parse_args()
    torch.set_num_threads(1)
    config = TrainConfig.load(args.config) if args.config else TrainConfig()
    config = config.with_(episodes=args.episodes, eval_every=80, eval_episodes=50,
                          stop_at=args.stop_at, seed=args.seed, torch_threads=1,
                          checkpoint_minutes=1e6)
    if args.bf16:
        config = config.with_(algo=config.algo.with_(bf16_matmuls=True))
    if not args.no_demos:
        config = config.with_(demos=str(args.demos))
    a = config.algo
    print(f"{machine()}; torch {torch.__version__}")
    print(f"seed {args.seed}, demos {'off' if args.no_demos else config.demos.folder} "
          f"({config.demos.episodes} moved), updates/step {a.updates_per_step}, "
          f"batch {a.batch_size} + {a.demo_batch_size} demonstration rows, hidden {a.hidden}, "
          f"hidden layers in {'bfloat16' if a.bf16_matmuls else 'float32'}"
          + ("" if native_bf16() or not a.bf16_matmuls else " (emulated: no native bfloat16)"))
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        start = time.perf_counter()
        trainer = Trainer.start(config, out, progress=False)
        made = time.perf_counter() - start
        try:
            result = trainer.run()
        finally:
            trainer.close()
        total = time.perf_counter() - start
    t, last = trainer.timing, result.last_eval
    reached = "reached" if result.stopped else "NOT reached (censored at the budget)"
    print(f"{args.stop_at:.2f} {reached} at episode {last['episode']} "
          f"(evaluation {float(last['success_rate']):.2f}), {t['updates']} updates")
    print(f"wall time {total:.1f} s: start (replays, moved demonstrations, networks) {made:.1f} s, "
          f"training {total - made:.1f} s (updates {t['update_s']:.1f} s, "
          f"collecting {t['collect_s']:.1f} s, evaluations and probes {t['eval_s']:.1f} s)")


if __name__ == "__main__":
    main()
