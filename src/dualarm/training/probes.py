"""Curriculum probes (``TrainConfig.starts.probe``): at every evaluation, deterministic episodes
from each later start class, recorded by the reverse curriculum the way evaluations measure
success. They have seeds of their own (``PROBE_SEED_BASE``), so training is not disturbed, and
act with the online actors whatever ``eval_actor`` is: the curriculum follows the learner."""

from __future__ import annotations

import numpy as np

from dualarm.training.curriculum import START_CLASSES, ReverseCurriculum
from dualarm.training.evaluation import evaluate
from dualarm.training.vector import PROBE_SEED_BASE, make_vector_env


class CurriculumProbes:
    """``episodes`` probe episodes per later start class, in copies made at the first probe.

    Args:
        config: the run's ``TrainConfig`` (its environment and ``num_envs``).
        constraints: the run's ``ConstraintSet`` (None for "none").
        curriculum: the ``ReverseCurriculum`` that records the probes' successes.
        start_states: the recorded states that training's later starts come from
            (``RecordedStates``), which the probes start from too; None: placed starts.
    """

    def __init__(self, config, constraints, curriculum: ReverseCurriculum, start_states=None):
        self.config, self.constraints, self.curriculum = config, constraints, curriculum
        self.start_states = start_states
        self.episodes = config.starts.probe
        self.vecs = None

    def run(self, agent, episode: int, writer) -> None:
        """Probe the learner ``agent`` after training episode ``episode``; log each class's
        success rate to the TensorBoard ``writer``."""
        if self.vecs is None:
            n = min(self.config.num_envs, self.episodes)
            self.vecs = {k: make_vector_env(self.config, n, constraints=self.constraints, start=k)
                         for k in range(1, len(START_CLASSES))}
            if self.start_states is not None:
                for vec in self.vecs.values():
                    vec.set_start_states(self.start_states)
        for k, vec in self.vecs.items():
            seed_base = int(np.random.SeedSequence([PROBE_SEED_BASE, k, episode]).generate_state(1)[0])
            result = evaluate(lambda o: agent.act(o, actors="online"), vec, self.episodes, seed_base)
            self.curriculum.record(np.full((self.episodes, 2), k), result.success)
            writer.add_scalar(f"curriculum/probe_{START_CLASSES[k]}", result.success_rate, episode)
