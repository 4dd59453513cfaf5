"""The training loop: collect episodes in rounds, update DADDPG, log, evaluate, checkpoint.

A round starts one episode in each environment copy (seeded by the episode's number),
steps the copies together until all have ended, stores the transitions, updates the
observation statistics and then makes ``updates_per_step`` x (steps of the round)
gradient updates. Checkpoints are taken between rounds only, so a checkpoint always sits
on an episode boundary: a run that is killed and resumed truncates its logs to the
checkpoint and replays the lost episodes exactly as they would have run.
"""

from __future__ import annotations

import math
import sys
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from dualarm.envs.mirror import TaskMirror
from dualarm.errors import DualarmError, InputError
from dualarm.locks import DirectoryLock
from dualarm.rl.daddpg import DADDPG, NonFiniteLoss
from dualarm.rl.replay import ReplayBuffer
from dualarm.training.checkpointing import restore_trainer, trainer_state
from dualarm.training.config import TrainConfig
from dualarm.training.curriculum import ReverseCurriculum
from dualarm.training.demonstrations import demonstrations
from dualarm.training.evaluation import evaluate
from dualarm.training.exploration import Exploration
from dualarm.training.lifecycle import resume_run, start_run
from dualarm.training.probes import CurriculumProbes
from dualarm.training.records import (Timing, episode_rows, eval_row, log_evaluation, log_round,
                                      metrics_columns, progress_postfix)
from dualarm.training.rounds import run_round
from dualarm.training.run_dir import (AVERAGE_EVAL_COLUMNS, EVAL_COLUMNS, CsvLog,
                                      RunPaths, save_checkpoint)
from dualarm.training.storage import RoundStorage, hindsight_sampler
from dualarm.training.updates import GradientUpdates
from dualarm.training.vector import make_vector_env, seeds_for


class TrainingDiverged(DualarmError, RuntimeError):
    """A loss became NaN or infinite; the run stopped and its last good checkpoint is kept."""


@dataclass
class TrainResult:
    """Where a run ended: episodes and env steps done, the run directory, the last evaluation,
    and whether it ended by reaching ``stop_at`` (before ``episodes``)."""

    out: Path
    episodes: int
    env_steps: int
    wall_time_s: float
    last_eval: dict | None
    stopped: bool = False


class Trainer:
    """One run of DADDPG in a run directory (see ``dualarm.training.run_dir``).

    Use ``Trainer.start(config, out)`` for a new run and ``Trainer.resume(out)`` to continue
    one; then ``run()``.

    Args:
        config: the run's settings.
        paths: the run directory.
        make_env: builds one copy of a two-agent PettingZoo ParallelEnv; None means the
            Baxter task of ``config``.
        progress: show a progress bar on stderr.
    """

    def __init__(self, config: TrainConfig, paths: RunPaths, make_env=None, progress: bool = True):
        self.config = config
        self.paths = paths
        self.progress = progress
        torch.set_num_threads(config.torch_threads)
        baxter_only = config.baxter_only_options()
        if make_env is not None and baxter_only:
            raise InputError(f"{', '.join(baxter_only)}: defined for the Baxter task only "
                             "(its expert, start states, targets and named reward terms), "
                             "not a custom environment: start from TrainConfig.paper(), whose "
                             "options are all general")
        constraints = None if make_env is not None else config.load_constraints()
        self.vec = make_vector_env(config, config.num_envs, make_env, constraints, training=True)
        self.eval_vec = (make_vector_env(config, min(config.num_envs, config.eval_episodes),
                                         make_env, constraints)
                         if config.eval_every and config.eval_episodes else None)
        v = self.vec
        task = config.task_config()
        self.agent = DADDPG(config.algo, v.obs_sizes, v.act_sizes, seed=config.seed)
        self.buffer = ReplayBuffer(config.algo.buffer_size, 2, v.obs_size, v.act_size)
        self.mirror = TaskMirror(task, constraints) if config.replay.mirror else None
        # Demonstrations are recorded again on resume (the expert, the replays and the physics
        # are deterministic); the normaliser's statistics then come from the checkpoint.
        self.demos, start_states = demonstrations(config, v, constraints)
        if start_states is not None:            # later starts from the replays, not placed
            v.set_start_states(start_states)
        if self.demos is not None:
            self.agent.normalizer.update(self.demos.data["obs"][:len(self.demos)])
        self.curriculum, self.probes = None, None
        starts = config.starts
        if starts.curriculum:
            window = 2 * starts.probe if starts.probe else 64
            self.curriculum = ReverseCurriculum(starts.probs, starts.curriculum, window)
            if starts.probe:
                self.probes = CurriculumProbes(config, constraints, self.curriculum, start_states)
        self.rng = np.random.default_rng([config.seed, 1])
        self.exploration = Exploration(config, self.agent, self.rng)
        self.updates = GradientUpdates(config, self.agent, self.buffer,
                                       hindsight_sampler(config, self.buffer, task), self.demos, self.rng)
        self.episodes = 0
        self.env_steps = 0
        self.wall_time_s = 0.0
        self.eval_rows = 0
        self.best = (-math.inf, -math.inf)      # (success rate, mean return) of the best eval
        self.last_eval: dict | None = None
        self.recent_success = deque(maxlen=100)
        self.recent_return = deque(maxlen=100)
        #: Seconds spent since this process started training, by part of a round
        #: (collect_s: the episodes, of which act_s choosing actions and store_s storing
        #: transitions, the rest stepping the environments; update_s: gradient updates;
        #: eval_s: evaluations and curriculum probes), and the counts of the same span.
        self.timing = Timing(collect_s=0.0, act_s=0.0, store_s=0.0, update_s=0.0, eval_s=0.0,
                             updates=0, episodes=0, env_steps=0)
        self.metrics = CsvLog(paths.metrics, metrics_columns(v, config.starts.later))
        # with policy_average, the averaged actors are evaluated beside the run's own
        self.eval_average = config.algo.policy_average > 0 and config.algo.eval_actor != "average"
        columns = list(EVAL_COLUMNS) + (list(AVERAGE_EVAL_COLUMNS) if self.eval_average else [])
        self.eval_log = CsvLog(paths.eval, columns, consecutive=False)
        self._writer = None
        self._lock: DirectoryLock | None = None

    # ------------------------------------------------------------ lifecycle
    @classmethod
    def start(cls, config: TrainConfig, out: str | Path, make_env=None,
              progress: bool = True) -> "Trainer":
        """A new run in ``out`` (which must not hold a run already), holding its lock.

        Nothing is written until the environment and the learner are built (bad
        constraints leave no directory). A guided run copies its constraints file into
        the directory, so that it resumes from anywhere, moved or copied.

        Raises:
            DirectoryBusy: another process holds ``out``.
            InputError: ``out`` holds a run already.
        """
        return start_run(cls, config, out, make_env, progress)

    @classmethod
    def resume(cls, out: str | Path, episodes: int | None = None, make_env=None,
               progress: bool = True) -> "Trainer":
        """Continue the run in ``out`` from its latest checkpoint (or from the start if it
        has none), optionally with a new total of ``episodes``, holding its lock.

        Everything is checked before anything is written (the config, the checkpoint, the
        logs up to the checkpoint): a resume that fails leaves the directory as it was.

        Raises:
            DirectoryBusy: another process holds ``out``.
            InputError: no run there, or ``episodes`` below the episodes done.
            CheckpointError: the checkpoint or the logs do not continue each other.
        """
        return resume_run(cls, out, episodes, make_env, progress)

    def close(self) -> None:
        """Release the run directory's lock (also released when the process ends)."""
        if self._lock is not None:
            self._lock.release()
            self._lock = None

    def stored_config(self) -> TrainConfig:
        """The config as the run directory keeps it (``TrainConfig.stored_in``): its own
        constraints copy named relative to the directory, every other path absolute."""
        return self.config.stored_in(self.paths.root)

    # ------------------------------------------------------------- the loop
    def run(self) -> TrainResult:
        """Train until ``config.episodes`` episodes are done; returns where it ended.

        Raises:
            TrainingDiverged: a loss became non-finite (the last checkpoint is kept).
        """
        from torch.utils.tensorboard import SummaryWriter
        from tqdm import tqdm

        c = self.config
        self._writer = SummaryWriter(str(self.paths.events), purge_step=self.episodes or None)
        bar = tqdm(total=c.episodes, initial=self.episodes, unit="ep", file=sys.stderr,
                   disable=not self.progress, desc=f"train {c.condition}", dynamic_ncols=True)
        started = time.perf_counter() - self.wall_time_s
        last_checkpoint = time.perf_counter()
        try:
            while self.episodes < c.episodes and not self.reached_stop:
                before = self.episodes
                rows, losses = self._round(started)
                self.metrics.append(rows)
                log_round(self._writer, rows, losses, self.recent_success, self.episodes,
                          self.curriculum, self.agent.action_l2)
                bar.update(len(rows))
                evaluated = self._crossed(before, c.eval_every) or self.episodes >= c.episodes
                if self.eval_vec is not None and evaluated:
                    with self.timing.part("eval_s"):
                        self._evaluate(started)
                        if self.probes is not None:
                            self.probes.run(self.agent, self.episodes, self._writer)
                self.wall_time_s = time.perf_counter() - started
                bar.set_postfix(progress_postfix(self.recent_success, self.recent_return, self.last_eval),
                                refresh=False)
                due = (time.perf_counter() - last_checkpoint >= 60 * c.checkpoint_minutes
                       or self._crossed(before, c.checkpoint_every) or evaluated)
                if due or self.episodes >= c.episodes:
                    self.save()
                    last_checkpoint = time.perf_counter()
        finally:
            bar.close()
            self._writer.close()
        return TrainResult(self.paths.root, self.episodes, self.env_steps, self.wall_time_s,
                           self.last_eval, stopped=self.reached_stop)

    @property
    def reached_stop(self) -> bool:
        """Whether an evaluation reached ``stop_at`` (kept by the checkpoint, so a stopped run
        stays stopped on resume)."""
        stop, last = self.config.stop_at, self.last_eval
        return stop is not None and last is not None and last["success_rate"] >= stop

    def _crossed(self, before: int, every: int) -> bool:
        return every > 0 and before // every != self.episodes // every

    def _round(self, started: float) -> tuple[list[dict], list[dict]]:
        """Run one episode in each copy (fewer at the end of the run), then update."""
        c, v, agent = self.config, self.vec, self.agent
        n = min(v.num_envs, c.episodes - self.episodes)
        agent.start_episodes(np.arange(v.num_envs) < n)
        if self.curriculum is not None:      # this round's starts, from the episodes so far
            v.set_start_probs(self.curriculum.probs())
        timing = self.timing
        storage = RoundStorage(self.buffer, self.mirror, c.replay.her_share > 0, n)

        def act(obs):
            with timing.part("act_s"):
                return self.exploration.act(obs, self.env_steps)

        def store(obs, actions, step, live):
            with timing.part("store_s"):
                storage.store(obs, actions, step, live)
                self.env_steps += len(live)

        with timing.part("collect_s"):
            r = run_round(v, seeds_for(c.seed, self.episodes, n), act, store)
        with timing.part("store_s"):
            starts = v.starts()[:n] if c.starts.later else None
            if self.curriculum is not None and self.probes is None:
                self.curriculum.record(starts, r.success)
            agent.normalizer.update(storage.finish(r.first_obs))   # what the critics are shown
        round_steps = int(r.steps.sum())
        with timing.part("update_s"):
            try:
                losses = self.updates.run(self.env_steps, round_steps)
            except NonFiniteLoss as exc:
                raise TrainingDiverged(
                    f"training stopped in the round after episode {self.episodes}: {exc}. The "
                    f"last good checkpoint is kept in {self.paths.latest}; lower the learning "
                    "rates or the reward scale, or set grad_clip, and resume") from None
        timing["updates"] += len(losses)
        wall = time.perf_counter() - started
        timing["episodes"] += n
        timing["env_steps"] += round_steps
        rows = episode_rows(v, r, n, self.episodes + 1, self.env_steps - round_steps, wall, starts)
        self.episodes += n
        self.recent_success.extend(bool(x) for x in r.success[:n])
        self.recent_return.extend(float(x) for x in r.returns[:n].sum(axis=1))
        return rows, losses

    def _evaluate(self, started: float) -> None:
        c = self.config
        result = evaluate(lambda o: self.agent.act(o), self.eval_vec, c.eval_episodes)
        average = None
        if self.eval_average:       # the same placements; acting draws no random numbers
            average = evaluate(lambda o: self.agent.act(o, actors="average"), self.eval_vec,
                               c.eval_episodes)
        self.wall_time_s = time.perf_counter() - started
        self.eval_log.append([eval_row(self.episodes, self.env_steps, self.wall_time_s, result,
                                       average)])
        self.eval_rows += 1
        self.last_eval = {"episode": self.episodes, "success_rate": result.success_rate,
                          "return_mean": result.mean_return}
        log_evaluation(self._writer, result, self.episodes, average)
        if (result.success_rate, result.mean_return) > self.best:
            self.best = (result.success_rate, result.mean_return)
            save_checkpoint(self.paths.best, {"policy": self.agent.policy_state_dict(),
                                              "config": self.stored_config().to_dict(),
                                              "eval": self.last_eval})

    # ---------------------------------------------------------- checkpoints
    def save(self) -> None:
        """Write ``checkpoints/latest.pt`` atomically (call between rounds only)."""
        save_checkpoint(self.paths.latest, trainer_state(self))

    def load(self, payload: dict) -> None:
        """Restore the state saved by ``save`` (the config must match but for ``episodes``)."""
        restore_trainer(self, payload)

def train(config: TrainConfig, out: str | Path, make_env=None, progress: bool = True) -> TrainResult:
    """Start a run in ``out`` and train it to the end (see ``Trainer``)."""
    trainer = Trainer.start(config, out, make_env, progress)
    try:
        return trainer.run()
    finally:
        trainer.close()


def resume(out: str | Path, episodes: int | None = None, make_env=None,
           progress: bool = True) -> TrainResult:
    """Continue the run in ``out`` to its (or a new) total of episodes."""
    trainer = Trainer.resume(out, episodes, make_env, progress)
    try:
        return trainer.run()
    finally:
        trainer.close()
