"""The variants of the update only the ``paper`` and ``paper-code`` presets use (chosen by
:func:`fleetrl.agent.update.choose_variants`): π_θold fixed at line 11, GAE inside each window, the TD(0)
critic target of Eq. 3, and the authors' one Adam stepping the critic and then the actor."""

from __future__ import annotations

from collections.abc import Generator
from typing import TYPE_CHECKING

import torch

from fleetrl.agent.config import PPOConfig
from fleetrl.agent.losses import gae, td_targets
from fleetrl.agent.network import ActorCritic

if TYPE_CHECKING:
    from fleetrl.agent.update import Advantages, Batch, Gradient, Minibatch, Model, Objective


def round_start_policy(net: ActorCritic, head: torch.Tensor, memory: Batch) -> torch.Tensor:
    """π_θold = π_θ at line 11 (the paper): log π of the stored actions under the policy as the round
    begins."""
    return net.log_probs_and_entropy(head, memory.actions)[0]


def window_advantages(net: ActorCritic, memory: Batch, values: torch.Tensor, cfg: PPOConfig) -> Advantages:
    """Eq. 2 inside each U-window (the paper: the sum runs to the window's end) with the current critic."""
    del net, values
    gamma, lam = cfg.gamma, cfg.gae_lambda

    def advantages(w: slice, v: torch.Tensor, v_next: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return gae(memory.rewards[w], v, v_next, memory.terminated[w], memory.episode_end[w], gamma, lam), v

    return advantages


def td_target(
    memory: Batch, w: slice, next_values: torch.Tensor, adv: torch.Tensor, values: torch.Tensor, gamma: float
) -> torch.Tensor:
    """V^target = r_{t+1} + γ·V(s_{t+1}) (Eq. 3), bootstrapped at a truncation, not at a terminal state."""
    del adv, values
    return td_targets(memory.rewards[w], next_values, memory.terminated[w], gamma)


def critic_then_actor(
    model: Model, batch: Minibatch, objective: Objective
) -> Generator[Gradient, Gradient, Gradient]:
    """The authors' code: one optimisation is two steps of one Adam. The critic's gradient and step (lines
    20-21), then π_θ again at the parameters that step left and the actor's gradient and step (22-23)."""
    g_mu = list(torch.autograd.grad(model.config.critic_coef * batch.critic_loss, model.critic_grad))
    applied = yield model.with_extra_loss(g_mu, model.critic)
    model.step("critic", applied)
    head, _ = model.net(batch.obs)
    g_theta = list(torch.autograd.grad(objective(batch, head), model.actor))
    applied = yield model.with_extra_loss(g_theta, model.actor)
    model.step("actor", applied)
    return applied
