"""`dualarm demos generate | segment | replay`: demonstration sets, and the options the constraints
commands share with them (demonstration folder, labels, mapping)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from dualarm.cli.arguments import (InputPath, OutputDir, OutputFile, calibration_arguments, non_negative,
                                   positive_int, seed_number)
from dualarm.demos.formats import DEFAULT_DEMO_DIR, LABELS_NAME
from dualarm.demos.loading import DEFAULT_LOWPASS_HZ, MappingOptions
from dualarm.errors import InputError


def demo_dir_of(args: argparse.Namespace) -> Path:
    """The command's demonstration folder: DEMO_DIR, or the shipped set."""
    return Path(args.demo_dir) if args.demo_dir is not None else DEFAULT_DEMO_DIR


def mapping_options_of(args: argparse.Namespace) -> MappingOptions:
    """The mapping options (calibration window, heading, low-pass) the command was given."""
    return MappingOptions(calib_seconds=args.calib_seconds, calib_start=args.calib_start, heading=args.heading,
                          lowpass_hz=args.lowpass_hz, calib_pose=args.calib_pose)


def check_suffix(path: Path, suffixes: tuple[str, ...]) -> None:
    """Refuse an output file whose name does not end in one of ``suffixes``."""
    if not path.name.lower().endswith(suffixes):
        raise InputError(f"output must end in {' or '.join(suffixes)}", source=str(path))


def cmd_demos_generate(args: argparse.Namespace) -> int:
    """Generate a demonstration set (IMU CSVs, labels and scene) from the scripted expert."""
    from dualarm.sim_demos.generate import generate_demos, write_demo_set

    out = Path(args.output)
    demos = generate_demos(args.count, args.seed, progress=not args.quiet)
    paths = write_demo_set(demos, out)
    if not args.quiet:
        for d in demos:
            print(f"{d.name}: env seed {d.env_seed}, {d.time[-1]:.2f} s, {len(d.time)} samples", file=sys.stderr)
        others = ", ".join(p.name for p in paths[len(demos):])
        print(f"wrote {len(demos)} recordings, {others} in {out}/", file=sys.stderr)
    return 0


def cmd_demos_segment(args: argparse.Namespace) -> int:
    """Segment demonstrations automatically; compare with labels when there are any."""
    from dualarm.demos.labels import read_labels, write_labels
    from dualarm.demos.loading import load_demo_dir
    from dualarm.demos.segmentation import segment_demos, segmentation_agreement

    if args.output:
        check_suffix(args.output, (".csv",))
    demo_dir = demo_dir_of(args)
    demos, _ = load_demo_dir(demo_dir, options=mapping_options_of(args), require_labels=False, with_grip=True)
    auto = segment_demos(demos, args.calib_start + args.calib_seconds, use_grip=not args.no_grip)
    labels_path = Path(args.labels) if args.labels else demo_dir / LABELS_NAME
    if args.labels or labels_path.exists():
        labels = read_labels(labels_path)
        errors, agree = [], []
        print("demo      boundary |auto - label| [s] per arm: reach start, grasp start, align start, "
              "align end   frames agreeing")
        for d in demos:
            if d.name not in labels:
                continue
            r = segmentation_agreement(d.time, auto[d.name], labels[d.name].windows)
            errors.append(r["boundary_error_s"])
            agree.append(r["frame_agreement"])
            e = r["boundary_error_s"]
            print(f"{d.name:<9} left {' '.join(f'{x:.3f}' for x in e[0])}  right "
                  f"{' '.join(f'{x:.3f}' for x in e[1])}   {100 * r['frame_agreement'].mean():.1f}%")
        if errors:
            e = np.stack(errors)
            print(f"mean      {' '.join(f'{x:.3f}' for x in e.mean(axis=(0, 1)))} (both arms)   "
                  f"{100 * np.mean(agree):.1f}%")
            print(f"max       {' '.join(f'{x:.3f}' for x in e.max(axis=(0, 1)))}")
    if args.output:
        write_labels(args.output, auto)
        print(f"wrote {args.output}", file=sys.stderr)
    return 0


def demo_dir_argument(p: argparse.ArgumentParser, flag: bool = False) -> None:
    help_ = ("folder of recordings (IMU .csv, .csv.gz, .sto, .mat; suit .bvh, .mvnx); default: the "
             "shipped set of 10")
    if flag:
        p.add_argument("--demos", dest="demo_dir", type=InputPath, metavar="DIR", help=help_)
    else:
        p.add_argument("demo_dir", type=InputPath, nargs="?", metavar="DEMO_DIR", help=help_)


def mapping_options(p: argparse.ArgumentParser) -> None:
    calibration_arguments(p)
    p.add_argument("--lowpass-hz", type=non_negative, default=DEFAULT_LOWPASS_HZ, metavar="HZ",
                   help=f"zero-phase low-pass cut-off on the joint angles, 0 for none "
                        f"(default: {DEFAULT_LOWPASS_HZ:g})")


def cmd_demos_replay(args: argparse.Namespace) -> int:
    """Replay each recording at its scene in the simulator; print which succeed and why not."""
    from dualarm.envs import make_core
    from dualarm.sim_demos.replay import load_replay_folder, replay_demonstration

    demo_dir = demo_dir_of(args)
    env = make_core()
    demos, labels, scenes = load_replay_folder(demo_dir, env.config.workspace(), args.labels,
                                               mapping_options_of(args))
    if args.steps > env.config.max_episode_steps:
        raise InputError(f"--steps {args.steps}: at most the episode's "
                         f"{env.config.max_episode_steps} steps")
    missing = [d.name for d in demos if d.grip is None]
    if missing:
        raise InputError(f"recording(s) {', '.join(missing)} have no gripper events (left_grip, "
                         "right_grip columns): a replay needs them", source=str(demo_dir))
    wins = 0
    try:
        print(f"{'demo':<10} {'success':<7} {'steps':>5} {'tracking, cm (l/r)':>18}  why not")
        for d in demos:
            r = replay_demonstration(env, d, labels[d.name], scenes[d.name], steps=args.steps)
            wins += r.success
            err = "/".join(f"{100 * e:.1f}" for e in r.tracking_error)
            print(f"{r.name:<10} {'yes' if r.success else 'no':<7} {r.steps:>5} {err:>18}  {r.why}")
        print(f"{wins} of {len(demos)} recordings replay to success at their own scene "
              f"(task window retimed to {args.steps} steps)")
        if args.moved:
            moved_yield(env, demos, labels, scenes, args)
    finally:
        env.close()
    return 0


def moved_yield(env, demos, labels, scenes, args) -> None:
    """Move the recordings to ``args.moved`` of the task's random placements (MimicGen) and
    print the yield, per recording and in all."""
    from tqdm import tqdm

    from dualarm.sim_demos.augment import augment
    from dualarm.training.demonstrations import DEMO_SEED_BASE

    with tqdm(total=args.moved, unit="demo", desc="moving", file=sys.stderr, leave=False) as bar:
        out = augment(env, demos, labels, scenes, args.moved, DEMO_SEED_BASE + args.seed,
                      steps=args.steps, on_attempt=lambda tried, kept: bar.update(kept - bar.n))
    steps = np.mean([r.steps for r in out.replays]) if out.replays else float("nan")
    print(f"moved to new placements: {len(out.replays)} of {out.attempts} succeed "
          f"(yield {out.yield_:.0%}; mean {steps:.1f} steps to success); by recording:")
    for d in demos:
        tried = [ok for name, ok in zip(out.sources, out.successes) if name == d.name]
        print(f"  {d.name:<10} {sum(tried)} of {len(tried)}")


def labels_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--labels", type=InputPath, metavar="FILE.csv",
                   help=f"labels file (demo,arm,subtask,start_s,end_s); default: the demonstration folder's {LABELS_NAME}")


def add_demos_command(sub) -> None:
    """Add the ``demos`` command group to the top-level subparsers."""
    demos = sub.add_parser("demos", help="demonstration sets: generate, segment, replay",
                           description="Demonstration sets of the reach-grasp-align task.")
    dsub = demos.add_subparsers(dest="demos_command", required=True, metavar="COMMAND")
    gen = dsub.add_parser("generate", help="make IMU demonstrations from the scripted expert",
                          description="Run the scripted expert at seeded placements, add human variability "
                                      "(speed, timing, elbow swivel, tremor) and write six-sensor IMU "
                                      "recordings (random mountings, noise, a zero-pose window) with "
                                      "sub-task labels. The same --count and --seed give the same bytes; "
                                      "--count 10 --seed 0 is the shipped set.")
    gen.add_argument("-o", "--output", type=OutputDir, required=True, metavar="DIR",
                     help="the demonstration folder to write (recordings, labels.csv, scene.csv)")
    gen.add_argument("--count", type=positive_int, default=10, help="number of demonstrations (default: 10)")
    gen.add_argument("--seed", type=seed_number, default=0, help="seed (default: 0)")
    gen.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    gen.set_defaults(func=cmd_demos_generate)

    seg = dsub.add_parser("segment", help="automatic sub-task segmentation (and agreement with labels)",
                          description="Find each arm's reach, grasp and align from the hand's motion "
                                      "(Baxter forward kinematics) and the gripper events when the recording "
                                      f"has left_grip/right_grip columns. With labels (DEMO_DIR/{LABELS_NAME} or "
                                      "--labels), print how well they agree.")
    demo_dir_argument(seg)
    labels_option(seg)
    mapping_options(seg)
    seg.add_argument("--no-grip", action="store_true", help="ignore gripper-event columns")
    seg.add_argument("-o", "--output", type=OutputFile, metavar="FILE.csv", help="write the automatic labels")
    seg.set_defaults(func=cmd_demos_segment)

    from dualarm.sim_demos.replay import DEFAULT_STEPS
    rep = dsub.add_parser("replay", help="replay each recording at its scene in the simulator",
                          description="Map each recording to Baxter's joints, retime its task window "
                                      "to the learner's pace, and follow both hands' paths in the "
                                      "simulator at the demonstration's own scene (DEMO_DIR/scene.csv), "
                                      "the grip closed and opened as recorded. Prints which recordings "
                                      "succeed, and where the others stop; with --moved, how "
                                      "many succeed when moved to new placements.")
    demo_dir_argument(rep)
    labels_option(rep)
    mapping_options(rep)
    rep.add_argument("--steps", type=positive_int, default=DEFAULT_STEPS,
                     help=f"steps the task window is retimed to (default: {DEFAULT_STEPS}; an "
                          "episode is 50)")
    rep.add_argument("--moved", type=positive_int, metavar="N",
                     help="also move the recordings to N of the task's random placements, each "
                          "sub-task's hand path with the box or target it acts on (MimicGen; "
                          "what `dualarm train --demos` does) and print the yield")
    rep.add_argument("--seed", type=seed_number, default=0,
                     help="with --moved: the run seed whose placements to use (default: 0)")
    rep.set_defaults(func=cmd_demos_replay)
