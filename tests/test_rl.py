"""DADDPG's parts: stacked networks, Eqs. 13-15, agent independence, replay, normaliser, noise."""

import warnings

import numpy as np
import pytest
import torch

from dualarm.rl import DADDPG, DADDPGConfig, daddpg
from dualarm.rl.daddpg import NonFiniteLoss
from dualarm.rl.networks import StackedMLP
from dualarm.rl.noise import GaussianNoise
from dualarm.rl.normalizer import RunningNormalizer
from dualarm.rl.replay import ReplayBuffer

OBS, ACT = (5, 7), (2, 3)


def small_agent(**changes) -> DADDPG:
    config = DADDPGConfig(hidden=(16, 16), batch_size=8, buffer_size=100, **changes)
    return DADDPG(config, OBS, ACT, seed=3)


def random_batch(seed=0, b=8, rew=None) -> dict:
    g = torch.Generator().manual_seed(seed)
    obs = torch.randn(b, 2, 7, generator=g)
    nxt = torch.randn(b, 2, 7, generator=g)
    obs[:, 0, 5:] = 0.0                 # agent 0's observation is 5 wide, padded to 7
    nxt[:, 0, 5:] = 0.0
    act = torch.rand(b, 2, 3, generator=g) * 2 - 1
    act[:, 0, 2] = 0.0                  # agent 0's action is 2 wide, padded to 3
    return {"obs": obs, "next_obs": nxt, "act": act,
            "rew": torch.randn(b, 2, generator=g) if rew is None else rew,
            "done": (torch.rand(b, generator=g) < 0.3).float()}


def agent_mlp(net: StackedMLP, i: int, x: torch.Tensor) -> torch.Tensor:
    """Agent i's network evaluated as an ordinary MLP from its slice of the stacked weights."""
    for layer in net.hidden:
        x = torch.relu(x @ layer.weight[i] + layer.bias[i, 0])
    x = x @ net.out.weight[i] + net.out.bias[i, 0]
    return torch.tanh(x) if net.tanh_output else x


def critic_loss_by_hand(agent, batch, target) -> float:
    """Eq. 13 recomputed agent by agent: sum over agents of mean (y_i - Q_i)^2, where
    ``target(i, q2)`` gives y_i (B, heads) from the target critic's output q2 (B, heads)."""
    norm = agent.normalizer.normalize
    o, o2 = norm(batch["obs"]), norm(batch["next_obs"])
    s, s2 = o.reshape(len(o), -1), o2.reshape(len(o2), -1)
    total = 0.0
    for i in range(2):
        with torch.no_grad():
            a2 = agent_mlp(agent.actor_target, i, o2[:, i]) * agent.action_mask[i, 0]
            q2 = agent_mlp(agent.critic_target, i, torch.cat([s2, a2], -1))
            q = agent_mlp(agent.critic, i, torch.cat([s, batch["act"][:, i]], -1))
        total += float(((target(i, q2) - q) ** 2).mean())
    return total


def test_stacked_mlp_is_one_mlp_per_agent():
    net = StackedMLP(2, 4, 3, (8, 8), tanh_output=True, generator=torch.Generator().manual_seed(0))
    x = torch.randn(2, 10, 4)
    y = net(x)
    assert y.shape == (2, 10, 3)
    for i in range(2):
        torch.testing.assert_close(y[i], agent_mlp(net, i, x[i]))
    assert not torch.equal(net.out.weight[0], net.out.weight[1])   # agents start different


def test_low_precision_multiplies_the_hidden_layers_in_bfloat16_and_keeps_float32_parameters():
    g = torch.Generator().manual_seed(0)
    full = StackedMLP(2, 24, 3, (64, 64), generator=g)
    low = StackedMLP(2, 24, 3, (64, 64), low_precision=True)
    low.load_state_dict(full.state_dict())
    assert [l.low_precision for l in low.hidden] == [True, True] and not low.out.low_precision
    x = torch.randn(2, 50, 24, generator=g)
    y, y_low = full(x), low(x)
    assert y_low.dtype == torch.float32
    # each hidden layer rounded to 8 significant bits: close to float32, but not equal to it
    torch.testing.assert_close(y_low, y, rtol=0.05, atol=0.02)
    assert not torch.equal(y_low, y)
    # by hand: each hidden layer's inputs, weights and bias rounded to bfloat16, summed in
    # float32 and the result rounded again (up to a last bit where the sums' order differs);
    # the output layer in float32
    def rounded(t):
        return t.bfloat16().float()
    h = rounded(x)
    for layer in low.hidden:
        h = rounded(torch.relu(h @ rounded(layer.weight) + rounded(layer.bias)))
    by_hand = h @ low.out.weight + low.out.bias
    torch.testing.assert_close(y_low, by_hand, rtol=1e-2, atol=2e-4)
    assert (y_low - by_hand).abs().max() < (y - by_hand).abs().max() / 4
    y_low.square().sum().backward()
    for p in low.parameters():
        assert p.grad.dtype == torch.float32 and p.grad.abs().sum() > 0


def test_a_bf16_learner_updates_close_to_the_float32_one():
    batch = random_batch()
    full, low = small_agent(), small_agent(bf16_matmuls=True)
    infos = []
    for agent in (full, low):
        agent.normalizer.update(batch["obs"].numpy())
        infos.append(agent.update(batch))
    for key in ("critic_loss", "actor_loss", "q_mean"):
        assert infos[1][key] == pytest.approx(infos[0][key], rel=0.03, abs=1e-3), key
    assert infos[1] != infos[0]
    # Adam's first step moves each weight by about +-lr: the two agree but for a few weights
    # whose gradient is near zero and changed sign
    for a, b in zip(full.critic.parameters(), low.critic.parameters()):
        assert b.dtype == torch.float32
        assert ((b - a).abs() > 1e-4).float().mean() < 0.05


def test_bf16_on_a_cpu_without_native_bfloat16_warns_that_it_is_slower(monkeypatch):
    monkeypatch.setattr(daddpg, "native_bf16", lambda: False)
    with pytest.warns(UserWarning, match="no native bfloat16"):
        small_agent(bf16_matmuls=True)
    monkeypatch.setattr(daddpg, "native_bf16", lambda: True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        small_agent(bf16_matmuls=True)


def test_the_first_stacks_alone_give_the_same_outputs_and_only_their_gradients():
    net = StackedMLP(4, 4, 2, (8, 8), generator=torch.Generator().manual_seed(0))
    x = torch.randn(4, 6, 4)
    torch.testing.assert_close(net(x[:2], stacks=2), net(x)[:2])
    net(x[:2], stacks=2).sum().backward()
    for p in net.parameters():
        assert p.grad[:2].abs().sum() > 0 and (p.grad[2:] == 0).all()


def test_with_twin_critics_the_actor_climbs_the_first_twin_only():
    """TD3: the actor's loss is -Q of the first twin of its own critic (plus the penalty);
    changing the second twins changes the critic loss, not the actor's."""
    a, b = small_agent(twin_critics=True), small_agent(twin_critics=True)
    with torch.no_grad():
        for p in b.critic.parameters():
            p[2:] += 0.5                                   # stacks 2, 3: the second twins
    batch = random_batch()
    out_a, out_b = a.update(batch), b.update(batch)
    assert out_a["actor_loss"] == pytest.approx(out_b["actor_loss"], rel=1e-6)
    assert out_a["critic_loss"] != pytest.approx(out_b["critic_loss"], rel=1e-3)
    for pa, pb in zip(a.actor.parameters(), b.actor.parameters()):
        torch.testing.assert_close(pa, pb)


def test_twin_min_weight_mixes_the_minimum_and_the_mean_of_the_target_twins():
    """WD3's target: r + gamma (beta min(Q'1, Q'2) + (1 - beta) mean), per agent, by hand."""
    batch = random_batch()
    r = batch["rew"].T.unsqueeze(-1)                       # (A, B, 1)
    not_done = (1 - batch["done"]).view(1, -1, 1)
    targets = {}
    for beta in (1.0, 0.5, 0.0):
        agent = small_agent(twin_critics=True, twin_min_weight=beta)
        with torch.no_grad():                              # twins far apart, so min != mean
            for p in agent.critic_target.parameters():
                p[2:] += 0.3
        o2 = agent.normalizer.normalize(batch["next_obs"])
        s2 = o2.reshape(8, -1)
        y = agent.td_target(r, not_done, o2.transpose(0, 1))
        for i in range(2):
            with torch.no_grad():
                a2 = agent_mlp(agent.actor_target, i, o2[:, i]) * agent.action_mask[i, 0]
                q1, q2 = (agent_mlp(agent.critic_target, t * 2 + i, torch.cat([s2, a2], -1))[:, 0]
                          for t in (0, 1))
            mix = beta * torch.minimum(q1, q2) + (1 - beta) * (q1 + q2) / 2
            expected = batch["rew"][:, i] + agent.config.gamma * (1 - batch["done"]) * mix
            torch.testing.assert_close(y[i, :, 0], expected)
        targets[beta] = y
    assert (targets[0.0] > targets[1.0] + 1e-4).any() and (targets[0.0] >= targets[1.0] - 1e-6).all()
    with pytest.raises(ValueError, match="twin_min_weight"):
        DADDPGConfig(twin_min_weight=0.5)                  # needs twin critics
    with pytest.raises(ValueError, match="twin_min_weight"):
        DADDPGConfig(twin_critics=True, twin_min_weight=1.5)


def test_update_follows_equations_13_to_15():
    agent = small_agent()
    agent.normalizer.update(np.random.default_rng(0).normal(size=(50, 2, 7)))
    batch = random_batch()
    norm = agent.normalizer.normalize
    old = {k: [p.detach().clone() for p in getattr(agent, k).parameters()]
           for k in ("actor", "critic", "actor_target", "critic_target")}
    c = agent.config
    o, o2 = norm(batch["obs"]), norm(batch["next_obs"])
    s, s2 = o.reshape(8, -1), o2.reshape(8, -1)            # whole state (s_left, s_right)
    expected_critic = 0.0
    for i in range(2):
        with torch.no_grad():
            a2 = agent_mlp(agent.actor_target, i, o2[:, i]) * agent.action_mask[i, 0]
            q2 = agent_mlp(agent.critic_target, i, torch.cat([s2, a2], -1))[:, 0]
            y = batch["rew"][:, i] + c.gamma * (1 - batch["done"]) * q2           # Eq. 13 target
            q = agent_mlp(agent.critic, i, torch.cat([s, batch["act"][:, i]], -1))[:, 0]
        expected_critic += float(((y - q) ** 2).mean())
    out = agent.update(batch)
    assert out["critic_loss"] == pytest.approx(expected_critic, rel=1e-5)
    # Eq. 15: theta' <- tau theta + (1 - tau) theta' with the updated online weights
    tau = c.tau
    for online, target, before in ((agent.actor, agent.actor_target, old["actor_target"]),
                                   (agent.critic, agent.critic_target, old["critic_target"])):
        for p, pt, pb in zip(online.parameters(), target.parameters(), before):
            torch.testing.assert_close(pt, tau * p.detach() + (1 - tau) * pb)
    # both networks of both agents moved
    for key in ("actor", "critic"):
        for p, pb in zip(getattr(agent, key).parameters(), old[key]):
            assert not torch.equal(p[0], pb[0]) and not torch.equal(p[1], pb[1])


def test_agents_learn_independently_from_their_own_rewards():
    """Agent 0's networks after updates do not depend on agent 1's rewards (stacked Adam and
    per-agent gradient clipping are per agent), and vice versa."""
    rew_a = torch.randn(8, 2, generator=torch.Generator().manual_seed(1))
    rew_b = rew_a.clone()
    rew_b[:, 1] = rew_b[:, 1] * 100 + 5
    a, b = small_agent(grad_clip=0.5), small_agent(grad_clip=0.5)
    for k in range(5):
        a.update(random_batch(k, rew=rew_a))
        b.update(random_batch(k, rew=rew_b))
    for key in ("actor", "critic"):
        for pa, pb in zip(getattr(a, key).parameters(), getattr(b, key).parameters()):
            torch.testing.assert_close(pa[0], pb[0])
            assert not torch.allclose(pa[1], pb[1])


def test_gradient_clipping_bounds_each_agents_norm():
    """After an update with a small grad_clip, each agent's gradient norm over each network
    is the bound; with a large one the gradients are left as they were computed."""
    def agent_norms(agent, net):
        grads = [p.grad for p in getattr(agent, net).parameters()]
        return torch.stack([g[i].pow(2).sum() for g in grads for i in range(2)]).view(-1, 2).sum(0).sqrt()

    clipped, free = small_agent(grad_clip=1e-4), small_agent(grad_clip=1e6)
    clipped.update(random_batch())
    free.update(random_batch())
    for net in ("critic", "actor"):
        torch.testing.assert_close(agent_norms(clipped, net), torch.full((2,), 1e-4), rtol=1e-3, atol=0)
        assert (agent_norms(free, net) > 1e-3).all()


def test_actor_gradient_ascends_the_critic():
    """Eq. 14: many actor steps against a fixed critic raise Q(s, mu(s))."""
    agent = small_agent(action_l2=0.0)
    batch = random_batch()
    o = agent.normalizer.normalize(batch["obs"]).transpose(0, 1)
    s = o.transpose(0, 1).reshape(1, 8, -1).expand(2, 8, -1)

    def q_of_policy():
        with torch.no_grad():
            return agent.critic(torch.cat([s, agent.actor(o) * agent.action_mask], -1)).mean(dim=(1, 2))

    before = q_of_policy()
    critic_state = {k: v.clone() for k, v in agent.critic.state_dict().items()}
    for _ in range(30):
        agent.update(batch)
        agent.critic.load_state_dict(critic_state)        # hold the critic fixed
    assert (q_of_policy() > before).all()


def test_a_penalty_weight_per_sample_replaces_action_l2():
    """Equal weights give the scalar penalty; a weight of 0 on agent 0's rows leaves agent
    0's actor to the critic alone, while agent 1's update is unchanged."""
    batch = random_batch()
    plain, same, free = (small_agent(action_l2=0.3) for _ in range(3))
    out = plain.update(batch)
    assert same.update({**batch, "penalty_weight": torch.full((8, 2), 0.3)})["actor_loss"] == \
        pytest.approx(out["actor_loss"], rel=1e-6)
    free.update({**batch, "penalty_weight": torch.tensor([[0.0, 0.3]]).expand(8, 2)})
    for p_plain, p_same, p_free in zip(plain.actor.parameters(), same.actor.parameters(),
                                       free.actor.parameters()):
        torch.testing.assert_close(p_same, p_plain)
        torch.testing.assert_close(p_free[1], p_plain[1])
        assert not torch.allclose(p_free[0], p_plain[0])


def test_a_shaping_term_is_a_reward_in_the_learners_units():
    """shaping (B, A) adds to the scaled reward: the same update as its reward / reward_scale."""
    batch = random_batch()
    shaping = torch.randn(8, 2, generator=torch.Generator().manual_seed(1))
    shaped, moved, plain = (small_agent(reward_scale=0.5) for _ in range(3))
    out = shaped.update({**batch, "shaping": shaping})
    ref = moved.update({**batch, "rew": batch["rew"] + shaping / 0.5})
    assert out["critic_loss"] == pytest.approx(ref["critic_loss"], rel=1e-5)
    assert plain.update(batch)["critic_loss"] != pytest.approx(out["critic_loss"], rel=1e-3)
    for p_shaped, p_moved in zip(shaped.critic.parameters(), moved.critic.parameters()):
        torch.testing.assert_close(p_shaped, p_moved)


def test_actions_masked_and_bounded():
    agent = small_agent()
    obs = np.random.default_rng(0).normal(size=(6, 2, 7))
    rng = np.random.default_rng(1)
    for explore in (False, True):
        a = agent.act(obs, rng, explore=explore)
        assert a.shape == (6, 2, 3)
        assert np.all(a[:, 0, 2] == 0.0)                # agent 0 has 2 actions
        assert np.all(np.abs(a) <= 1.0)
    assert np.array_equal(agent.act(obs), agent.act(obs))  # deterministic without noise


def test_non_finite_loss_raises_and_changes_nothing():
    agent = small_agent()
    before = [p.detach().clone() for p in agent.critic.parameters()]
    batch = random_batch(rew=torch.full((8, 2), float("nan")))
    with pytest.raises(NonFiniteLoss, match="non-finite loss"):
        agent.update(batch)
    for p, pb in zip(agent.critic.parameters(), before):
        assert torch.equal(p, pb)


def test_state_dict_round_trip_continues_identically():
    a, b = small_agent(), small_agent()
    a.update(random_batch(0))
    b.load_state_dict(a.state_dict())
    ra, rb = a.update(random_batch(1)), b.update(random_batch(1))
    assert ra == rb
    other = DADDPG(DADDPGConfig(hidden=(16, 16), batch_size=8, buffer_size=100), (5, 8), ACT)
    with pytest.raises(ValueError, match="obs_sizes"):
        other.load_state_dict(a.state_dict())


@pytest.mark.parametrize("eval_actor", ["online", "target", "average"])
def test_the_deterministic_policy_acts_with_eval_actor_and_exploration_with_the_actors(eval_actor):
    """eval_actor "target" or "average": evaluations act with the Polyak-averaged actors or
    the slower averages of policy_average; exploring actions (noise and random actions off
    here) still come from the online actors; a policy file holds the evaluated actors, and a
    learner loaded from it acts as the saved one did."""
    agent = small_agent(eval_actor=eval_actor, noise_std=0.0, tau=0.5, policy_average=0.2)
    for k in range(3):
        agent.update(random_batch(k))
    obs = random_batch(9)["obs"].numpy()                                    # (N, A, O)
    norm = agent.normalizer.normalize(torch.as_tensor(obs)).transpose(0, 1)     # (A, N, O)
    mask = agent.action_mask
    online, target, average = ((net(norm) * mask).transpose(0, 1).detach().numpy()
                               for net in (agent.actor, agent.actor_target, agent.actor_average))
    assert not np.allclose(online, target, atol=1e-4) and not np.allclose(target, average, atol=1e-4)
    evaluated = agent.act(obs)
    expected = {"online": online, "target": target, "average": average}
    np.testing.assert_allclose(evaluated, expected[eval_actor], atol=1e-6)
    for which, actions in expected.items():                      # any actors when asked by name
        np.testing.assert_allclose(agent.act(obs, actors=which), actions, atol=1e-6)
    np.testing.assert_allclose(agent.act(obs, np.random.default_rng(0), explore=True), online, atol=1e-6)
    loaded = small_agent(eval_actor=eval_actor, policy_average=0.2)
    loaded.load_policy_state_dict(agent.policy_state_dict())
    np.testing.assert_allclose(loaded.act(obs), evaluated, atol=1e-6)
    whole = small_agent(eval_actor=eval_actor, policy_average=0.2)   # a latest checkpoint's learner state
    whole.load_policy_state_dict(agent.state_dict())
    np.testing.assert_allclose(whole.act(obs), evaluated, atol=1e-6)


def test_policy_average_is_an_exponential_average_of_the_actors_and_resumes():
    """After each update the averaged actors move policy_average of the way to the online
    ones (theta_avg <- theta_avg + rate (theta - theta_avg)), computed here by hand; they
    do not change learning (the same updates as without them) and a learner state carries
    them; without policy_average there are none to act with."""
    rate = 0.1
    agent, plain = small_agent(policy_average=rate), small_agent()
    expected = [p.detach().clone() for p in agent.actor.parameters()]
    for k in range(4):
        assert agent.update(random_batch(k)) == plain.update(random_batch(k))
        expected = [e + rate * (p.detach() - e) for e, p in zip(expected, agent.actor.parameters())]
    for e, p in zip(expected, agent.actor_average.parameters()):
        torch.testing.assert_close(p, e)
    resumed = small_agent(policy_average=rate)
    resumed.load_state_dict(agent.state_dict())
    for a, b in zip(resumed.actor_average.parameters(), agent.actor_average.parameters()):
        assert torch.equal(a, b)
    with pytest.raises(ValueError, match="policy_average"):
        plain.act(random_batch(0)["obs"].numpy(), actors="average")
    with pytest.raises(ValueError, match="eval_actor.*policy_average"):
        DADDPGConfig(eval_actor="average")
    with pytest.raises(ValueError, match="policy_average"):
        DADDPGConfig(policy_average=1.5)


def test_config_validation_names_the_field():
    with pytest.raises(ValueError, match="gamma"):
        DADDPGConfig(gamma=1.5)
    with pytest.raises(ValueError, match="tau"):
        DADDPGConfig(tau=0.0)
    with pytest.raises(ValueError, match="eval_actor"):
        DADDPGConfig(eval_actor="averaged")
    with pytest.raises(ValueError, match="unknown DADDPG field"):
        DADDPGConfig.from_dict({"learning_rate": 1e-3})
    assert DADDPGConfig.from_dict(DADDPGConfig().to_dict()) == DADDPGConfig()


def test_update_flops_counts_the_matmuls():
    agent = small_agent()
    fa = 2 * 2 * (7 * 16 + 16 * 16 + 16 * 3)
    fc = 2 * 2 * (17 * 16 + 16 * 16 + 16 * 1)
    assert agent.actor.flops_per_sample() == fa and agent.critic.flops_per_sample() == fc
    assert agent.update_flops(10) == 10 * (4 * fa + 6 * fc)
    twins = small_agent(twin_critics=True)                 # the actor pass runs the first twins only
    assert twins.update_flops(10) == 10 * (4 * fa + 4 * 2 * fc + 2 * fc)


def test_normalizer_matches_numpy_and_clips():
    x = np.random.default_rng(0).normal(3.0, 2.0, size=(500, 2, 4))
    norm = RunningNormalizer(2, 4, clip=1.5)
    norm.update(x[:200])
    norm.update(x[200:])
    np.testing.assert_allclose(norm.mean.numpy(), x.mean(axis=0), rtol=1e-5)
    np.testing.assert_allclose(norm.std.numpy(), x.std(axis=0), rtol=1e-4)
    y = norm.normalize(torch.as_tensor(x, dtype=torch.float32)).numpy()
    assert y.max() <= 1.5 and y.min() >= -1.5
    inside = np.abs((x - x.mean(0)) / x.std(0)) < 1.4
    np.testing.assert_allclose(y[inside], ((x - x.mean(0)) / x.std(0))[inside], atol=1e-4)
    restored = RunningNormalizer(2, 4, clip=1.5)
    restored.load_state_dict(norm.state_dict())
    assert torch.equal(restored.mean, norm.mean) and torch.equal(restored.std, norm.std)


def test_replay_wraps_around_and_reloads_identically():
    buf = ReplayBuffer(10, 2, 3, 2)
    for k in range(4):                                     # 16 transitions into 10 slots
        n = 4
        val = np.arange(k * n, (k + 1) * n, dtype=float)
        buf.add(np.broadcast_to(val[:, None, None], (n, 2, 3)), np.zeros((n, 2, 2)),
                np.zeros((n, 2)), np.zeros((n, 2, 3)), np.zeros(n))
    assert len(buf) == 10
    assert sorted(set(buf.data["obs"][:, 0, 0].astype(int))) == list(range(6, 16))
    copy = ReplayBuffer(10, 2, 3, 2)
    copy.load_state_dict(buf.state_dict())
    s1 = buf.sample(np.random.default_rng(5), 6)
    s2 = copy.sample(np.random.default_rng(5), 6)
    for key in s1:
        assert torch.equal(s1[key], s2[key])
    copy.add(np.full((1, 2, 3), 99.0), np.zeros((1, 2, 2)), np.zeros((1, 2)), np.zeros((1, 2, 3)), np.zeros(1))
    buf.add(np.full((1, 2, 3), 99.0), np.zeros((1, 2, 2)), np.zeros((1, 2)), np.zeros((1, 2, 3)), np.zeros(1))
    assert np.array_equal(copy.data["obs"], buf.data["obs"])
    with pytest.raises(ValueError, match="obs"):
        ReplayBuffer(10, 2, 4, 2).load_state_dict(buf.state_dict())


def test_gaussian_noise_has_its_std():
    g = GaussianNoise(0.3).sample(np.random.default_rng(0), (20000,))
    assert abs(g.std() - 0.3) < 0.01 and abs(g.mean()) < 0.01


def test_settings_of_the_older_layout_still_load():
    """Run directories written before tau and the option removals load as they ran."""
    old = {**DADDPGConfig().to_dict(), "polyak": 0.95, "noise": "gaussian", "ou_theta": 0.15,
           "n_step": 1, "value_rescale": False, "advantage_learning": 0.0}
    del old["tau"]
    assert DADDPGConfig.from_dict(old) == DADDPGConfig(tau=1 - 0.95)
    assert DADDPGConfig.from_dict({"advantage_learning": 0}) == DADDPGConfig()   # an int 0 too
    for name, value in (("noise", "ou"), ("value_rescale", True),
                        ("value_rescale", 0), ("advantage_learning", 0.9)):
        with pytest.raises(ValueError, match=f"{name}: .* is no longer an option"):
            DADDPGConfig.from_dict({name: value})
    with pytest.raises(ValueError, match="not both"):
        DADDPGConfig.from_dict({"polyak": 0.9, "tau": 0.1})


def test_behaviour_cloning_term_is_q_filtered():
    """The actor loss gains bc_weight x the squared miss of the demonstrated actions, counted
    only where the critic rates the demonstration above the actor's own action."""
    agent_bc, agent_plain = small_agent(bc_weight=2.5), small_agent()
    for agent in (agent_bc, agent_plain):
        agent.normalizer.update(np.random.default_rng(0).normal(size=(50, 2, 7)))
    batch, demo_rows = random_batch(b=12), 5
    with torch.no_grad():
        o = agent_bc.normalizer.normalize(batch["obs"]).transpose(0, 1)
        a_demo = batch["act"].transpose(0, 1)[:, -demo_rows:]
        a_pi = agent_bc.actor(o)[:, -demo_rows:] * agent_bc.action_mask
        o_demo = o[:, -demo_rows:]
        q_demo = agent_bc.critic(agent_bc._critic_input(o_demo, a_demo))
        q_pi = agent_bc.critic(agent_bc._critic_input(o_demo, a_pi))
        better = (q_demo > q_pi).float()
        expected = 2.5 * (better * ((a_pi - a_demo) ** 2).sum(-1, keepdim=True)).mean(dim=(1, 2)).sum()
    assert 0 < better.sum() < better.numel()          # the filter keeps some rows, drops others
    with_bc = agent_bc.update(batch, demo_rows)["actor_loss"]
    without = agent_plain.update(batch, demo_rows)["actor_loss"]
    assert with_bc - without == pytest.approx(expected.item(), rel=1e-5, abs=1e-6)


def test_behaviour_cloning_pulls_the_actor_to_better_demonstrations():
    """Demonstrations that earn more than the actor's actions: with bc_weight the actor's action
    on those states moves to the demonstrated one faster than from the critic alone."""
    def miss_after(bc_weight):
        agent = small_agent(bc_weight=bc_weight, actor_lr=1e-3, critic_lr=1e-3)
        batch = random_batch(b=16)
        target = torch.tensor([0.8, -0.6, 0.4])
        batch["act"][:] = target * agent.action_mask[:, 0]
        batch["rew"][:] = 1.0                     # the demonstrated actions pay
        batch["done"][:] = 1.0
        for _ in range(150):
            agent.update(batch, demo_rows=16)
        with torch.no_grad():
            a = agent.policy(batch["obs"].transpose(0, 1)).transpose(0, 1)
        return float(((a - batch["act"]) ** 2).sum(-1).mean())

    assert miss_after(5.0) < 0.5 * miss_after(0.0)


def test_demo_settings_are_validated():
    with pytest.raises(ValueError, match="demo_batch_size"):
        DADDPGConfig(demo_batch_size=-1)
    with pytest.raises(ValueError, match="bc_weight"):
        DADDPGConfig(bc_weight=-0.1)


def test_a_checkpoint_with_reward_heads_is_refused_by_name():
    """reward_heads left the code: a learner saved with several heads is refused, naming it."""
    config = DADDPGConfig(hidden=(16, 16), batch_size=8, buffer_size=100)
    state = DADDPG(config, OBS, ACT, seed=3).state_dict()
    DADDPG(config, OBS, ACT, seed=0).load_state_dict(state)
    state["head_scales"] = [0.00025, 0.05, 0.001]
    with pytest.raises(ValueError, match="3 reward heads"):
        DADDPG(config, OBS, ACT, seed=0).load_state_dict(state)


def test_the_share_of_random_actions_can_differ_per_environment_and_agent():
    """random_eps (N, A): 0 keeps the noisy policy's action, 1 draws a random one; the
    random stream is the same as with the config's share (runs without it are unchanged)."""
    obs = np.random.default_rng(0).normal(size=(64, 2, 7))
    agent = small_agent(random_eps=0.5, noise_std=0.0)
    policy = agent.act(obs)
    eps = np.zeros((64, 2))
    eps[:32, 1] = 1.0                       # agent 1 in the first 32 envs: always random
    a = agent.act(obs, np.random.default_rng(1), explore=True, random_eps=eps)
    np.testing.assert_allclose(a[:, 0], policy[:, 0])
    np.testing.assert_allclose(a[32:, 1], policy[32:, 1])
    assert not np.isclose(a[:32, 1, :2], policy[:32, 1, :2]).any()
    same = agent.act(obs, np.random.default_rng(1), explore=True, random_eps=np.full((64, 2), 0.5))
    np.testing.assert_array_equal(same, agent.act(obs, np.random.default_rng(1), explore=True))

