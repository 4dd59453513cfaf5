"""`dualarm diagnose`: where a run's policy fails, per arm and link of the task."""

from __future__ import annotations

import argparse

from dualarm.cli.arguments import positive_int, run_options
from dualarm.task import SUBTASKS


def cmd_diagnose(args: argparse.Namespace) -> int:
    """Outcome of each arm's episodes (``dualarm.training.outcomes``) from each start asked for."""
    from dualarm.errors import InputError
    from dualarm.training.loop import make_vector_env
    from dualarm.training.outcomes import link_outcomes
    from dualarm.training.policy import load_policy

    config, agent, info = load_policy(args.run, args.checkpoint)
    task = config.task_config()
    if task.control != "cartesian":
        raise InputError(f"{args.run}: dualarm diagnose reads cartesian-control runs only")
    constraints = config.load_constraints()
    print(f"{info['checkpoint']} (after {info['episodes']} training episodes), "
          f"{args.episodes} episodes per start, deterministic policy:")
    for start in args.start:
        vec = make_vector_env(config, min(config.num_envs, args.episodes), constraints=constraints,
                              start=SUBTASKS.index(start))
        report = link_outcomes(lambda o: agent.act(o), vec, task, args.episodes)
        vec.close()
        where = "the normal reset" if start == "reach" else f"both arms at {start}"
        print(f"\nfrom {where}: success {report.success_rate:.2f} "
              f"({int(report.success.sum())}/{args.episodes})")
        print(report.table())
    return 0


def add_diagnose_command(sub) -> None:
    """Add ``diagnose`` to the top-level subparsers."""
    p = sub.add_parser("diagnose", help="where a trained policy fails, arm by arm",
                       description="Run a policy's deterministic episodes from the normal reset "
                                   "and from later sub-tasks, and count per arm where each "
                                   "episode stopped: still at home, reached but not closed, "
                                   "closed off the box, not lifted, slid out, dropped, held "
                                   "away from the target, or aligned.")
    run_options(p)
    p.add_argument("--episodes", type=positive_int, default=32,
                   help="episodes per start (default 32)")
    p.add_argument("--start", choices=SUBTASKS, nargs="+", default=list(SUBTASKS),
                   help="the sub-tasks both arms start at (default: all three): reach is "
                        "the normal reset, grasp at the boxes with the fingers open, align "
                        "holding them")
    p.set_defaults(func=cmd_diagnose)
