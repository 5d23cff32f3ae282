"""One round's PPO update (Algorithm 2, lines 11-24) cut into steps, each a gradient and the optimiser steps
that take it.

:class:`RoundUpdate` is built at line 11 (π_θold fixed, the K windows of line 13 drawn) and then gives one
step's gradients at a time; :class:`~fleetrl.agent.ppo.PPOAgent` applies them through its Adam optimisers.
With ``optimisers='per_model'`` step j is optimisation j: the critic's and the actor's gradients taken at
the same parameters (lines 20 and 22), applied critic first (lines 21, 23). With ``'one_sequential'``
(the authors' code) optimisation j is two steps: 2j the critic's gradient, 2j+1 the actor's, taken at the
parameters the critic's step left.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from fleetrl.agent.config import PPOConfig
from fleetrl.agent.losses import clipped_surrogate, critic_loss, gae, td_targets
from fleetrl.agent.memory import Transitions, sample_window
from fleetrl.agent.network import ActorCritic

CRITIC = "critic"
"""the part of a step that moves μ (lines 20-21)"""
ACTOR = "actor"
"""the part of a step that moves θ (lines 22-23)"""


@dataclass(frozen=True)
class UpdateStats:
    """What one round's update did, averaged over its K optimisations."""

    actor_loss: float
    """−L^CLIP (Eq. 6), the quantity the actor minimises (entropy bonus not included)"""
    critic_loss: float
    """L^V (Eq. 3; unweighted by ``critic_coef``)"""
    entropy: float
    """mean entropy of π_θ over the sampled windows (nats)"""
    approx_kl: float
    """mean of (R − 1) − log R, an estimate of KL(π_θold ‖ π_θ) (diagnostic)"""
    clip_fraction: float
    """share of samples whose ratio R_t lay outside [1 − ε, 1 + ε] (diagnostic)"""


@dataclass
class _CriticTerms:
    """What the critic's half of an optimisation computed on its window."""

    window: slice
    head: torch.Tensor
    """the actor head's output on the window (logits, or the Gaussian mean in units of the box)"""
    advantages: torch.Tensor
    loss: torch.Tensor


class RoundUpdate:
    """The update of one round, step by step (see the module docstring for what a step is).

    :param net: the actor-critic being trained
    :param config: the agent's hyper-parameters
    :param data: the trajectory memory's transitions, behaviour log-probabilities recorded
    :param window_rng: draws the K window starts (line 13), all of them here, in order
    :param actor_params: θ, in the order of an actor gradient (trunk, policy head)
    :param critic_grad_params: what L^V is differentiated against (trunk, value head)
    :param n_trunk: how many of ``critic_grad_params`` are the trunk's
    """

    def __init__(
        self,
        net: ActorCritic,
        config: PPOConfig,
        data: Transitions,
        window_rng: np.random.Generator,
        actor_params: list[nn.Parameter],
        critic_grad_params: list[nn.Parameter],
        n_trunk: int,
    ) -> None:
        cfg = config
        self.net, self.config = net, config
        self._actor_params, self._critic_grad_params, self._n_trunk = (
            actor_params,
            critic_grad_params,
            n_trunk,
        )
        self.obs = torch.from_numpy(data.obs)
        self.actions = torch.from_numpy(data.actions)
        self.rewards = torch.from_numpy(data.rewards)
        self.next_obs = torch.from_numpy(data.next_obs)
        self.terminated = torch.from_numpy(data.terminated)
        self.episode_end = torch.from_numpy(data.episode_end)

        # Line 11: π_θold ← π_θ — the log-probabilities of the stored actions under the policy as it is now,
        # or (old_policy 'behaviour') under the policy that acted.
        with torch.no_grad():
            head, values = net(self.obs)
            if cfg.old_policy == "behaviour":
                self.old_log_probs = torch.from_numpy(data.behaviour_log_probs)
            else:
                self.old_log_probs = net.log_probs_and_entropy(head, self.actions)[0]
            self.memory_advantages = None
            self.memory_values = values
            """V_μ(s) at line 11: with ``gae_scope='memory'`` the λ-return target is Â + this, fixed for the
            round like Â (not Â + the critic's current value, whose loss would not depend on the critic)"""
            if cfg.gae_scope == "memory":  # Eq. 2 once over the whole memory, critic frozen at line 11
                next_values = net.value_of(self.next_obs)
                self.memory_advantages = gae(
                    self.rewards,
                    values,
                    next_values,
                    self.terminated,
                    self.episode_end,
                    cfg.gamma,
                    cfg.gae_lambda,
                )
        # Line 13, K times: a contiguous window of U transitions from a random start (Figure 3).
        self.windows = [
            sample_window(len(data), cfg.batch_size, window_rng) for _ in range(cfg.n_optimisations)
        ]
        self.sequential = cfg.optimisers == "one_sequential"
        self.n_steps = cfg.n_optimisations * (2 if self.sequential else 1)
        """how many steps the update has (K, or 2K when the critic and the actor step in turn)"""
        self.applied = 0
        """how many steps were applied so far"""
        self._critic_half: _CriticTerms | None = None
        self._totals = np.zeros(5)  # actor loss, critic loss, entropy, approx KL, clip fraction

    def parts(self, k: int) -> tuple[str, ...]:
        """What step ``k`` moves, in the order its optimiser steps are taken (:func:`step_parts`)."""
        return step_parts(self.config, k)

    def gradients(self, k: int) -> list[list[torch.Tensor]]:
        """Step ``k``'s gradients, one list per part of :meth:`parts` (g_μ over the critic optimiser's
        parameters, g_θ over θ); accumulates the step's losses into :meth:`stats`."""
        if not self.sequential:  # lines 14-22 at one set of parameters
            half = self._critic_terms(k)
            return [*reversed(self._actor_and_critic(half))]
        if k % 2 == 0:  # the authors' order: the critic's gradient and step first ...
            self._critic_half = self._critic_terms(k // 2)
            return [self._critic_gradient(self._critic_half)]
        assert self._critic_half is not None, "the actor's half follows its critic's half"
        half, self._critic_half = self._critic_half, None
        head, _ = self.net(self.obs[half.window])  # ... then π_θ at the parameters the critic's step left
        half.head = head
        objective = self._actor_objective(half)
        return [list(torch.autograd.grad(objective, self._actor_params))]

    def stats(self) -> UpdateStats:
        """The losses and diagnostics averaged over the K optimisations."""
        means = self._totals / self.config.n_optimisations
        return UpdateStats(*(float(m) for m in means))

    # ---- one optimisation on window j (lines 14-18) ---------------------------------------------------

    def _critic_terms(self, j: int) -> _CriticTerms:
        """Lines 14-17: π_θ(·|s_t), V_μ(s_t), Â (Eq. 2), V^target and L^V (Eq. 3) on window j."""
        cfg = self.config
        start, stop = self.windows[j]
        w = slice(start, stop)
        head, v = self.net(self.obs[w])
        with torch.no_grad():
            v_next = self.net.value_of(self.next_obs[w])
        if self.memory_advantages is None:  # line 15, Eq. 2: the sum runs to the end of the window
            adv = gae(
                self.rewards[w],
                v.detach(),
                v_next,
                self.terminated[w],
                self.episode_end[w],
                cfg.gamma,
                cfg.gae_lambda,
            )
        else:
            adv = self.memory_advantages[w]
        if cfg.critic_target == "td":  # line 16, Eq. 3: V^target = r + γV(s'), bootstrapped at truncation
            targets = td_targets(self.rewards[w], v_next, self.terminated[w], cfg.gamma)
        elif self.memory_advantages is None:  # the λ-return Â + V(s), both at the current critic
            targets = adv + v.detach()
        else:  # the λ-return of line 11: Â and V(s) both from the critic as the round began
            targets = adv + self.memory_values[w]
        if cfg.normalise_advantages and adv.numel() > 1:
            adv = (adv - adv.mean()) / (adv.std() + 1e-8)
        l_v = critic_loss(v, targets, cfg.critic_loss)  # line 17, Eq. 3
        self._totals[1] += l_v.item()
        return _CriticTerms(w, head, adv, l_v)

    def _actor_objective(self, half: _CriticTerms) -> torch.Tensor:
        """Line 18: −L^CLIP (Eq. 6) − β·H, the quantity the actor descends (Eq. 7).

        log π_θ(a_t|s_t) and H come from the actor head (softmax, or a Gaussian's log-density summed over
        the action components); the ratio R_t = exp(log π_θ − log π_θold) (Eq. 5) and its clip are the same
        for both."""
        cfg = self.config
        log_probs, entropy = self.net.log_probs_and_entropy(half.head, self.actions[half.window])
        old = self.old_log_probs[half.window]
        l_clip = clipped_surrogate(log_probs, old, half.advantages, cfg.clip_eps)
        with torch.no_grad():
            log_ratio = log_probs - old
            ratio = log_ratio.exp()
            kl = ((ratio - 1.0) - log_ratio).mean()
            clipped = ((ratio - 1.0).abs() > cfg.clip_eps).float().mean()
        self._totals[[0, 2, 3, 4]] += [-l_clip.item(), entropy.item(), kl.item(), clipped.item()]
        return -l_clip - cfg.entropy_coef * entropy

    def _critic_gradient(self, half: _CriticTerms) -> list[torch.Tensor]:
        """Line 20: g_μ = ∇(c·L^V) over the trunk and the value head."""
        return list(torch.autograd.grad(self.config.critic_coef * half.loss, self._critic_grad_params))

    def _actor_and_critic(self, half: _CriticTerms) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
        """Lines 20 and 22 at the same parameters: (g_θ, g_μ).

        With ``trunk_split == 'actor'`` the critic loss's trunk gradient, times ``critic_trunk_coef``, joins
        g_θ, so the actor optimiser alone moves the trunk and the shared gradient carries the critic's say.
        """
        cfg = self.config
        objective = self._actor_objective(half)
        g_theta = list(torch.autograd.grad(objective, self._actor_params, retain_graph=True))
        g_v = self._critic_gradient(half)
        trunk_grads, head_grads = g_v[: self._n_trunk], g_v[self._n_trunk :]
        if cfg.trunk_split == "shared":
            return g_theta, trunk_grads + head_grads
        for i, g in enumerate(trunk_grads):
            g_theta[i] = g_theta[i] + cfg.critic_trunk_coef * g
        return g_theta, head_grads


def step_parts(config: PPOConfig, k: int) -> tuple[str, ...]:
    """What step ``k`` of an update moves, in order: the critic and the actor (``per_model``), or the critic
    at even and the actor at odd steps (``one_sequential``)."""
    if config.optimisers == "per_model":
        return (CRITIC, ACTOR)
    return (CRITIC,) if k % 2 == 0 else (ACTOR,)
