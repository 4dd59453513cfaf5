"""Time the Baxter reach-grasp-align environment against the raw MuJoCo physics under it.

Usage: python benchmarks/env_speed.py [--steps 3000] [--repeat 7] [--seed 0] [--csv]

For each case (cartesian control driven by the scripted expert, cartesian with uniform
random actions, joint control with uniform random actions) and each repeat:

1. env: ``--steps`` environment steps, resetting when an episode ends. Only the
   ``env.step`` and ``env.reset`` calls are timed (resets are counted in the env time,
   amortised over the steps); the policy's own time is reported apart. Before every step
   MuJoCo integration state (``mjSTATE_INTEGRATION``: time, qpos, qvel, warm start, ...)
   is recorded, and after it the controls and mocap poses the step set before its
   ``mj_step`` (ctrl, mocap_pos, mocap_quat), both outside the timer.
2. physics: every recorded state (with that step's controls) is set on a separate
   ``MjData`` of the same model and advanced by ``mj_step(nstep=substeps)``; only the ``mj_step`` calls are timed. This is
   the physics the env did, without anything the Python layer adds.

Env and physics measurements alternate, so that both see the same machine speed. Every
repeat runs the same seeded episodes. Reported: the best (lowest time) and the median over
the repeats; the overhead, (env time per step - physics time per step) / physics time per
step, is taken from the best times and as the median of the per-repeat ratios.
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

from dualarm.envs.baxter import BaxterReachGraspAlign, StepResult  # noqa: E402
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
        self.env_s, self.step_s, self.reset_s, self.policy_s, self.physics_s = [], [], [], [], []
        self.episodes = self.physics_errors = 0
        self.replay_mismatch = None

    def _policy(self):
        if self.policy_name == "expert":
            return ScriptedExpert(self.config)
        rng = np.random.default_rng(self.seed)
        shape = (2, self.env.action_size)
        return lambda obs: rng.uniform(-1.0, 1.0, size=shape)

    def run_env(self) -> None:
        env, m, d = self.env, self.model, self.env.data
        policy = self._policy()
        clock, get_state = time.perf_counter, mujoco.mj_getState
        states, commands, qpos, first = self.states, self.commands, self.qpos, self.first_of_episode
        first[:] = False
        t_step = t_reset = t_policy = 0.0
        episodes = errors = 0
        t0 = clock()
        obs, _ = env.reset(seed=self.seed)
        t_reset += clock() - t0
        done, first[0] = False, True
        for i in range(self.steps):
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
        self.episodes, self.physics_errors = episodes + 1, errors
        self.step_s.append(t_step)
        self.reset_s.append(t_reset)
        self.env_s.append(t_step + t_reset)
        self.policy_s.append(t_policy)

    def run_physics(self, check: bool = False) -> None:
        m, d = self.model, self.replay
        nstep = self.config.substeps
        clock, set_state, step = time.perf_counter, mujoco.mj_setState, mujoco.mj_step
        total = 0.0
        mismatch = 0
        for i in range(self.steps):
            set_state(m, d, self.states[i], STATE)
            set_state(m, d, self.commands[i], COMMAND)
            t0 = clock()
            step(m, d, nstep=nstep)
            total += clock() - t0
            if check and i + 1 < self.steps and not self.first_of_episode[i + 1]:
                mismatch += not np.array_equal(d.qpos, self.qpos[i + 1])
        self.physics_s.append(total)
        if check:
            self.replay_mismatch = mismatch

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
            "mj_step_calls_per_s_best": n * sub / phys_best,
            "physics_max_env_steps_per_s": n / phys_best,
            "overhead_pct_best": 100.0 * (env_best - phys_best) / phys_best,
            "overhead_pct_median": 100.0 * (statistics.median(ratios) - 1.0),
            "episodes": self.episodes, "physics_errors": self.physics_errors,
        }


def per_call_us(fn, calls: int = 2000, batches: int = 5) -> float:
    """Best-of-``batches`` time of one ``fn()`` call, us."""
    best = float("inf")
    for _ in range(batches):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        best = min(best, time.perf_counter() - t0)
    return 1e6 * best / calls


def breakdown(config: TaskConfig, settle_steps: int = 20) -> dict[str, float] | None:
    """Approximate per-step cost (us) of the parts of ``env.step`` other than ``mj_step``.

    Each part is timed in isolation, in a tight loop, on a mid-episode state of a scratch
    env. It relies on ``BaxterReachGraspAlign``'s private helpers; None if they changed.
    """
    try:
        env = BaxterReachGraspAlign(config)
        expert = ScriptedExpert(config)
        obs, _ = env.reset(seed=1)
        for _ in range(settle_steps):
            obs = env.step(expert(obs)).obs
        action = expert(obs)
        m, d = env.model, env.data
        grip = env._prev_grip
        state = env._evaluate(grip)
        terms = env._reward_terms(state)
        zeros = np.zeros((2, 3))
        parts = {
            "mj_kinematics": per_call_us(lambda: mujoco.mj_kinematics(m, d)),
            "check_action": per_call_us(lambda: env.check_action(action)),
            "_evaluate": per_call_us(lambda: env._evaluate(grip)),
            "_reward_terms": per_call_us(lambda: env._reward_terms(state)),
            "_observe": per_call_us(lambda: env._observe(state, zeros)),
            "_info+StepResult": per_call_us(
                lambda: StepResult(obs, terms["distance"], False, False,
                                   env._info(state, terms, False))),
        }
        return parts
    except (AttributeError, TypeError, KeyError):
        return None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=3000, help="env steps per case and repeat")
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--csv", action="store_true", help="also print machine-readable rows")
    args = ap.parse_args()

    print(f"machine: {machine()}")
    cases = [Case(mode, policy, args.steps, args.seed) for mode, policy in CASES]
    for case in cases:                       # warm-up: imports, caches, first-call costs
        case.run_env()
        case.run_physics(check=True)
        case.env_s.clear(), case.step_s.clear(), case.reset_s.clear()
        case.policy_s.clear(), case.physics_s.clear()
    for _ in range(args.repeat):             # interleaved: env, physics, env, physics, ...
        for case in cases:
            case.run_env()
            case.run_physics()
    rows = [case.summary() for case in cases]

    c0 = cases[0].config
    print(f"{args.steps} env steps per case x {args.repeat} repeats (interleaved env / physics), "
          f"{c0.substeps} substeps of {1e3 * c0.scene.timestep:g} ms per env step, "
          f"episodes of at most {c0.max_episode_steps} steps; best / median over repeats")
    for case, row in zip(cases, rows):
        print(f"  {row['mode']}/{row['policy']}: {row['episodes']} episodes per repeat, "
              f"{row['physics_errors']} physics errors, replay reproduced the env's qpos: "
              f"{'yes' if case.replay_mismatch == 0 else f'NO ({case.replay_mismatch} mismatches)'}")
    print()
    print("| mode | policy | env steps/s best | median | env us/step | of which reset | "
          "physics us/step best | median | mj_step calls/s | physics-only max steps/s | "
          "overhead % best | median | policy us/step |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['mode']} | {r['policy']} | {r['env_steps_per_s_best']:,.0f} | "
              f"{r['env_steps_per_s_median']:,.0f} | {r['env_us_per_step_best']:.0f} | "
              f"{r['reset_us_per_step_best']:.1f} | {r['physics_us_per_step_best']:.0f} | "
              f"{r['physics_us_per_step_median']:.0f} | {r['mj_step_calls_per_s_best']:,.0f} | "
              f"{r['physics_max_env_steps_per_s']:,.0f} | {r['overhead_pct_best']:.1f} | "
              f"{r['overhead_pct_median']:.1f} | {r['policy_us_per_step_best']:.1f} |")
    print()
    for r in rows:
        if r["mode"] != "cartesian":
            continue
        rate_ok = r["env_steps_per_s_best"] >= TARGET_STEPS_PER_S
        over_ok = r["overhead_pct_best"] < TARGET_OVERHEAD_PCT
        print(f"targets, cartesian/{r['policy']}: >= {TARGET_STEPS_PER_S:,} env steps/s: "
              f"{r['env_steps_per_s_best']:,.0f} best, {r['env_steps_per_s_median']:,.0f} median "
              f"({'met' if rate_ok else 'MISSED'} at best); overhead < {TARGET_OVERHEAD_PCT:g}% "
              f"of physics: {r['overhead_pct_best']:.1f}% best, {r['overhead_pct_median']:.1f}% "
              f"median ({'met' if over_ok else 'MISSED'} at best)")
    for r in rows:
        if r["mode"] == "joint":
            print(f"overhead target, joint/{r['policy']}: {r['overhead_pct_best']:.1f}% best, "
                  f"{r['overhead_pct_median']:.1f}% median "
                  f"({'met' if r['overhead_pct_best'] < TARGET_OVERHEAD_PCT else 'MISSED'} at best)")

    parts = breakdown(c0)
    if parts is not None:
        r = rows[0]
        overhead = r["env_us_per_step_best"] - r["physics_us_per_step_best"]
        listed = sum(parts.values()) + r["reset_us_per_step_best"]
        text = ", ".join(f"{k} {v:.1f}" for k, v in parts.items())
        print(f"overhead breakdown, cartesian/expert, us per step (parts timed alone): "
              f"{overhead:.1f} total = {text}, reset (amortised) {r['reset_us_per_step_best']:.1f}, "
              f"rest {overhead - listed:.1f}")

    if args.csv:
        keys = list(rows[0])
        print()
        print(",".join(keys))
        for r in rows:
            print(",".join(f"{r[k]:.3f}" if isinstance(r[k], float) else str(r[k]) for k in keys))


if __name__ == "__main__":
    main()
