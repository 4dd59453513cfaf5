"""Time the Baxter reach-grasp-align environment against the raw MuJoCo physics under it.

Usage: python benchmarks/env_speed.py [--steps 3000] [--repeat 7] [--chunk 250] [--seed 0]
                                    [--num-envs 8] [--csv] [--no-breakdown]

For each case (cartesian control driven by the scripted expert, cartesian with uniform
random actions, joint control with uniform random actions, and cartesian with random
actions on ``--num-envs`` copies stepped together by ``BaxterBatch``) and each repeat:

1. env: ``--steps`` environment steps, resetting when an episode ends. Only the
   ``env.step`` and ``env.reset`` calls are timed (resets are counted in the env time,
   amortised over the steps); the policy's own time is reported apart. Outside the
   timer, the MuJoCo integration state (``mjSTATE_INTEGRATION`` less the commands: time,
   qpos, qvel, warm start, ...) is recorded before every step, and the commands the step
   set before its ``mj_step`` (ctrl, mocap_pos, mocap_quat) after it.
2. physics: every recorded state, with its step's commands, is set on a separate
   ``MjData`` of the same model and advanced by ``mj_step(nstep=substeps)``; only the
   ``mj_step`` calls are timed. This is the physics the env did (the replay reproduces
   the env's trajectory bit for bit; the script checks it), without the Python layer.

Env and physics timing alternate every ``--chunk`` steps (a fraction of a second), so that
both see the same machine speed; every repeat runs the same seeded episodes. Reported:
the best (lowest time) and the median over the repeats. The overhead, (env time per step
- physics time per step) / physics time per step, is taken from the best times and as the
median of the per-repeat ratios.

The breakdown (skip with --no-breakdown) runs each case again with ``mujoco.mj_step``
wrapped in a timer, which splits ``env.step`` into the physics as it runs inside the env
(which can be slower than the replay: the Python work between steps evicts MuJoCo's data
from the caches) and the rest.
Runs on one core (thread counts pinned to 1 before numpy loads).
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"

import argparse  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from dualarm.envs.baxter import BaxterBatch, BaxterReachGraspAlign  # noqa: E402
from dualarm.envs.config import TaskConfig  # noqa: E402
from dualarm.envs.expert import ScriptedExpert  # noqa: E402

TARGET_STEPS_PER_S = 1200       # cartesian mode
TARGET_OVERHEAD_PCT = 25.0      # of the physics time
_S = mujoco.mjtState
#: What ``env.step`` sets before its ``mj_step`` (read after the step: they stay set).
COMMAND = int(_S.mjSTATE_CTRL) | int(_S.mjSTATE_MOCAP_POS) | int(_S.mjSTATE_MOCAP_QUAT)
#: The rest of the integration state (read before the step).
STATE = int(_S.mjSTATE_INTEGRATION) & ~COMMAND
CASES = (("cartesian", "expert"), ("cartesian", "random"), ("joint", "random"))


def cpu_times() -> tuple[int, int] | None:
    """(steal, total) jiffies of all CPUs from /proc/stat, None where unavailable."""
    try:
        with open("/proc/stat") as f:
            values = [int(v) for v in f.readline().split()[1:]]
        return values[7], sum(values[:8])
    except (OSError, ValueError, IndexError):
        return None


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return (f"{cpu}, {os.cpu_count()} cores (one thread used); Python {platform.python_version()}, "
            f"MuJoCo {mujoco.__version__}, NumPy {np.__version__}")


class Case:
    """One (control mode, policy) pair: its env, policy, replay buffers and timings."""

    def __init__(self, control: str, policy: str, steps: int, seed: int):
        self.control, self.policy_name, self.steps, self.seed = control, policy, steps, seed
        self.config = TaskConfig(control=control)
        self.env = BaxterReachGraspAlign(self.config)
        self.model = self.env.model
        self.replay = mujoco.MjData(self.model)
        self.states = np.zeros((steps, mujoco.mj_stateSize(self.model, STATE)))
        self.commands = np.zeros((steps, mujoco.mj_stateSize(self.model, COMMAND)))
        self.qpos = np.zeros((steps, self.model.nq))
        self.first_of_episode = np.zeros(steps, dtype=bool)
        self.env_s, self.reset_s, self.policy_s, self.physics_s = [], [], [], []
        self.episodes = self.physics_errors = 0
        self.replay_mismatch = None

    def _policy(self):
        if self.policy_name == "expert":
            return ScriptedExpert(self.config)
        rng = np.random.default_rng(self.seed)
        shape = (2, self.env.action_size)
        return lambda obs: rng.uniform(-1.0, 1.0, size=shape)

    def run_env(self, lo: int = 0, hi: int | None = None) -> tuple[float, float, float]:
        """Env steps ``lo`` to ``hi`` of the seeded episodes (``lo == 0``: from the seeded
        reset), recording their states; seconds in (step, reset, policy)."""
        hi = self.steps if hi is None else hi
        env, m, d = self.env, self.model, self.env.data
        clock, get_state = time.perf_counter, mujoco.mj_getState
        states, commands, qpos, first = self.states, self.commands, self.qpos, self.first_of_episode
        t_step = t_reset = t_policy = 0.0
        if lo == 0:
            self._act = self._policy()
            self.episodes = self.physics_errors = 0
            first[:] = False
            t0 = clock()
            self._obs, _ = env.reset(seed=self.seed)
            t_reset += clock() - t0
            self._done, first[0] = False, True
            self.episodes = 1
        policy, obs, done = self._act, self._obs, self._done
        episodes = errors = 0
        for i in range(lo, hi):
            if done:
                t0 = clock()
                obs, _ = env.reset()
                t_reset += clock() - t0
                first[i] = True
                episodes += 1
            t0 = clock()
            action = policy(obs)
            t_policy += clock() - t0
            get_state(m, d, states[i], STATE)
            qpos[i] = d.qpos
            t0 = clock()
            result = env.step(action)
            t_step += clock() - t0
            get_state(m, d, commands[i], COMMAND)
            obs = result.obs
            done = result.terminated or result.truncated
            errors += result.info["physics_error"]
        self._obs, self._done = obs, done
        self.episodes += episodes
        self.physics_errors += errors
        return t_step, t_reset, t_policy

    #: Recorded steps between one copy's consecutive steps (a batch records n per round).
    stride = 1

    def run_physics(self, lo: int = 0, hi: int | None = None, check: bool = False) -> float:
        """Replay the recorded steps ``lo`` to ``hi``; seconds in ``mj_step``. ``check``
        counts the steps whose result differs from the state the env reached."""
        hi = self.steps if hi is None else hi
        m, d, k = self.model, self.replay, self.stride
        nstep = self.config.substeps
        clock, set_state, step = time.perf_counter, mujoco.mj_setState, mujoco.mj_step
        total = 0.0
        mismatch = 0
        for i in range(lo, hi):
            set_state(m, d, self.states[i], STATE)
            set_state(m, d, self.commands[i], COMMAND)
            t0 = clock()
            step(m, d, nstep=nstep)
            total += clock() - t0
            if check and i + k < hi and not self.first_of_episode[i + k]:
                mismatch += not np.array_equal(d.qpos, self.qpos[i + k])
        if check:
            self.replay_mismatch = mismatch
        return total

    def measure(self, chunk: int) -> None:
        """One repeat: ``chunk`` env steps, their physics replayed, the next ``chunk``, ..."""
        env = reset = policy = physics = 0.0
        for lo in range(0, self.steps, chunk):
            hi = min(lo + chunk, self.steps)
            t_step, t_reset, t_policy = self.run_env(lo, hi)
            env += t_step + t_reset
            reset += t_reset
            policy += t_policy
            physics += self.run_physics(lo, hi)
        self.env_s.append(env)
        self.reset_s.append(reset)
        self.policy_s.append(policy)
        self.physics_s.append(physics)

    def physics_inside_env(self, repeat: int, chunk: int) -> tuple[float, float, float]:
        """Best-of-``repeat`` us per step: env step (resets excluded), its own ``mj_step``
        calls (timed by wrapping ``mujoco.mj_step``), and the replay of the same steps."""
        original, spent = mujoco.mj_step, [0.0]
        clock = time.perf_counter

        def timed(m, d, nstep=1):
            t0 = clock()
            original(m, d, nstep=nstep)
            spent[0] += clock() - t0

        best = (float("inf"),) * 3
        for _ in range(repeat):
            spent[0] = t_step = t_replay = 0.0
            for lo in range(0, self.steps, chunk):
                hi = min(lo + chunk, self.steps)
                mujoco.mj_step = timed
                try:
                    t_step += self.run_env(lo, hi)[0]
                finally:
                    mujoco.mj_step = original
                t_replay += self.run_physics(lo, hi)
            best = tuple(min(b, t) for b, t in zip(best, (t_step, spent[0], t_replay)))
        return tuple(1e6 * t / self.steps for t in best)

    # ------------------------------------------------------------ summaries
    def summary(self) -> dict:
        n, sub = self.steps, self.config.substeps
        env_best, env_med = min(self.env_s), statistics.median(self.env_s)
        phys_best, phys_med = min(self.physics_s), statistics.median(self.physics_s)
        ratios = [e / p for e, p in zip(self.env_s, self.physics_s)]
        return {
            "mode": self.control, "policy": self.policy_name,
            "env_steps_per_s_best": n / env_best, "env_steps_per_s_median": n / env_med,
            "env_us_per_step_best": 1e6 * env_best / n,
            "reset_us_per_step_best": 1e6 * min(self.reset_s) / n,
            "policy_us_per_step_best": 1e6 * min(self.policy_s) / n,
            "physics_us_per_step_best": 1e6 * phys_best / n,
            "physics_us_per_step_median": 1e6 * phys_med / n,
            "mj_substeps_per_s_best": n * sub / phys_best,
            "physics_max_env_steps_per_s": n / phys_best,
            "overhead_pct_best": 100.0 * (env_best - phys_best) / phys_best,
            "overhead_pct_median": 100.0 * (statistics.median(ratios) - 1.0),
            "episodes": self.episodes, "physics_errors": self.physics_errors,
        }


class BatchCase(Case):
    """Cartesian control, random actions, ``num_envs`` copies stepped by one ``BaxterBatch``:
    the same measurements per environment step (env time, replayed physics)."""

    def __init__(self, num_envs: int, steps: int, seed: int):
        self.num_envs = self.stride = num_envs
        self.rounds = max(1, steps // num_envs)
        super().__init__("cartesian", "random", self.rounds * num_envs, seed)
        self.env = BaxterBatch(self.config, num_envs=num_envs)
        self.policy_name = f"random, {num_envs} envs batched"

    def run_env(self, lo: int = 0, hi: int | None = None) -> tuple[float, float, float]:
        """Batched rounds covering env steps ``lo`` to ``hi`` (multiples of num_envs)."""
        hi = self.steps if hi is None else hi
        env, m, n = self.env, self.model, self.num_envs
        clock, get_state = time.perf_counter, mujoco.mj_getState
        t_step = t_reset = t_policy = 0.0
        if lo == 0:
            self._rng = np.random.default_rng(self.seed)
            self.first_of_episode[:] = False
            self.episodes = self.physics_errors = 0
            t0 = clock()
            for i in range(n):
                env.reset_env(i, self.seed + i)
            t_reset += clock() - t0
            self.first_of_episode[:n] = True
            self.episodes = n
        for r in range(lo // n, hi // n):
            base = r * n
            t0 = clock()
            for i in np.flatnonzero(env.needs_reset):
                env.reset_env(int(i))
                self.first_of_episode[base + i] = True
                self.episodes += 1
            t_reset += clock() - t0
            t0 = clock()
            actions = self._rng.uniform(-1.0, 1.0, size=(n, 2, env.action_size))
            t_policy += clock() - t0
            for i, d in enumerate(env.datas):
                get_state(m, d, self.states[base + i], STATE)
                self.qpos[base + i] = d.qpos
            t0 = clock()
            result = env.step_all(actions)
            t_step += clock() - t0
            for i, d in enumerate(env.datas):
                get_state(m, d, self.commands[base + i], COMMAND)
            self.physics_errors += int(result.info["physics_error"].sum())
        return t_step, t_reset, t_policy

    def physics_inside_env(self, repeat: int, chunk: int) -> tuple[float, float, float]:
        return Case.physics_inside_env(self, repeat, self._chunk(chunk))

    def measure(self, chunk: int) -> None:
        Case.measure(self, self._chunk(chunk))

    def _chunk(self, chunk: int) -> int:
        return max(self.num_envs, chunk - chunk % self.num_envs)

    def summary(self) -> dict:
        row = super().summary()
        row["mode"] = f"cartesian x{self.num_envs}"
        return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=3000, help="env steps per case and repeat")
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--chunk", type=int, default=250,
                    help="env steps between switches from env to physics timing")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--num-envs", type=int, default=8,
                    help="copies stepped together by BaxterBatch in the batched case (0: skip)")
    ap.add_argument("--csv", action="store_true", help="also print machine-readable rows")
    ap.add_argument("--no-breakdown", dest="breakdown", action="store_false",
                    help="skip the overhead breakdown (an extra pass with mj_step wrapped)")
    ap.add_argument("--breakdown-repeat", type=int, default=3)
    args = ap.parse_args()

    print(f"machine: {machine()}")
    start_wall, start_own, start_cpu = time.perf_counter(), time.process_time(), cpu_times()
    cases = [Case(mode, policy, args.steps, args.seed) for mode, policy in CASES]
    if args.num_envs:
        cases.append(BatchCase(args.num_envs, args.steps, args.seed))
    for case in cases:                       # warm-up (first-call costs), replay check
        case.run_env()
        case.run_physics(check=True)
    for _ in range(args.repeat):             # interleaved: env, physics, env, physics, ...
        for case in cases:
            case.measure(args.chunk)
    rows = [case.summary() for case in cases]
    end_cpu = cpu_times()
    wall = time.perf_counter() - start_wall
    share = 100.0 * (time.process_time() - start_own) / wall
    steal = (f"{100.0 * (end_cpu[0] - start_cpu[0]) / (end_cpu[1] - start_cpu[1]):.1f}%"
             if start_cpu and end_cpu and end_cpu[1] > start_cpu[1] else "unknown")
    load = " ".join(f"{x:.2f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "unknown"
    measured = (f"measurement: {wall:.0f} s wall, this process on a CPU {share:.0f}% of it "
                f"(below 100%: other processes competed), CPU time stolen by the hypervisor "
                f"{steal}, load average {load}")

    c0 = cases[0].config
    print(f"{args.steps} env steps per case x {args.repeat} repeats (env / physics interleaved "
          f"every {args.chunk} steps), "
          f"{c0.substeps} substeps of {1e3 * c0.scene.timestep:g} ms per env step, "
          f"episodes of at most {c0.max_episode_steps} steps; best / median over repeats")
    print(measured)
    for case, row in zip(cases, rows):
        same = ("yes" if case.replay_mismatch == 0
                else f"NO ({case.replay_mismatch} mismatches)")
        print(f"  {row['mode']}/{row['policy']}: {row['episodes']} episodes per repeat, "
              f"{row['physics_errors']} physics errors, replay reproduced the env's qpos: {same}")
    print()
    print("| mode | policy | env steps/s best | median | env us/step | of which reset | "
          "physics us/step best | median | mj_step substeps/s | physics-only max steps/s | "
          "overhead % best | median | policy us/step |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['mode']} | {r['policy']} | {r['env_steps_per_s_best']:,.0f} | "
              f"{r['env_steps_per_s_median']:,.0f} | {r['env_us_per_step_best']:.0f} | "
              f"{r['reset_us_per_step_best']:.1f} | {r['physics_us_per_step_best']:.0f} | "
              f"{r['physics_us_per_step_median']:.0f} | {r['mj_substeps_per_s_best']:,.0f} | "
              f"{r['physics_max_env_steps_per_s']:,.0f} | {r['overhead_pct_best']:.1f} | "
              f"{r['overhead_pct_median']:.1f} | {r['policy_us_per_step_best']:.1f} |")
    print()
    for r in rows:
        if not r["mode"].startswith("cartesian"):
            continue
        rate_ok = r["env_steps_per_s_best"] >= TARGET_STEPS_PER_S
        over_ok = r["overhead_pct_best"] < TARGET_OVERHEAD_PCT
        print(f"targets, {r['mode']}/{r['policy']}: >= {TARGET_STEPS_PER_S:,} env steps/s: "
              f"{r['env_steps_per_s_best']:,.0f} best, {r['env_steps_per_s_median']:,.0f} median "
              f"({'met' if rate_ok else 'MISSED'} at best); overhead < {TARGET_OVERHEAD_PCT:g}% "
              f"of physics: {r['overhead_pct_best']:.1f}% best, {r['overhead_pct_median']:.1f}% "
              f"median ({'met' if over_ok else 'MISSED'} at best)")
    for r in rows:
        if r["mode"] == "joint":
            over_ok = r["overhead_pct_best"] < TARGET_OVERHEAD_PCT
            print(f"overhead target, joint/{r['policy']}: {r['overhead_pct_best']:.1f}% best, "
                  f"{r['overhead_pct_median']:.1f}% median "
                  f"({'met' if over_ok else 'MISSED'} at best)")

    if args.breakdown:
        print()
        print(f"where the overhead goes (best of {args.breakdown_repeat}, us per env step, "
              f"resets excluded):")
        for case in cases:
            step_us, inside_us, replay_us = case.physics_inside_env(args.breakdown_repeat,
                                                                    args.chunk)
            python_us = step_us - inside_us
            print(f"  {case.control}/{case.policy_name}: env.step {step_us:.0f} = mj_step inside "
                  f"the env {inside_us:.0f} (replayed alone: {replay_us:.0f}, "
                  f"{100 * (inside_us - replay_us) / replay_us:+.0f}%) + the rest of step "
                  f"{python_us:.0f} ({100 * python_us / replay_us:.0f}% of the replayed physics)")

    if args.csv:
        keys = list(rows[0])
        print()
        print(",".join(keys))
        for r in rows:
            print(",".join(f"{r[k]:.3f}" if isinstance(r[k], float) else str(r[k]) for k in keys))


if __name__ == "__main__":
    main()
