"""algo.demo_return_floor: the demonstration rows' targets floored at their own returns."""

import numpy as np
import pytest
import torch

from dualarm.errors import InputError
from dualarm.rl.config import DADDPGConfig
from dualarm.rl.daddpg import DADDPG
from dualarm.rl.replay import DemonstrationBuffer, discounted_returns
from dualarm.training.config import TrainConfig


def test_discounted_returns_sum_the_rest_of_the_episode():
    rew = np.array([[1.0, 0.0], [0.0, 2.0], [4.0, 0.0]])
    got = discounted_returns(rew, 0.5)
    assert np.allclose(got, [[1 + 0 + 1, 0 + 0.5 * 2 + 0], [0 + 2, 2], [4, 0]])


def test_only_a_terminated_episode_gets_returns():
    buf = DemonstrationBuffer(10, 2, 3, 1)
    obs, act = np.zeros((3, 2, 3)), np.zeros((3, 2, 1))
    rew = np.ones((3, 2))
    buf.add_with_returns(obs, act, rew, obs, np.array([0, 0, 0.0]), 0.9)    # cut off
    buf.add_with_returns(obs, act, rew, obs, np.array([0, 0, 1.0]), 0.9)    # a success
    assert np.isneginf(buf.data["ret"][:3]).all()
    assert np.allclose(buf.data["ret"][3:6, 0], [1 + 0.9 + 0.81, 1.9, 1.0])
    assert set(buf.sample(np.random.default_rng(0), 4)) >= {"obs", "ret"}


def _batch(rows: int, obs_size: int = 5):
    g = torch.Generator().manual_seed(0)
    obs = torch.randn(rows, 2, obs_size, generator=g)
    return {"obs": obs, "next_obs": obs.clone(), "act": torch.zeros(rows, 2, 2),
            "rew": torch.zeros(rows, 2), "done": torch.ones(rows)}


def test_the_floor_raises_the_targets_of_the_last_rows_only():
    """Terminal rows with zero reward have targets 0; a floor of 1 on the last 4 of 16 rows
    adds their squared distance to 1 to the critic loss, and nothing else."""
    config = DADDPGConfig(hidden=(8,), q_clip=1.0)
    losses = {}
    for floor in (None, 1.0):
        torch.manual_seed(0)
        agent = DADDPG(config, (5, 5), (2, 2), seed=0)
        batch = _batch(16)
        if floor is not None:
            batch["return_floor"] = torch.full((4, 2), 5.0)     # clipped to q_clip
        with torch.no_grad():
            q = agent._per_agent(agent.critic(agent._critic_input(
                agent.normalizer.normalize(batch["obs"]).transpose(0, 1), batch["act"].transpose(0, 1))))
        losses[floor] = (agent.update(batch, demo_rows=4)["critic_loss"], q)
    (plain, q), (floored, _) = losses[None], losses[1.0]
    expected = (((1.0 - q[:, :, -4:]) ** 2).sum() - (q[:, :, -4:] ** 2).sum()) / 16
    assert floored - plain == pytest.approx(expected.item(), rel=1e-4)
    assert floored > plain + 0.4          # 2 critics x 4 of 16 rows at distance ~1


def test_the_floor_needs_the_recordings():
    with pytest.raises(InputError, match="demo_return_floor"):
        TrainConfig().with_(algo={"demo_return_floor": True})
    config = TrainConfig().with_(demos={"folder": "src/dualarm/data/demos"},
                                 algo={"demo_return_floor": True})
    assert config.algo.demo_return_floor and config.algo.demo_batch_size == 64
