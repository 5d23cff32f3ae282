"""The choices of the update a preset names (:func:`choose_variants`): which policy is π_θold, how Â is
scoped, what the critic chases and how an optimisation is cut into steps."""

from __future__ import annotations

from collections.abc import Generator

import torch

from fleetrl.agent.config import PPOConfig
from fleetrl.agent.network import ActorCritic
from fleetrl.agent.update import (
    ACTOR,
    CRITIC,
    Advantages,
    Batch,
    Gradient,
    Minibatch,
    Model,
    Objective,
    Variants,
    Windows,
    gae,
    td_targets,
)

# ---- the paper's (``paper``, and ``paper-code`` where the authors' code does the same) -------------------


def round_start_policy(net: ActorCritic, head: torch.Tensor, memory: Batch) -> torch.Tensor:
    """π_θold = π_θ at line 11 (the paper)."""
    return net.log_probs_and_entropies(head, memory.actions)[0]


def window_advantages(
    net: ActorCritic, memory: Batch, values: torch.Tensor, cfg: PPOConfig, lengths: list[int]
) -> Advantages:
    """Eq. 2 inside each U-window (the paper: the sum runs to the window's end) with the current critic."""
    del net, values, lengths
    gamma, lam = cfg.gamma, cfg.gae_lambda

    def advantages(
        windows: Windows, v: torch.Tensor, v_next: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        w = windows.rows
        ends = memory.terminated[w], memory.episode_end[w]
        return gae(memory.rewards[w], v, v_next, *ends, gamma, lam, windows.lengths), v

    return advantages


def td_target(
    memory: Batch,
    w: slice | torch.Tensor,
    next_values: torch.Tensor,
    adv: torch.Tensor,
    values: torch.Tensor,
    gamma: float,
) -> torch.Tensor:
    """V^target = r_{t+1} + γ·V(s_{t+1}) (Eq. 3), bootstrapped at a truncation, not at a terminal state."""
    del adv, values
    return td_targets(memory.rewards[w], next_values, memory.terminated[w], gamma)


def critic_then_actor(
    model: Model, batch: Minibatch, objective: Objective
) -> Generator[Gradient, Gradient, Gradient]:
    """The authors' code, two steps of one Adam: the critic's gradient and step (lines 20-21), then π_θ again
    at the parameters that step left and the actor's gradient and step (22-23)."""
    g_mu = list(torch.autograd.grad(model.config.critic_coef * batch.critic_loss, model.critic))
    applied = yield model.with_extra_loss(g_mu, model.critic)
    model.step(CRITIC, applied)
    head, _ = model.net(batch.obs)
    g_theta = list(torch.autograd.grad(objective(batch, head), model.actor))
    applied = yield model.with_extra_loss(g_theta, model.actor)
    model.step(ACTOR, applied)
    return applied


# ---- the ``standard`` preset's ---------------------------------------------------------------------------


def behaviour_policy(net: ActorCritic, head: torch.Tensor, memory: Batch) -> torch.Tensor:
    """π_θold = the policy that acted (importance sampling)."""
    del net, head
    return memory.behaviour_log_probs


def memory_advantages(
    net: ActorCritic, memory: Batch, values: torch.Tensor, cfg: PPOConfig, lengths: list[int]
) -> Advantages:
    """Eq. 2 once over each unit's memory with the critic of line 11; a window takes its rows of Â and of
    V(s_t)."""
    next_values = net.value_of(memory.next_obs)
    gamma, lam = cfg.gamma, cfg.gae_lambda
    adv = gae(memory.rewards, values, next_values, memory.terminated, memory.episode_end, gamma, lam, lengths)
    return lambda windows, v, v_next: (adv[windows.rows], values[windows.rows])


def lambda_return(
    memory: Batch,
    w: slice | torch.Tensor,
    next_values: torch.Tensor,
    adv: torch.Tensor,
    values: torch.Tensor,
    gamma: float,
) -> torch.Tensor:
    """V^target = Â + V(s_t): the λ-return, from the values Â was measured against."""
    del memory, w, next_values, gamma
    return adv + values


def both_models_at_once(
    model: Model, batch: Minibatch, objective: Objective
) -> Generator[Gradient, Gradient, Gradient]:
    """Lines 19-23 as printed: g_θ (line 22) and g_μ (line 20) at the same parameters; μ's optimiser steps
    (line 21), then θ's (line 23)."""
    g_theta = list(torch.autograd.grad(objective(batch, batch.head), model.actor, retain_graph=True))
    g_mu = list(torch.autograd.grad(model.config.critic_coef * batch.critic_loss, model.critic))
    applied = yield model.with_extra_loss([*g_mu, *g_theta], model.critic + model.actor)
    model.step(CRITIC, applied[: len(model.critic)])
    model.step(ACTOR, applied[len(model.critic) :])
    return applied[len(model.critic) :]


def choose_variants(cfg: PPOConfig) -> Variants:
    """The functions ``cfg`` names, chosen once for the update."""
    sequential = cfg.optimisers == "one_sequential"
    return Variants(
        old_policy=round_start_policy if cfg.old_policy == "round_start" else behaviour_policy,
        advantages=window_advantages if cfg.gae_scope == "window" else memory_advantages,
        critic_target=td_target if cfg.critic_target == "td" else lambda_return,
        schedule=critic_then_actor if sequential else both_models_at_once,
        parts=((CRITIC,), (ACTOR,)) if sequential else ((CRITIC, ACTOR),),
        needs_next_values=cfg.gae_scope == "window" or cfg.critic_target == "td",
    )
