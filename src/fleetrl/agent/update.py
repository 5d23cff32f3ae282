"""The paper's losses (Eqs. 2, 3, 6) and one round's PPO update (Algorithm 2, lines 11-24) for U ≥ 1 units
of one policy, :func:`ppo_update`: a generator that yields each step's gradient and steps the optimisers with
what is sent back (:func:`hand_back`: its own; :class:`StepExchange`, a per-step scheme's: the fleet's)."""

from __future__ import annotations

from collections.abc import Callable, Generator, Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
import torch
from torch import nn
from torch.nn import functional

from fleetrl.agent.config import PPOConfig
from fleetrl.agent.memory import Batch, Transitions, Windows, concatenate, sample_window
from fleetrl.agent.network import ActorCritic
from fleetrl.agent.optimisers import Named, flatten_tensors, split, step_optimiser

CRITIC = "critic"  # the part of a step that moves μ (lines 20-21)
ACTOR = "actor"  # the part of a step that moves θ (lines 22-23)

Gradient = list[torch.Tensor]
"""one step's gradient: a tensor per parameter the step moves, critic part first"""
ExtraLoss = Callable[[nn.Module], torch.Tensor]
"""a scalar added to each minibatch's loss (FedProx's μ/2·‖θ − θ_global‖²), given the network"""


def td_targets(
    rewards: torch.Tensor, next_values: torch.Tensor, terminated: torch.Tensor, gamma: float
) -> torch.Tensor:
    """V^target(s_t) = r_{t+1} + γ·V(s_{t+1}) (Eq. 3), no bootstrap where s_{t+1} is terminal (a truncation
    bootstraps)."""
    return rewards + gamma * (1.0 - terminated) * next_values


def gae(
    rewards: torch.Tensor,
    values: torch.Tensor,
    next_values: torch.Tensor,
    terminated: torch.Tensor,
    episode_end: torch.Tensor,
    gamma: float,
    gae_lambda: float,
    lengths: Sequence[int] | None = None,
) -> torch.Tensor:
    """Generalised advantage estimates (Eq. 2), detached: δ_t = r_{t+1} + γ·V(s_{t+1})·(1 − terminated_t)
    − V(s_t) and Â_t = δ_t + (γλ)·Â_{t+1}, stopping at an episode's end and at the end of its run: one run
    (``lengths`` None) or runs of ``lengths`` one after the other, side by side in float64 arithmetic."""
    with torch.no_grad():
        deltas = (td_targets(rewards, next_values, terminated, gamma) - values).numpy()
        carry = gamma * gae_lambda * (1.0 - episode_end.numpy())
    if lengths is None or len(lengths) == 1:
        advantages = np.zeros_like(deltas)
        running = 0.0
        for t in range(deltas.shape[0] - 1, -1, -1):  # plain floats: ~30x faster than torch scalars
            running = float(deltas[t]) + float(carry[t]) * running
            advantages[t] = running
        return torch.from_numpy(advantages)
    # one row per run, a shorter run padded with zeros after its end (they leave the sum at 0)
    offsets = np.concatenate([[0], np.cumsum(lengths)])
    longest = int(max(lengths))
    delta_rows, carry_rows = np.zeros((len(lengths), longest)), np.zeros((len(lengths), longest))
    for u, (start, n) in enumerate(zip(offsets[:-1], lengths, strict=True)):
        delta_rows[u, :n] = deltas[start : start + n]
        carry_rows[u, :n] = carry[start : start + n]
    rows = np.zeros((len(lengths), longest))
    running_rows = np.zeros(len(lengths))
    for t in range(longest - 1, -1, -1):
        running_rows = delta_rows[:, t] + carry_rows[:, t] * running_rows
        rows[:, t] = running_rows
    return torch.from_numpy(np.concatenate([rows[u, :n] for u, n in enumerate(lengths)]).astype(np.float32))


def critic_loss(
    values: torch.Tensor, targets: torch.Tensor, kind: str = "abs", dim: int | None = None
) -> torch.Tensor:
    """L^V(μ) = Ê[|V^target(s_t) − V_μ(s_t)|] (Eq. 3), or for ``huber`` the smooth L1 loss of the authors'
    code; no gradient through the targets. Ê: over every element, or over ``dim`` only (one per unit)."""
    error = targets.detach() - values
    if kind == "abs":
        return error.abs().mean() if dim is None else error.abs().mean(dim)
    if kind == "huber":
        if dim is None:
            return functional.smooth_l1_loss(values, targets.detach(), beta=1.0)
        return functional.smooth_l1_loss(values, targets.detach(), beta=1.0, reduction="none").mean(dim)
    raise ValueError(f"unknown critic loss {kind!r} (choose abs or huber)")


def clipped_surrogate(
    log_probs: torch.Tensor,
    old_log_probs: torch.Tensor,
    advantages: torch.Tensor,
    clip_eps: float,
    dim: int | None = None,
) -> torch.Tensor:
    """L^CLIP(θ) = Ê[min(R_t·Â_t, clip(R_t, 1 − ε, 1 + ε)·Â_t)] (Eq. 6; Schulman et al.'s form, the products
    inside the min), R_t = π_θ / π_θold (Eq. 5), to maximise. Ê as in :func:`critic_loss`."""
    ratio = torch.exp(log_probs - old_log_probs.detach())
    unclipped = ratio * advantages
    clipped = torch.clamp(ratio, 1.0 - clip_eps, 1.0 + clip_eps) * advantages
    surrogate = torch.min(unclipped, clipped)
    return surrogate.mean() if dim is None else surrogate.mean(dim)


@dataclass(frozen=True)
class UpdateStats:
    """What one round's update did, averaged over its K optimisations: −L^CLIP (Eq. 6, no entropy bonus),
    L^V (Eq. 3, unweighted), π_θ's mean entropy, Ê[(R − 1) − log R] ≈ KL(π_θold ‖ π_θ), and the share of
    ratios R_t outside [1 − ε, 1 + ε]."""

    actor_loss: float
    critic_loss: float
    entropy: float
    approx_kl: float
    clip_fraction: float


@dataclass(frozen=True)
class Finished:
    """What an update returns: the units' mean statistics, each unit's, and line 25's gradient."""

    stats: UpdateStats
    unit_stats: tuple[UpdateStats, ...]
    actor_gradient: Gradient


ACTOR_TOTALS = np.array([0, 2, 3, 4])  # the columns of the per-unit totals the actor fills (critic: 1)
T = TypeVar("T")


def ppo_update(
    model: Model, memories: Sequence[Transitions], window_rngs: Sequence[np.random.Generator]
) -> Generator[Gradient, Gradient, Finished]:
    """Algorithm 2, lines 11-24: K optimisations on windows of each unit's memory (each non-empty); unit u
    draws its K window starts from ``window_rngs[u]`` (line 13), all of them at line 11."""
    cfg, net = model.config, model.net
    lengths = [len(m) for m in memories]
    offsets = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
    memory, units = Batch.of(concatenate(memories)), len(lengths)
    # Line 11: π_θold ← π_θ, and V_μ(s) of every memory as the round begins.
    with torch.no_grad():
        head, values = net(memory.obs)
        if cfg.old_policy == "round_start":  # the paper: log π_θ of the stored actions at line 11
            old_log_probs = net.log_probs_and_entropies(head, memory.actions)[0]
        else:  # "behaviour": the policy that acted (standard PPO's importance sampling)
            old_log_probs = memory.behaviour_log_probs
        if cfg.gae_scope == "memory":  # Eq. 2 once over each unit's memory, with the critic of line 11
            next_values = net.value_of(memory.next_obs)
            ends = memory.terminated, memory.episode_end
            memory_adv = gae(memory.rewards, values, next_values, *ends, cfg.gamma, cfg.gae_lambda, lengths)
    # Line 13, K times for each unit: a contiguous window of U transitions from a random start (Figure 3).
    spans = [[sample_window(n, cfg.batch_size, rng) for _ in range(cfg.n_optimisations)]
             for n, rng in zip(lengths, window_rngs, strict=True)]  # fmt: skip
    totals = np.zeros((units, 5))  # per unit: actor loss, critic loss, entropy, approx KL, clip fraction
    schedule = critic_then_actor if cfg.optimisers == "one_sequential" else both_models_at_once

    def actor_objective(batch: Minibatch, head: torch.Tensor) -> torch.Tensor:
        """Line 18: the units' mean of −L^CLIP (Eq. 6) − β·H on each window; R_t = π_θ / π_θold (Eq. 5)."""
        rows = batch.windows.rows
        log_probs, entropies = net.log_probs_and_entropies(head, memory.actions[rows])
        objective = torch.zeros(())
        for group, part, shape in batch.windows.parts():
            new, old = log_probs[part].reshape(shape), old_log_probs[rows][part].reshape(shape)
            l_clip = clipped_surrogate(new, old, batch.advantages[part].reshape(shape), cfg.clip_eps, dim=1)
            entropy = (
                entropies[part].reshape(shape).mean(1) if entropies.dim() else entropies.expand(shape[0])
            )
            objective = objective + (-l_clip - cfg.entropy_coef * entropy).sum()
            with torch.no_grad():
                log_ratio = new - old
                ratio = log_ratio.exp()
                kl = ((ratio - 1.0) - log_ratio).mean(1)
                clipped = ((ratio - 1.0).abs() > cfg.clip_eps).float().mean(1)
                totals[np.ix_(group, ACTOR_TOTALS)] += torch.stack([-l_clip, entropy, kl, clipped], 1).numpy()
        return objective / units

    actor_gradient: Gradient = []
    for k in range(cfg.n_optimisations):  # line 12: for k = 1 … K
        windows = Windows.of(offsets, [unit_spans[k] for unit_spans in spans])
        rows = windows.rows
        head, v = net(memory.obs[rows])  # line 14: π_θ(·|s_t) and V_μ(s_t), every unit's window at once
        v_next = memory.next_obs.new_empty(0)  # V_μ(s_{t+1}), where Eq. 2 or 3 reads it
        if cfg.gae_scope == "window" or cfg.critic_target == "td":
            with torch.no_grad():
                v_next = net.value_of(memory.next_obs[rows])
        # line 15: Â_t (Eq. 2) inside each window with the current critic (the paper), or the memory's
        if cfg.gae_scope == "window":
            ends = memory.terminated[rows], memory.episode_end[rows]
            baseline = v.detach()
            adv = gae(
                memory.rewards[rows], baseline, v_next, *ends, cfg.gamma, cfg.gae_lambda, windows.lengths
            )
        else:
            adv, baseline = memory_adv[rows], values[rows]
        # line 16: V^target = r + γV(s') (Eq. 3), or the λ-return Â + V(s) from the V(s) of Â
        if cfg.critic_target == "td":
            targets = td_targets(memory.rewards[rows], v_next, memory.terminated[rows], cfg.gamma)
        else:
            targets = adv + baseline
        value_loss, scaled = torch.zeros(()), []
        for group, part, shape in windows.parts():
            l_v = critic_loss(v[part].reshape(shape), targets[part].reshape(shape), cfg.critic_loss, dim=1)
            value_loss = value_loss + l_v.sum()  # line 17: L^V (Eq. 3) of each unit
            totals[group, 1] += l_v.detach().numpy()
            unit_adv = adv[part].reshape(shape)
            if cfg.normalise_advantages and shape[1] > 1:  # per unit's window, as a unit alone does
                unit_adv = (unit_adv - unit_adv.mean(1, keepdim=True)) / (
                    unit_adv.std(1, keepdim=True) + 1e-8
                )
            scaled.append(unit_adv.reshape(-1))
        # Lines 19-23: the gradients and the optimisers' steps (one step, or the critic's then the actor's).
        batch = Minibatch(windows, memory.obs[rows], head, torch.cat(scaled), value_loss / units)
        actor_gradient = yield from schedule(model, batch, actor_objective)
    means = totals / cfg.n_optimisations
    unit_stats = tuple(UpdateStats(*(float(x) for x in row)) for row in means)
    return Finished(UpdateStats(*(float(x) for x in means.mean(0))), unit_stats, actor_gradient)


def both_models_at_once(
    model: Model, batch: Minibatch, objective: Objective
) -> Generator[Gradient, Gradient, Gradient]:
    """Lines 19-23 as printed: g_θ (line 22) and g_μ (line 20) at the same parameters; μ's optimiser steps
    (line 21), then θ's (line 23). Returns the actor gradient applied."""
    g_theta = list(torch.autograd.grad(objective(batch, batch.head), model.actor, retain_graph=True))
    g_mu = list(torch.autograd.grad(model.config.critic_coef * batch.critic_loss, model.critic))
    applied = yield model.with_extra_loss([*g_mu, *g_theta], model.critic + model.actor)
    model.step(CRITIC, applied[: len(model.critic)])
    model.step(ACTOR, applied[len(model.critic) :])
    return applied[len(model.critic) :]


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


def step_parts(cfg: PPOConfig) -> tuple[tuple[str, ...], ...]:
    """What each step of an optimisation moves, in the order its optimisers step."""
    return ((CRITIC,), (ACTOR,)) if cfg.optimisers == "one_sequential" else ((CRITIC, ACTOR),)


@dataclass
class Model:
    """What an update trains: the network, θ (trunk + actor head) and μ (trunk + value head) with their
    Adam optimisers (one Adam twice with ``one_sequential``)."""

    net: ActorCritic
    actor: list[nn.Parameter]
    critic: list[nn.Parameter]
    actor_optimiser: torch.optim.Optimizer
    critic_optimiser: torch.optim.Optimizer
    config: PPOConfig
    extra_loss: ExtraLoss | None = None

    def step(self, part: str, gradient: Gradient) -> None:
        """Lines 21 / 23: one optimiser's step with ``gradient`` (of the shared parameters alone: the unit's
        own offsets stay)."""
        params, optimiser = (
            (self.actor, self.actor_optimiser) if part == ACTOR else (self.critic, self.critic_optimiser)
        )
        if len(gradient) > len(params):
            raise ValueError(f"{len(gradient)} gradient tensors for {len(params)} parameters")
        for p, g in zip(params, gradient, strict=False):
            p.grad = g
        step_optimiser(optimiser)
        for p in params:
            p.grad = None

    def with_extra_loss(self, gradient: Gradient, params: list[nn.Parameter]) -> Gradient:
        """``gradient`` over ``params`` plus the gradient of :attr:`extra_loss`, if any."""
        if self.extra_loss is None:
            return gradient
        unique = list({id(p): p for p in params}.values())
        extra = torch.autograd.grad(self.extra_loss(self.net), unique, allow_unused=True)
        by_id = {id(p): e for p, e in zip(unique, extra, strict=True)}
        return [
            g if by_id[id(p)] is None else g + by_id[id(p)] for g, p in zip(gradient, params, strict=True)
        ]


@dataclass
class Minibatch:
    """One optimisation's windows and what lines 14-17 computed on them: s_t, the actor head's output, Â_t
    and the units' mean L^V."""

    windows: Windows
    obs: torch.Tensor
    head: torch.Tensor
    advantages: torch.Tensor
    critic_loss: torch.Tensor


Objective = Callable[[Minibatch, torch.Tensor], torch.Tensor]
"""(windows, actor head output) → the actor's objective, −L^CLIP − β·H"""


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
    """The update ``steps`` under way: :meth:`gradient_of` hands out a step's gradient, :meth:`apply` applies
    what the fleet sends back and computes the next.

    :param parts: the parts step k moves, in its gradient's order: each part's shared parameters (what the
        flat vector holds) and how many of the unit's own offsets follow them (their gradient stays here)
    """

    def __init__(
        self,
        steps: Generator[Gradient, Gradient, UpdateStats],
        parts: Callable[[int], list[tuple[Named, int]]],
        count: int,
    ) -> None:
        self._steps, self._parts, self.count = steps, parts, count
        self.step = 0  # the index of the step whose gradient is :attr:`gradient`
        self.taken = False  # the step's gradient was handed out and awaits :meth:`apply`
        self.stats: UpdateStats | None = None
        self.gradient: Gradient | None = None
        self._advance(lambda: next(steps))

    def gradient_of(self, k: int) -> np.ndarray:
        """Step ``k``'s gradient, flat float32; RuntimeError if it is not the step next."""
        if self.taken:
            raise RuntimeError(f"step {self.step}'s gradient is not applied yet: call apply_step()")
        if self.gradient is None or k != self.step:
            raise RuntimeError(f"step {k} requested, but step {self.step} of {self.count} is next")
        self.taken = True
        return flatten_tensors([g for shared, _ in self._pieces(self.gradient) for g in shared])

    def apply(self, flat: np.ndarray) -> None:
        """Apply ``flat`` for the step handed out and compute the next step's gradient (or finish)."""
        if not self.taken:
            raise RuntimeError("no step gradient to apply: call step_gradients(k) first")
        named = [item for shared, _ in self._parts(self.step) for item in shared]
        fleet = iter(split(flat, named, "step gradient"))
        assert self.gradient is not None
        applied = [
            g for shared, own in self._pieces(self.gradient) for g in [next(fleet) for _ in shared] + own
        ]
        self._advance(lambda: self._steps.send(applied))
        self.step += 1

    def finished(self) -> UpdateStats:
        """The update's statistics; RuntimeError if a step was not applied."""
        if self.stats is None:
            raise RuntimeError(f"end_update() after {self.step} of {self.count} steps")
        return self.stats

    def abandon(self) -> None:
        """Stop the update before its last step: the steps applied stay, nothing after them runs."""
        self._steps.close()
        self.gradient, self.taken = None, False

    def _pieces(self, gradient: Gradient) -> list[tuple[Gradient, Gradient]]:
        pieces, at = [], 0
        for shared, own in self._parts(self.step):
            pieces.append(
                (gradient[at : at + len(shared)], gradient[at + len(shared) : at + len(shared) + own])
            )
            at += len(shared) + own
        return pieces

    def _advance(self, resume: Callable[[], Gradient]) -> None:
        self.taken = False
        try:
            self.gradient = resume()
        except StopIteration as done:
            self.gradient, self.stats = None, done.value
