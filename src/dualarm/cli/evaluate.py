"""`dualarm eval`: success rate and return of a run's policy on the fixed evaluation episodes."""

from __future__ import annotations

import argparse

from dualarm.cli.arguments import positive_int, run_options
from dualarm.rl.config import EVAL_ACTORS
from dualarm.task import SUBTASKS


def cmd_eval(args: argparse.Namespace) -> int:
    """Success rate and mean return of a run's policy on the fixed evaluation episodes."""
    from dualarm.training.evaluation import evaluate
    from dualarm.training.vector import make_vector_env
    from dualarm.training.policy import load_actors, policy_heading

    config, agent, info = load_actors(args.run, args.checkpoint, args.actor)
    for start in dict.fromkeys(args.start):                      # each start once, in order
        vec = make_vector_env(config, min(config.num_envs, args.episodes),
                              start=SUBTASKS.index(start))
        result = evaluate(lambda o: agent.act(o), vec, args.episodes)
        where = "" if start == "reach" else f", both arms starting at {start}"
        print(f"{policy_heading(info)}, "
              f"{args.episodes} evaluation episodes{where}:")
        print(f"  success rate  {result.success_rate:.3f} ({int(result.success.sum())}/{args.episodes})")
        print(f"  return        {result.mean_return:.1f} (mean, both arms)")
        print(f"  steps         {result.steps.mean():.1f} (mean)")
    return 0


def add_eval_command(sub) -> None:
    """Add ``eval`` to the top-level subparsers."""
    ev = sub.add_parser("eval", help="success rate and return of a trained policy",
                        description="Evaluate a run's policy on the fixed set of evaluation episodes.")
    run_options(ev)
    ev.add_argument("--episodes", type=positive_int, default=100,
                    help="evaluation episodes, each at its own seeded placement (default: 100)")
    ev.add_argument("--start", choices=SUBTASKS, nargs="+", default=["reach"],
                    help="the sub-tasks both arms start at, one evaluation each: reach (the "
                         "normal reset, default), grasp (at the boxes, fingers open), align "
                         "(holding them): how well each link of the task is learned")
    ev.add_argument("--actor", choices=EVAL_ACTORS, default=None,
                    help="the actors, the target actors (their Polyak averages, Eq. 15, which "
                         "act more steadily late in a run) or the averaged actors of "
                         "algo.policy_average. Default: the run's own "
                         "(algo.eval_actor), from --checkpoint; the other ones are read "
                         "from the latest checkpoint, whatever --checkpoint says")
    ev.set_defaults(func=cmd_eval)
