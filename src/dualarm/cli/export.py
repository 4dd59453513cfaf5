"""`dualarm export`: a learned episode (or a user's trajectory) in the formats robots read."""

from __future__ import annotations

import argparse
from pathlib import Path


from dualarm.cli.arguments import (FigureFile, InputPath, NewOutput, limit_scale, sample_rate,
                                   seed_number)
from dualarm.errors import InputError

FORMATS = {
    "csv": "our CSV: time, 14 joint angles (rad), grip closure 0-1 per arm (the policy's own "
           "20 ms steps, or time-parameterised with --retime)",
    "baxter": "Baxter SDK joint trajectory file for joint_trajectory_file_playback (time-"
              "parameterised, grippers 0 closed .. 100 open)",
    "ros2": "rosbag2 directory with MCAP storage: trajectory_msgs/JointTrajectory on "
            "/joint_trajectory and /gripper_trajectory, sensor_msgs/JointState on /joint_states",
    "onnx": "both actors with the observation normaliser folded in, one .onnx file "
            "(inputs obs_left, obs_right; outputs action_left, action_right)",
}


def _source_trajectory(args: argparse.Namespace):
    """(trajectory, task config or None, what it is) from a run's episode or a CSV file."""
    from dualarm.export.trajectory import from_episode, read_trajectory_csv

    source = Path(args.source)
    if source.is_dir():
        from dualarm.training.policy import policy_episode

        env, episode, info = policy_episode(source, args.checkpoint, args.seed)
        print(f"{info['checkpoint']}: seed {args.seed}, "
              f"{'success' if episode.success else 'failure'} in {episode.steps} steps")
        trajectory = from_episode(episode, env.config.control_period)
        return trajectory, env.config
    return read_trajectory_csv(source), None


def _print_report(retimed) -> None:
    from dualarm.task import JOINT_COLUMNS

    rep = retimed.report()
    print(f"time-parameterised: {rep['duration_s']:.3f} s (waypoints: {rep['source_duration_s']:.3f} s), "
          f"largest deviation from the waypoints {rep['waypoint_deviation_rad']:.2e} rad")
    print(f"  {'joint':10s} {'peak vel':>9s} {'limit':>6s} {'':>5s} {'peak acc':>9s} {'limit':>6s}")
    for k, name in enumerate(JOINT_COLUMNS):
        print(f"  {name:10s} {rep['peak_velocity'][k]:9.3f} {retimed.limits.velocity[k]:6.2f} "
              f"{100 * rep['velocity_ratio'][k]:4.0f}% {rep['peak_acceleration'][k]:9.3f} "
              f"{retimed.limits.acceleration[k]:6.2f} {100 * rep['acceleration_ratio'][k]:4.0f}%")


def cmd_export(args: argparse.Namespace) -> int:
    """Write a run's episode (or a trajectory CSV) as csv, baxter, ros2 or onnx."""
    source_is_run = Path(args.source).is_dir()
    if args.retime and args.format != "csv":
        raise InputError(f"--retime: csv only; --format {args.format} "
                         + ("is always time-parameterised" if args.format != "onnx"
                            else "exports the policy, not a trajectory") + " (nothing was written)")
    retiming = args.format in ("baxter", "ros2") or args.retime
    checks = [flag for flag, given in (("--plot", args.plot), ("--replay", args.replay)) if given]
    if checks and not retiming:
        raise InputError(f"{' and '.join(checks)}: check a time-parameterised trajectory; use "
                         "--format baxter or ros2, or csv with --retime (nothing was written)")
    if args.format == "onnx":
        if not source_is_run:
            raise InputError(f"{args.source}: --format onnx exports a run's policy; give a run directory")
        from dualarm.export.onnx_policy import check_onnx, export_onnx
        from dualarm.training.policy import load_policy

        config, agent, info = load_policy(args.source, args.checkpoint)
        export_onnx(agent, args.output)
        error = check_onnx(agent, args.output, config)
        print(f"{info['checkpoint']} -> {args.output}: largest difference from PyTorch over "
              f"{error['observations']} observations {error['max_abs']:.1e}")
        return 0
    if not retiming and not source_is_run:
        raise InputError(f"{args.source}: --format csv of a trajectory file would copy it; add "
                         "--retime to time-parameterise it")
    from dualarm.export import formats
    from dualarm.export.retime import Limits, retime
    from dualarm.export.trajectory import write_trajectory_csv

    trajectory, task = _source_trajectory(args)
    if not retiming:
        write_trajectory_csv(args.output, trajectory)
        print(f"wrote {args.output}: {len(trajectory.time)} rows, {trajectory.duration:.2f} s "
              "(time s, 14 joint angles rad, grip closure 0-1 per arm; not time-parameterised)")
        return 0
    limits = Limits.baxter(args.velocity_scale, args.acceleration_scale)
    retimed = retime(trajectory, limits)
    _print_report(retimed)
    samples = retimed.sample(args.rate)
    if args.format == "csv":
        write_trajectory_csv(args.output, samples.as_trajectory())
    elif args.format == "baxter":
        formats.write_baxter_csv(args.output, samples)
    else:
        formats.write_ros2_bag(args.output, samples)
    print(f"wrote {args.output} ({args.format}): {len(samples.time)} points at {args.rate:g} Hz")
    if args.plot:
        from dualarm.export.plots import plot_retimed

        print(f"wrote {plot_retimed(retimed, args.plot)}")
    if args.replay:
        from dualarm.envs.config import TaskConfig
        from dualarm.export.replay import replay

        success, _ = replay(retimed, task or TaskConfig(), args.seed)
        print(f"replayed in the simulator (seed {args.seed}, joint position servos): "
              f"{'both boxes at their targets' if success else 'the task is NOT done'}")
    return 0


def add_export_command(sub) -> None:
    """Add ``export`` to the top-level subparsers."""
    export = sub.add_parser(
        "export", help="a learned episode or a trajectory as csv, baxter, ros2 or onnx",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Run one episode of a run's deterministic policy (or read a trajectory CSV) "
                    "and write it for a robot. baxter and ros2 (and csv with --retime) are "
                    "time-parameterised with toppra within Baxter's joint position, velocity "
                    "and acceleration limits, both arms on one time axis.\n\nformats:\n"
                    + "\n".join(f"  {k:7s} {v}" for k, v in FORMATS.items()))
    export.add_argument("source", type=InputPath, metavar="RUN_OR_CSV",
                        help="a run directory of dualarm train, or a trajectory CSV (time, "
                             "left_s0 .. right_w2, grip_left, grip_right)")
    export.add_argument("-o", "--output", type=NewOutput, required=True, metavar="OUT",
                        help="the file (csv, baxter, onnx) or bag folder (ros2) to create")
    export.add_argument("--format", choices=tuple(FORMATS), default="csv",
                        help="csv (default), baxter, ros2 or onnx")
    export.add_argument("--seed", type=seed_number, default=0, help="the episode's placement seed (default 0)")
    export.add_argument("--checkpoint", choices=("best", "latest"), default="best",
                        help="the best evaluated policy or the last checkpoint (default: best)")
    export.add_argument("--retime", action="store_true",
                        help="csv only: time-parameterise as baxter and ros2 always are")
    export.add_argument("--rate", type=sample_rate, default=100.0, metavar="HZ",
                        help="sample rate of time-parameterised output, at most 1000 Hz "
                             "(default 100 Hz, as Baxter's joint_recorder)")
    export.add_argument("--velocity-scale", type=limit_scale, default=1.0, metavar="S",
                        help="fraction of Baxter's velocity limits to use, in [0.01, 1] (default 1)")
    export.add_argument("--acceleration-scale", type=limit_scale, default=1.0, metavar="S",
                        help="fraction of the acceleration limits to use, in [0.01, 1] (default 1)")
    export.add_argument("--plot", type=FigureFile, metavar="FILE.png",
                        help="also plot position, velocity and acceleration per joint against the limits")
    export.add_argument("--replay", action="store_true",
                        help="replay the time-parameterised trajectory in the simulator with "
                             "joint position servos and say whether the boxes reach their targets")
    export.set_defaults(func=cmd_export)
