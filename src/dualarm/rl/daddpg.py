"""Dual-agent DDPG, paper Section 2.3: one DDPG agent per arm, trained together.

Agent i has an actor mu_i(s_i) on its own observation and a critic Q_i(s, a_i) on the
whole state s = (s_1, s_2) and its own action, plus target copies mu'_i and Q'_i:

    Eq. 13   L(theta_Q_i) = E[(y_i - Q_i(s, a_i))^2],  y_i = r_i + gamma Q'_i(s', mu'_i(s'_i))
    Eq. 14   grad J(theta_mu_i) = E[grad_a Q_i(s, a) |a=mu_i(s_i) grad_theta mu_i(s_i)]
    Eq. 15   theta' <- tau theta + (1 - tau) theta'

``td_target``, ``actor_loss`` and ``soft_update`` are the three equations; ``update`` is one
step of all three. TD3's twin critics and target smoothing (Fujimoto et al. 2018), the target
clip (HER's clip_return) and Q-filtered behaviour cloning (Nair et al. 2018) are options.

Both agents' networks are stacked along a leading agent axis (``StackedMLP``), so each
line below updates the two agents in one batched pass.

Shapes: A agents, B batch, O observation width, U action width (narrower agents are
zero-padded to O and U; padded action components are masked to zero).
"""

from __future__ import annotations

import warnings

import numpy as np
import torch

from dualarm.rl.config import EVAL_ACTORS, DADDPGConfig
from dualarm.rl.networks import StackedMLP
from dualarm.rl.noise import GaussianNoise
from dualarm.rl.normalizer import RunningNormalizer


def native_bf16() -> bool:
    """Whether this CPU multiplies bfloat16 natively (oneDNN's check: AVX512-BF16 or AMX)."""
    try:
        return bool(torch.ops.mkldnn._is_mkldnn_bf16_supported())
    except (AttributeError, RuntimeError):
        return False


class NonFiniteLoss(FloatingPointError):
    """A loss became NaN or infinite: the update was not applied."""


class DADDPG:
    """The learner: act with noise, update from replay batches, save and load.

    Args:
        config: hyper-parameters.
        obs_sizes: observation width of each agent.
        act_sizes: action width of each agent (actions in [-1, 1]).
        seed: seeds the initial weights.

    Each critic has one output, the return of the rewards times ``config.reward_scale``.
    """

    def __init__(self, config: DADDPGConfig, obs_sizes: tuple[int, ...],
                 act_sizes: tuple[int, ...], seed: int = 0):
        self.config = c = config
        self.num_agents = a = len(obs_sizes)
        self.obs_sizes, self.act_sizes = tuple(obs_sizes), tuple(act_sizes)
        self.obs_size, self.act_size = max(obs_sizes), max(act_sizes)
        self._scale = torch.tensor([c.reward_scale], dtype=torch.float32)
        g = torch.Generator().manual_seed(seed)
        state_size = a * self.obs_size
        # Critic stacks: [Q_1 .. Q_A] or, with twin critics, [Q_1 .. Q_A, Q2_1 .. Q2_A].
        self.critics_per_agent = 2 if c.twin_critics else 1
        k = a * self.critics_per_agent
        if c.bf16_matmuls and not native_bf16():
            warnings.warn("bf16_matmuls: this CPU has no native bfloat16 arithmetic (AVX512-BF16 "
                          "or AMX), so updates will be slower than in float32", stacklevel=2)
        low = {"low_precision": c.bf16_matmuls}
        self.actor = StackedMLP(a, self.obs_size, self.act_size, c.hidden, True, g, final_scale=0.1, **low)
        self.critic = StackedMLP(k, state_size + self.act_size, 1, c.hidden, False, g, final_scale=0.1, **low)
        self.actor_target = StackedMLP(a, self.obs_size, self.act_size, c.hidden, True, **low)
        self.critic_target = StackedMLP(k, state_size + self.act_size, 1, c.hidden, **low)
        self.actor_target.load_state_dict(self.actor.state_dict())
        self.critic_target.load_state_dict(self.critic.state_dict())
        # policy_average: a slower average of the actors, for acting only (None: off)
        self.actor_average = None
        if c.policy_average > 0:
            self.actor_average = StackedMLP(a, self.obs_size, self.act_size, c.hidden, True, **low)
            self.actor_average.load_state_dict(self.actor.state_dict())
            self.actor_average.requires_grad_(False)
        for p in (*self.actor_target.parameters(), *self.critic_target.parameters()):
            p.requires_grad_(False)
        # Each network's parameter list, gathered once: walking the modules for it on every
        # update cost more than the soft update itself. load_state_dict copies into these
        # same tensors, so the lists stay valid.
        self._params = {name: list(getattr(self, name).parameters()) for name in
                        ("actor", "critic", "actor_target", "critic_target", "actor_average")
                        if getattr(self, name) is not None}
        self.actor_opt = torch.optim.Adam(self.actor.parameters(), lr=c.actor_lr, fused=True)
        self.critic_opt = torch.optim.Adam(self.critic.parameters(), lr=c.critic_lr, fused=True)
        self.normalizer = RunningNormalizer(a, self.obs_size, c.obs_clip)
        self.action_mask = torch.zeros(a, 1, self.act_size)
        for i, n in enumerate(act_sizes):
            self.action_mask[i, :, :n] = 1.0
        # the components action_l2 penalises: the real ones
        self.penalty_mask = self.action_mask
        # the penalty's weight now: config.action_l2, unless the training loop schedules it
        self.action_l2 = c.action_l2
        self.noise = GaussianNoise(c.noise_std)
        # target smoothing noise draws from the learner's own stream, not torch's global one
        self.torch_rng = torch.Generator().manual_seed(seed + 1)
        self.updates = 0

    def action_penalty(self, actions: torch.Tensor, weight: torch.Tensor | None = None) -> torch.Tensor:
        """The action penalty per agent, (A,), from actions (A, B, U): the mean squared action
        over every real component, times ``action_l2``
        (the attribute: the config's, or the loop's schedule), or times ``weight`` (A, B, 1),
        a weight per sample and agent, before the mean over the batch."""
        squared = actions ** 2 * self.penalty_mask
        if weight is None:
            return self.action_l2 * squared.mean(dim=(1, 2))
        return (weight * squared.mean(dim=2, keepdim=True)).mean(dim=(1, 2))

    # --------------------------------------------------------------- acting
    def actors(self, which: str) -> StackedMLP:
        """The actors named ``which`` (one of ``EVAL_ACTORS``): "online", "target" or
        "average" (``policy_average``'s; ValueError without it)."""
        if which not in EVAL_ACTORS:
            raise ValueError(f"actors must be one of {EVAL_ACTORS}, got {which!r}")
        if which == "average" and self.actor_average is None:
            raise ValueError("no averaged actors: algo.policy_average is 0")
        return {"online": self.actor, "target": self.actor_target, "average": self.actor_average}[which]

    def policy(self, obs: torch.Tensor, explore: bool = True, actors: str | None = None) -> torch.Tensor:
        """mu_i(s_i) for every agent: obs (A, B, O) raw float32 -> actions (A, B, U). The
        online actors, or with ``explore`` False the config's ``eval_actor`` (or ``actors``)."""
        actor = self.actor if explore else self.actors(actors or self.config.eval_actor)
        return actor(self.normalizer.normalize(obs.transpose(0, 1)).transpose(0, 1)) * self.action_mask

    def start_episodes(self, envs: np.ndarray) -> None:
        """New episodes begin in the environments of the boolean mask (N,): the exploration
        that spans steps starts afresh there."""
        self.noise.reset(envs)

    def act(self, obs: np.ndarray, rng: np.random.Generator | None = None,
            explore: bool = False, random_eps: np.ndarray | None = None,
            actors: str | None = None) -> np.ndarray:
        """Actions (N, A, U) in [-1, 1] for observations (N, A, O) of N environments.

        With ``explore``, noise is added and each agent's action is replaced by a uniform
        random one with probability ``random_eps`` (both need ``rng``). ``random_eps`` (N, A),
        if given, is that probability per environment and agent in place of the config's.
        Without ``explore``, ``actors`` names the actors acting (default ``eval_actor``).
        """
        with torch.inference_mode():
            o = torch.as_tensor(np.asarray(obs, dtype=np.float32)).transpose(0, 1)
            actions = self.policy(o, explore, actors).transpose(0, 1).numpy().astype(np.float64)
        if explore:
            c = self.config
            actions = np.clip(actions + self.noise.sample(rng, actions.shape), -1.0, 1.0)
            random = rng.uniform(-1.0, 1.0, size=actions.shape)
            eps = c.random_eps if random_eps is None else random_eps
            pick = rng.random(actions.shape[:2]) < eps
            actions = np.where(pick[..., None], random, actions)
            actions *= self.action_mask[:, 0].numpy()
        return actions

    # ------------------------------------------------------------- learning
    def _critic_input(self, obs_n: torch.Tensor, actions: torch.Tensor,
                      copies: int | None = None) -> torch.Tensor:
        """Critic input (K, B, A*O + U): the whole state s = (s_1, ..., s_A) from normalised
        obs (A, B, O), next to each critic's own agent's action from actions (A, B, U).
        K = A x ``copies`` (default: all critics per agent; 1 feeds only the first twins)."""
        a, b, o = obs_n.shape
        copies = self.critics_per_agent if copies is None else copies
        s = obs_n.transpose(0, 1).reshape(1, b, a * o).expand(a * copies, b, a * o)
        return torch.cat([s, actions.repeat(copies, 1, 1)], -1)

    def _per_agent(self, q: torch.Tensor) -> torch.Tensor:
        """Critic outputs (K, B, 1) -> (critics_per_agent, A, B, 1)."""
        return q.view(self.critics_per_agent, self.num_agents, *q.shape[1:])

    def td_target(self, r: torch.Tensor, not_done: torch.Tensor, o2: torch.Tensor) -> torch.Tensor:
        """Eq. 13's y_i = r_i + gamma Q'_i(s', mu'_i(s'_i)), (A, B, 1), without gradients.

        r (A, B, 1) scaled rewards, not_done (1, B, 1), o2 (A, B, O) normalised next
        observations. With twin critics Q' is the smaller of the two
        target critics (or with ``twin_min_weight`` beta, beta min + (1 - beta) mean), with
        ``target_noise`` the target actions are smoothed (TD3), with ``q_clip`` y is clipped.
        """
        c = self.config
        a2 = self.actor_target(o2)
        if c.target_noise > 0:
            eps = (torch.randn(a2.shape, generator=self.torch_rng) * c.target_noise).clamp(-0.5, 0.5)
            a2 = (a2 + eps).clamp(-1.0, 1.0)
        y = r + c.gamma * not_done * self._target_q(o2, a2)
        return y.clamp(-c.q_clip, c.q_clip) if c.q_clip > 0 else y

    def _target_q(self, o: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
        """Q'_i(s, a_i) (A, B, 1) of the target critics: the smaller twin, or with
        ``twin_min_weight`` beta < 1 beta min + (1 - beta) mean (one critic: itself)."""
        q = self._per_agent(self.critic_target(self._critic_input(o, actions * self.action_mask)))
        beta = self.config.twin_min_weight
        low = q.min(dim=0).values
        return low if beta == 1 else beta * low + (1 - beta) * q.mean(dim=0)

    def actor_loss(self, o: torch.Tensor, q_taken: torch.Tensor, a_taken: torch.Tensor,
                   demo_rows: int = 0, penalty_weight: torch.Tensor | None = None) -> torch.Tensor:
        """Eq. 14 as a loss: -Q_i(s, mu_i(s_i)) through the actor only, plus the action
        penalty (``action_penalty``, with ``penalty_weight`` (A, B, 1) if given), summed over
        agents. With ``bc_weight``, behaviour cloning on the last ``demo_rows`` rows where the
        critic rates the demonstrated action (``q_taken``) above the actor's."""
        c = self.config
        a_pi = self.actor(o) * self.action_mask
        self.critic.requires_grad_(False)
        # only the first twin of each agent's critics scores the actor (TD3): the first A
        # stacked critics, run alone
        a = self.num_agents
        q_pi = self.critic(self._critic_input(o, a_pi, copies=1), stacks=a)
        self.critic.requires_grad_(True)
        loss = (-q_pi.mean(dim=(1, 2)) + self.action_penalty(a_pi, penalty_weight)).sum()
        if demo_rows and c.bc_weight > 0:
            q_demo = q_taken[0, :, -demo_rows:]
            better = (q_demo > q_pi[:, -demo_rows:]).detach().float()              # (A, D, 1)
            miss = ((a_pi[:, -demo_rows:] - a_taken[:, -demo_rows:]) ** 2).sum(-1, keepdim=True)
            loss = loss + c.bc_weight * (better * miss).mean(dim=(1, 2)).sum()
        return loss

    @torch.no_grad()
    def soft_update(self) -> None:
        """Eq. 15: theta' <- tau theta + (1 - tau) theta', for every target network."""
        tau, params = self.config.tau, self._params
        torch._foreach_lerp_(params["actor_target"], params["actor"], tau)
        torch._foreach_lerp_(params["critic_target"], params["critic"], tau)
        if self.actor_average is not None:
            torch._foreach_lerp_(params["actor_average"], params["actor"], self.config.policy_average)

    def update(self, batch: dict[str, torch.Tensor], demo_rows: int = 0) -> dict[str, float]:
        """One gradient step of both agents' critics (Eq. 13) and actors (Eq. 14), then the
        target networks (Eq. 15).

        Args:
            batch: obs and next_obs (B, A, O), act (B, A, U), rew (B, A) and done (B,);
                optionally penalty_weight (B, A), the action penalty's weight per sample and
                agent in place of ``action_l2``; optionally shaping (B, A), a term added to the
                scaled reward (learner units, for example potential-based shaping).
            demo_rows: the last ``demo_rows`` rows of the batch are demonstrations (see
                :meth:`actor_loss`).

        Returns:
            {"critic_loss", "actor_loss", "q_mean"} summed or averaged over agents.

        Raises:
            NonFiniteLoss: a loss is NaN or infinite (no parameter was changed).
        """
        norm = self.normalizer.normalize
        o = norm(batch["obs"]).transpose(0, 1)                     # (A, B, O)
        o2 = norm(batch["next_obs"]).transpose(0, 1)
        a_taken = batch["act"].transpose(0, 1)                     # (A, B, U)
        r = batch["rew"].unsqueeze(-1).transpose(0, 1) * self._scale   # (A, B, 1)
        if "shaping" in batch:                                     # r is a new tensor: add in place
            r[..., 0] += batch["shaping"].transpose(0, 1)
        not_done = (1.0 - batch["done"]).view(1, -1, 1)            # (1, B, 1)

        with torch.no_grad():
            y = self.td_target(r, not_done, o2)
        q = self._per_agent(self.critic(self._critic_input(o, a_taken)))
        critic_loss = ((y - q) ** 2).mean(dim=(2, 3)).sum()       # per sample, summed over critics
        # The actor climbs the critic as it is before this step's critic update.
        weight = batch.get("penalty_weight")
        if weight is not None:
            weight = weight.transpose(0, 1).unsqueeze(-1)          # (A, B, 1)
        actor_loss = self.actor_loss(o, q, a_taken, demo_rows, weight)

        if not (torch.isfinite(critic_loss) and torch.isfinite(actor_loss)):
            raise NonFiniteLoss(f"non-finite loss at update {self.updates + 1}: critic "
                                f"{critic_loss.item()}, actor {actor_loss.item()}")
        self.critic_opt.zero_grad(set_to_none=True)
        self.actor_opt.zero_grad(set_to_none=True)
        # The actor loss's graph does not reach the critic's weights, and the critic loss's
        # does not reach the actor's: one backward pass gives both gradients.
        (critic_loss + actor_loss).backward()
        self._clip("critic")
        self.critic_opt.step()
        self._clip("actor")
        self.actor_opt.step()
        self.soft_update()
        self.updates += 1
        return {"critic_loss": critic_loss.item(), "actor_loss": actor_loss.item(),
                "q_mean": q[0].mean().item()}

    def _clip(self, net: str) -> None:
        """Scale each agent's gradients in the network named ``net`` ("actor" or "critic") so
        that their global norm is at most grad_clip.

        Every stacked parameter is (A, rows, columns), so one norm over its last two axes is
        per agent. The gradients are rewritten only when some agent's norm exceeds the bound
        (in the recipe that is rare; scaling every update by 1 cost about 5 % of its time)."""
        if self.config.grad_clip <= 0:
            return
        grads = [p.grad for p in self._params[net] if p.grad is not None]
        norm = torch.linalg.vector_norm(
            torch.stack([torch.linalg.vector_norm(g, dim=(1, 2)) for g in grads]), dim=0)  # (A,)
        if not bool((norm > self.config.grad_clip).any()):
            return
        scale = (self.config.grad_clip / (norm + 1e-6)).clamp(max=1.0).view(-1, 1, 1)
        for g in grads:
            g.mul_(scale)

    def update_flops(self, batch_size: int | None = None) -> float:
        """Floating-point operations of one ``update`` (matmuls only; forward = 1, backward = 2).

        Critic: target actor and target critic forward, critic forward and backward.
        Actor: actor forward and backward, the first twins' forward and input-gradient backward
        (weight gradients of the critic are not computed in the actor pass).
        """
        b = batch_size or self.config.batch_size
        fa, fc = self.actor.flops_per_sample(), self.critic.flops_per_sample()  # all stacks
        # target actor and critic; critic forward and backward
        critic_pass = fa + fc + 3 * fc
        # actor forward and backward; the first twins' forward and input gradient
        actor_pass = 3 * fa + 2 * fc // self.critics_per_agent
        return b * (critic_pass + actor_pass)

    # -------------------------------------------------------- saving/loading
    _PARTS = ("actor", "critic", "actor_target", "critic_target", "actor_opt", "critic_opt",
              "normalizer")
    _POLICY_PARTS = ("actor", "normalizer")

    def _shapes(self) -> dict:
        return {"obs_sizes": list(self.obs_sizes), "act_sizes": list(self.act_sizes),
                "hidden": list(self.config.hidden)}

    def _restore(self, state: dict, parts: tuple[str, ...], what: str) -> None:
        """Load ``parts`` from ``state`` after checking the network shapes match."""
        if len(state.get("head_scales", ())) > 1:
            raise ValueError(f"the saved {what} has {len(state['head_scales'])} reward heads "
                             "(reward_heads, an option removed since; docs/learning-runs.md)")
        for key, mine in self._shapes().items():
            theirs = state.get(key)
            if theirs is None or list(theirs) != mine:
                raise ValueError(f"{key} {tuple(theirs or ())} of the saved {what} does not match "
                                 f"this one's {tuple(mine)}")
        for part in parts:
            getattr(self, part).load_state_dict(state[part])

    @property
    def _parts(self) -> tuple[str, ...]:
        return self._PARTS + (("actor_average",) if self.actor_average is not None else ())

    def state_dict(self) -> dict:
        """Everything the learner needs to continue exactly (tensors and plain values)."""
        return {**{p: getattr(self, p).state_dict() for p in self._parts},
                "updates": self.updates, "torch_rng": self.torch_rng.get_state(), **self._shapes()}

    def load_state_dict(self, state: dict) -> None:
        """Restore from ``state_dict()``; raises ValueError naming what does not match."""
        self._restore(state, self._parts, "learner")
        self.updates = int(state["updates"])
        if "torch_rng" in state:
            self.torch_rng.set_state(state["torch_rng"])

    def policy_state_dict(self) -> dict:
        """What acting needs: the normaliser and, as "actor", the actors the deterministic
        policy uses (``eval_actor``: the online, target or averaged actors); small, for
        ``best`` policies."""
        state = {**{p: getattr(self, p).state_dict() for p in self._POLICY_PARTS}, **self._shapes()}
        state["actor"] = self.actors(self.config.eval_actor).state_dict()
        return state

    def load_policy_state_dict(self, state: dict) -> None:
        """Restore from ``policy_state_dict()``, or from a whole learner's ``state_dict()``
        (whose actors for acting are the ones ``eval_actor`` names): they become both the
        online and the target actors, so that the deterministic policy is the saved one."""
        own = {"target": "actor_target", "average": "actor_average"}.get(self.config.eval_actor)
        if own is not None and own in state:
            state = {**state, "actor": state[own]}
        self._restore(state, self._POLICY_PARTS, "policy")
        self.use_actors_everywhere()

    def use_actors_everywhere(self) -> None:
        """Copy the online actors over the target and averaged ones, so that the
        deterministic policy is the same whichever actors it reads."""
        self.actor_target.load_state_dict(self.actor.state_dict())
        if self.actor_average is not None:
            self.actor_average.load_state_dict(self.actor.state_dict())
