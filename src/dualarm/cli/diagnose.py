"""`dualarm diagnose`: where a run's policy fails, per arm and link of the task."""

from __future__ import annotations

import argparse

from dualarm.cli.arguments import positive_int, run_options
from dualarm.rl.config import EVAL_ACTORS
from dualarm.task import SUBTASKS


def cmd_diagnose(args: argparse.Namespace) -> int:
    """Outcome of each arm's episodes (``dualarm.training.outcomes``) from each start asked for."""
    from dualarm.errors import InputError
    from dualarm.training.vector import make_vector_env
    from dualarm.training.outcomes import link_outcomes
    from dualarm.training.policy import load_actors, policy_heading

    if args.critic:
        return _critic_table(args)
    config, agent, info = load_actors(args.run, args.checkpoint, args.actor)
    task = config.task_config()
    if task.control != "cartesian":
        raise InputError(f"{args.run}: dualarm diagnose reads cartesian-control runs only")
    constraints = config.load_constraints()
    print(f"{policy_heading(info)}, "
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


#: the steps of an episode at which ``--critic`` compares Q with the observed return
CRITIC_STEPS = (0, 5, 10, 15, 20, 30, 40, 60, 80)


def _critic_table(args: argparse.Namespace) -> int:
    """Each arm's critic Q(s_t, a_t) next to the discounted return observed from step t, in
    the learner's units, from each start asked for (the latest checkpoint: the critics)."""
    from dualarm.training.diagnostics import critic_vs_returns
    from dualarm.training.vector import make_vector_env
    from dualarm.training.shaping import shaping_potential
    from dualarm.training.policy import load_learner

    config, agent, info = load_learner(args.run)
    potential = shaping_potential(config)
    constraints = config.load_constraints()
    print(f"{info['checkpoint']} (after {info['episodes']} training episodes), {args.episodes} "
          f"episodes per start, deterministic policy; Q and the observed discounted return G "
          f"in the learner's units{' (shaped, as the learner sees them)' if potential else ''}:")
    for start in args.start:
        vec = make_vector_env(config, min(config.num_envs, args.episodes), constraints=constraints,
                              start=SUBTASKS.index(start))
        r = critic_vs_returns(agent, vec, args.episodes, potential=potential)
        vec.close()
        where = "the normal reset" if start == "reach" else f"both arms at {start}"
        print(f"\nfrom {where}: Q - G over all {r.steps} steps: left {r.bias[0]:+.3f}, "
              f"right {r.bias[1]:+.3f}")
        print(f"  {'step':>4} {'episodes':>8} {'Q left':>8} {'G left':>8} {'Q right':>8} {'G right':>8}")
        for t in CRITIC_STEPS:
            if t < len(r.episodes_by_step):
                q, g = r.q_by_step[t], r.return_by_step[t]
                print(f"  {t:>4} {r.episodes_by_step[t]:>8} {q[0]:>+8.3f} {g[0]:>+8.3f} "
                      f"{q[1]:>+8.3f} {g[1]:>+8.3f}")
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
    p.add_argument("--actor", choices=EVAL_ACTORS, default=None,
                   help="the actors acting, as dualarm eval's --actor: online, target or "
                        "average (algo.policy_average's); default the run's own, from "
                        "--checkpoint; the others from the latest checkpoint")
    p.add_argument("--critic", action="store_true",
                   help="instead: each arm's critic Q next to the discounted return its "
                        "policy really collects, by step of the episode (the latest "
                        "checkpoint, which holds the critics; --checkpoint is ignored)")
    p.set_defaults(func=cmd_diagnose)
