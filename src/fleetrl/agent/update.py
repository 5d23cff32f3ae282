"""One round's PPO update (Algorithm 2, lines 11-24), read top to bottom in :func:`ppo_update`.

The update is a generator: it yields each optimisation step's gradient and steps the optimisers with what is
sent back. A worker alone sends every gradient straight back (:func:`hand_back`: the same tensors, no copy);
a scheme that averages the fleet's gradients at every step sends back the fleet's average instead
(``PPOAgent.begin_update`` ... ``end_update`` drive it with flat vectors, the only place numpy enters).

The preset variants are small functions chosen once (:func:`choose_variants`): how Â is scoped, what the
critic chases, which policy is π_θold and how an optimisation is cut into steps. Those only the ``paper`` and
``paper-code`` presets use live in :mod:`fleetrl.agent.paper_variants`.
"""

from __future__ import annotations

from collections.abc import Callable, Generator
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
import torch
from torch import nn

from fleetrl.agent import paper_variants as paper
from fleetrl.agent.config import PPOConfig
from fleetrl.agent.losses import clipped_surrogate, critic_loss, gae
from fleetrl.agent.memory import Transitions, sample_window
from fleetrl.agent.network import ActorCritic

CRITIC = "critic"
"""the part of a step that moves μ (lines 20-21)"""
ACTOR = "actor"
"""the part of a step that moves θ (lines 22-23)"""

Gradient = list[torch.Tensor]
"""one optimisation step's gradient: a tensor per parameter the step moves, critic part first (its layout is
``PPOAgent.step_layout``)"""
ExtraLoss = Callable[[nn.Module], torch.Tensor]
"""a scalar added to each minibatch's loss (FedProx's μ/2·‖θ − θ_global‖², say), given the network"""


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


@dataclass(frozen=True)
class Finished:
    """What an update returns: its statistics and line 25's gradient (the last actor gradient applied)."""

    stats: UpdateStats
    actor_gradient: Gradient


T = TypeVar("T")
UpdateSteps = Generator[Gradient, Gradient, Finished]
"""an update under way: yields a step's gradient, is sent the gradient to apply, returns :class:`Finished`"""


def ppo_update(model: Model, data: Transitions, window_rng: np.random.Generator) -> UpdateSteps:
    """Algorithm 2, lines 11-24: K optimisations of the actor and the critic on windows of the memory
    ``data``; ``window_rng`` draws the K window starts (line 13), all of them at line 11, in order."""
    cfg, net, memory, variants = model.config, model.net, Batch.of(data), model.variants
    # Line 11: π_θold ← π_θ. Its log-probabilities of the stored actions (or the acting policy's, standard
    # PPO), and V_μ(s) of the whole memory as the round begins.
    with torch.no_grad():
        head, values = net(memory.obs)
        old_log_probs = variants.old_policy(net, head, memory)
        advantages = variants.advantages(net, memory, values, cfg)  # Eq. 2 now, or on each window
    # Line 13, K times: a contiguous window of U transitions from a random start (Figure 3).
    windows = [sample_window(len(data), cfg.batch_size, window_rng) for _ in range(cfg.n_optimisations)]
    totals = np.zeros(5)  # actor loss, critic loss, entropy, approx KL, clip fraction

    def actor_objective(batch: Minibatch, head: torch.Tensor) -> torch.Tensor:
        """Line 18: −L^CLIP (Eq. 6) − β·H, what the actor descends (Eq. 7); R_t = π_θ / π_θold (Eq. 5)."""
        w = batch.window
        log_probs, entropy = net.log_probs_and_entropy(head, memory.actions[w])
        l_clip = clipped_surrogate(log_probs, old_log_probs[w], batch.advantages, cfg.clip_eps)
        with torch.no_grad():
            log_ratio = log_probs - old_log_probs[w]
            ratio = log_ratio.exp()
            kl = ((ratio - 1.0) - log_ratio).mean()
            clipped = ((ratio - 1.0).abs() > cfg.clip_eps).float().mean()
        totals[[0, 2, 3, 4]] += [-l_clip.item(), entropy.item(), kl.item(), clipped.item()]
        return -l_clip - cfg.entropy_coef * entropy

    actor_gradient: Gradient = []
    for start, stop in windows:  # line 12: for k = 1 … K
        w = slice(start, stop)
        head, v = net(memory.obs[w])  # line 14: π_θ(·|s_t) and V_μ(s_t)
        v_next = next_values(model, memory.next_obs[w])
        adv, baseline = advantages(w, v.detach(), v_next)  # line 15: Â_t (Eq. 2)
        # line 16: V^target (Eq. 3: r + γV(s'); or the λ-return Â + V)
        targets = variants.critic_target(memory, w, v_next, adv, baseline, cfg.gamma)
        if cfg.normalise_advantages and adv.numel() > 1:
            adv = (adv - adv.mean()) / (adv.std() + 1e-8)
        l_v = critic_loss(v, targets, cfg.critic_loss)  # line 17: L^V (Eq. 3)
        totals[1] += l_v.item()
        # Lines 19-23: the gradients and the optimisers' steps (one step, or the critic's then the actor's).
        batch = Minibatch(w, memory.obs[w], head, adv, l_v)
        actor_gradient = yield from variants.schedule(model, batch, actor_objective)
    means = totals / cfg.n_optimisations
    return Finished(UpdateStats(*(float(m) for m in means)), actor_gradient)


@dataclass
class Model:
    """What an update trains: the network, its two parameter groups and their Adam optimisers."""

    net: ActorCritic
    actor: list[nn.Parameter]
    """θ: the trunk and the actor head (what the federation shares)"""
    critic: list[nn.Parameter]
    """μ: what the critic's optimiser steps (the value head, and the trunk with ``trunk_split='shared'``)"""
    critic_grad: list[nn.Parameter]
    """what L^V is differentiated against: the trunk and the value head (both splits)"""
    n_trunk: int
    """how many of ``critic_grad`` are the trunk's"""
    actor_optimiser: torch.optim.Optimizer
    critic_optimiser: torch.optim.Optimizer
    """the same Adam as ``actor_optimiser`` with ``optimisers='one_sequential'``"""
    config: PPOConfig
    variants: Variants
    """the functions ``config`` names (:func:`choose_variants`)"""
    extra_loss: ExtraLoss | None = None
    """added to each minibatch's loss (``PPOAgent.set_extra_loss``)"""

    def step(self, part: str, gradient: Gradient) -> None:
        """Lines 21 / 23: one optimiser's step with ``gradient`` over its parameters (clipped in place to
        ``max_grad_norm`` first, if set)."""
        params, optimiser = (
            (self.actor, self.actor_optimiser) if part == ACTOR else (self.critic, self.critic_optimiser)
        )
        for p, g in zip(params, gradient, strict=True):
            p.grad = g
        if self.config.max_grad_norm > 0.0:
            nn.utils.clip_grad_norm_(params, self.config.max_grad_norm)  # in place: ``gradient`` sees it too
        optimiser.step()
        for p in params:
            p.grad = None

    def with_extra_loss(self, gradient: Gradient, params: list[nn.Parameter]) -> Gradient:
        """``gradient`` over ``params`` plus the gradient of :attr:`extra_loss` (unchanged without one)."""
        if self.extra_loss is None:
            return gradient
        unique = list({id(p): p for p in params}.values())
        extra = torch.autograd.grad(self.extra_loss(self.net), unique, allow_unused=True)
        by_id = {id(p): e for p, e in zip(unique, extra, strict=True)}
        return [
            g if by_id[id(p)] is None else g + by_id[id(p)] for g, p in zip(gradient, params, strict=True)
        ]


@dataclass(frozen=True)
class Batch:
    """The trajectory memory as tensors (no copy), and the window an optimisation takes from it."""

    obs: torch.Tensor
    actions: torch.Tensor
    rewards: torch.Tensor
    next_obs: torch.Tensor
    terminated: torch.Tensor
    episode_end: torch.Tensor
    behaviour_log_probs: torch.Tensor

    @classmethod
    def of(cls, data: Transitions) -> Batch:
        """The memory's transitions as tensors sharing their arrays."""
        return cls(*(torch.from_numpy(a) for a in (
            data.obs, data.actions, data.rewards, data.next_obs, data.terminated, data.episode_end,
            data.behaviour_log_probs,
        )))  # fmt: skip


@dataclass
class Minibatch:
    """One optimisation's window j and what lines 14-17 computed on it."""

    window: slice
    obs: torch.Tensor
    """s_t on the window"""
    head: torch.Tensor
    """the actor head's output on the window (logits, or the Gaussian mean in units of the box)"""
    advantages: torch.Tensor
    critic_loss: torch.Tensor


Advantages = Callable[[slice, torch.Tensor, torch.Tensor], tuple[torch.Tensor, torch.Tensor]]
"""(window, V(s_t), V(s_{t+1}) at the current critic) → (Â on the window, the V(s_t) Â was measured from)"""
CriticTarget = Callable[[Batch, slice, torch.Tensor, torch.Tensor, torch.Tensor, float], torch.Tensor]
"""(memory, window, V(s_{t+1}), Â, the V(s_t) of Â, γ) → V^target on the window"""
Objective = Callable[[Minibatch, torch.Tensor], torch.Tensor]
"""(window, actor head output) → the actor's objective, −L^CLIP − β·H"""
Schedule = Callable[[Model, Minibatch, Objective], Generator[Gradient, Gradient, Gradient]]
"""how an optimisation is cut into steps; returns the actor gradient it applied"""


@dataclass(frozen=True)
class Variants:
    """The preset's choices, made once."""

    old_policy: Callable[[ActorCritic, torch.Tensor, Batch], torch.Tensor]
    advantages: Callable[[ActorCritic, Batch, torch.Tensor, PPOConfig], Advantages]
    critic_target: CriticTarget
    schedule: Schedule
    parts: tuple[tuple[str, ...], ...]
    """what each step of an optimisation moves, in the order its optimisers step"""
    needs_next_values: bool
    """whether a window's V(s_{t+1}) enters its advantages or critic target (Eq. 2 on each window, Eq. 3's
    TD target); otherwise it is not computed (no gradient flows through it, so skipping it changes nothing)"""


def hand_back(steps: Generator[Gradient, Gradient, T]) -> T:
    """Run an update alone: every step applies its own gradient, the very tensors it yielded."""
    try:
        gradient = next(steps)
        while True:
            gradient = steps.send(gradient)
    except StopIteration as done:
        result: T = done.value
        return result


class StepExchange:
    """An update driven one step at a time from outside (a fleet's step averages): :attr:`gradient` is the
    step's gradient awaiting what to apply, :meth:`send` applies it and takes the next, :attr:`stats` is set
    once the last step was applied.

    :param steps: the update (``PPOAgent.update_steps``); its first step is computed here
    """

    def __init__(self, steps: Generator[Gradient, Gradient, UpdateStats]) -> None:
        self._steps = steps
        self.step = 0
        """the index of the step whose gradient is :attr:`gradient`"""
        self.taken = False
        """the step's gradient was handed out and awaits :meth:`send`"""
        self.stats: UpdateStats | None = None
        self.gradient: Gradient | None = None
        self._advance(lambda: next(steps))

    def send(self, applied: Gradient) -> None:
        """Apply ``applied`` for the current step and compute the next step's gradient (or finish)."""
        self._advance(lambda: self._steps.send(applied))
        self.step += 1

    def abandon(self) -> None:
        """Stop the update before its last step: the steps applied stay, nothing after them runs."""
        self._steps.close()
        self.gradient, self.taken = None, False

    def _advance(self, resume: Callable[[], Gradient]) -> None:
        self.taken = False
        try:
            self.gradient = resume()
        except StopIteration as done:
            self.gradient, self.stats = None, done.value


# ---- the variants the ``standard`` preset uses (the paper's: fleetrl.agent.paper_variants) ----------------


def behaviour_policy(net: ActorCritic, head: torch.Tensor, memory: Batch) -> torch.Tensor:
    """π_θold = the policy that acted: log π of each stored action as it was drawn (importance sampling)."""
    del net, head
    return memory.behaviour_log_probs


def memory_advantages(net: ActorCritic, memory: Batch, values: torch.Tensor, cfg: PPOConfig) -> Advantages:
    """Eq. 2 once over the whole memory with the critic of line 11; a window takes its slice, and V(s_t) of
    line 11 with it (the λ-return target Â + V is then fixed for the round like Â)."""
    next_values = net.value_of(memory.next_obs)
    gamma, lam = cfg.gamma, cfg.gae_lambda
    adv = gae(memory.rewards, values, next_values, memory.terminated, memory.episode_end, gamma, lam)
    return lambda w, v, v_next: (adv[w], values[w])


def lambda_return(
    memory: Batch, w: slice, next_values: torch.Tensor, adv: torch.Tensor, values: torch.Tensor, gamma: float
) -> torch.Tensor:
    """V^target = Â + V(s_t): the λ-return, from the values Â was measured against."""
    del memory, w, next_values, gamma
    return adv + values


def both_models_at_once(
    model: Model, batch: Minibatch, objective: Objective
) -> Generator[Gradient, Gradient, Gradient]:
    """Lines 19-23 as printed: g_θ (line 22) and g_μ (line 20) at the same parameters, one step; μ's
    optimiser steps (line 21), then θ's (line 23).

    With ``trunk_split='actor'`` the critic loss's trunk gradient, times ``critic_trunk_coef``, joins g_θ, so
    the actor's optimiser alone moves the trunk and the shared gradient carries the critic's say."""
    cfg, n = model.config, model.n_trunk
    g_theta = list(torch.autograd.grad(objective(batch, batch.head), model.actor, retain_graph=True))
    g_v = list(torch.autograd.grad(cfg.critic_coef * batch.critic_loss, model.critic_grad))
    if cfg.trunk_split == "shared":  # the trunk is in μ too: each optimiser steps it with its own loss
        g_mu = g_v
    else:
        g_mu = g_v[n:]
        for i, g in enumerate(g_v[:n]):
            g_theta[i] = g_theta[i] + cfg.critic_trunk_coef * g
    params = model.critic + model.actor
    applied = yield model.with_extra_loss([*g_mu, *g_theta], params)
    model.step(CRITIC, applied[: len(model.critic)])
    model.step(ACTOR, applied[len(model.critic) :])
    return applied[len(model.critic) :]


def choose_variants(cfg: PPOConfig) -> Variants:
    """The functions ``cfg`` names, chosen once for the update."""
    sequential = cfg.optimisers == "one_sequential"
    return Variants(
        old_policy=paper.round_start_policy if cfg.old_policy == "round_start" else behaviour_policy,
        advantages=paper.window_advantages if cfg.gae_scope == "window" else memory_advantages,
        critic_target=paper.td_target if cfg.critic_target == "td" else lambda_return,
        schedule=paper.critic_then_actor if sequential else both_models_at_once,
        parts=((CRITIC,), (ACTOR,)) if sequential else ((CRITIC, ACTOR),),
        needs_next_values=cfg.gae_scope == "window" or cfg.critic_target == "td",
    )


def next_values(model: Model, next_obs: torch.Tensor) -> torch.Tensor:
    """V_μ(s_{t+1}) of a window's next states, without gradient; an empty tensor where the preset's
    advantages and critic target do not read it."""
    if not model.variants.needs_next_values:
        return next_obs.new_empty(0)
    with torch.no_grad():
        return model.net.value_of(next_obs)
