"""One update of a unit host: Algorithm 2, lines 11-24, for U units of one policy at once.

A unit host's units share one network and one optimiser state (the fleet is one policy), but each keeps its
own trajectory memory and window draws. Every optimisation step k takes unit u's window exactly as a worker
of that one unit would (its own memory, GAE over its own memory, its own ``window_rng``), and the host's
loss is the mean over its units of each unit's minibatch loss::

    L_host = (1/U) Σ_u L_u(w_u)     so     ∇L_host = (1/U) Σ_u ∇L_u(w_u) = (1/U) Σ_u g_u

where L_u is what :func:`fleetrl.agent.update.ppo_update` differentiates for that unit alone: −L^CLIP − β·H
and L^V as means over the unit's window, with Â standardised over the unit's window (per minibatch, as a
worker does). One forward pass over the concatenated windows and one backward pass give the host's gradient.
With U units per message and the chief weighing answers by their ``units`` (the mean rule), a fleet of hosts
takes the same step as the flat fleet of its units: Σ_h U_h·ḡ_h / Σ_h U_h = (1/N) Σ_i g_i. With weights w_u
per unit (a scheme that weighs units by need) the loss is the weighted mean, Σ_u w_u L_u / Σ_u w_u, and the
host's message weighs Σ_u w_u: again the flat fleet's weighted step.

What a host does not reproduce: a robust aggregation rule (median, trimmed mean) then sees one vector per
host, not per unit, and ``gae_scope='window'`` (the paper's per-window GAE) is not supported (the host
computes Â per unit memory, ``gae_scope='memory'``).
"""

from __future__ import annotations

from collections.abc import Generator, Sequence
from dataclasses import dataclass

import numpy as np
import torch

from fleetrl.agent.config import PPOConfig, host_config_problem
from fleetrl.agent.losses import clipped_surrogate, critic_loss, td_targets
from fleetrl.agent.memory import Transitions, sample_window
from fleetrl.agent.update import (
    Batch,
    Gradient,
    Minibatch,
    Model,
    Objective,
    UpdateStats,
    both_models_at_once,
    next_values,
)


@dataclass(frozen=True)
class HostFinished:
    """What a host's update returns: the statistics of each unit and of the host, line 25's gradient."""

    unit_stats: tuple[UpdateStats, ...]
    """each unit's statistics, averaged over the K optimisations (its own window's losses)"""
    stats: UpdateStats
    """the mean of the units' statistics"""
    actor_gradient: Gradient


def concatenate(memories: Sequence[Transitions]) -> Transitions:
    """The units' memories one after the other (unit 0's first)."""
    if len(memories) == 1:
        return memories[0]
    fields = ("obs", "actions", "rewards", "next_obs", "terminated", "episode_end", "behaviour_log_probs")
    arrays = [np.concatenate([getattr(m, name) for m in memories]) for name in fields]
    return Transitions(*arrays)


def unit_advantages(
    memory: Batch, values: torch.Tensor, next_values: torch.Tensor, offsets: np.ndarray, cfg: PPOConfig
) -> torch.Tensor:
    """Eq. 2 over each unit's memory (the segment ``offsets[u]:offsets[u+1]`` of the concatenation), the U
    recursions run side by side: the same float64 arithmetic as :func:`fleetrl.agent.losses.gae` on each
    unit's memory alone (a shorter memory is padded with zeros after its end, which leave the sum at 0)."""
    with torch.no_grad():
        deltas = (td_targets(memory.rewards, next_values, memory.terminated, cfg.gamma) - values).numpy()
        carry = cfg.gamma * cfg.gae_lambda * (1.0 - memory.episode_end.numpy())
    lengths = np.diff(offsets)
    units, longest = lengths.shape[0], int(lengths.max())
    delta_rows = np.zeros((units, longest))
    carry_rows = np.zeros((units, longest))
    for u, (start, n) in enumerate(zip(offsets[:-1], lengths, strict=True)):
        delta_rows[u, :n] = deltas[start : start + n]
        carry_rows[u, :n] = carry[start : start + n]
    rows = np.zeros((units, longest))
    running = np.zeros(units)
    for t in range(longest - 1, -1, -1):
        running = delta_rows[:, t] + carry_rows[:, t] * running
        rows[:, t] = running
    advantages = np.concatenate([rows[u, :n] for u, n in enumerate(lengths)]).astype(np.float32)
    return torch.from_numpy(advantages)


HostSteps = Generator[Gradient, Gradient, HostFinished]
"""a host's update under way: yields a step's gradient, is sent the gradient to apply, returns
:class:`HostFinished`"""


def host_update(
    model: Model,
    memories: Sequence[Transitions],
    window_rngs: Sequence[np.random.Generator],
    weights: np.ndarray | None = None,
) -> HostSteps:
    """Lines 11-24 for the units whose memories are ``memories`` (each non-empty), unit u drawing its K
    window starts from ``window_rngs[u]`` as a worker of that unit alone does; each step yields the host's
    gradient (the mean of the units' minibatch gradients, weighted by ``weights`` if given: one positive
    number per unit) and applies what is sent back.

    :raises ValueError: ``model.config`` is not one a host can update (:func:`host_config_problem`)
    """
    cfg, net, variants = model.config, model.net, model.variants
    problem = host_config_problem(cfg)
    if problem is not None:
        raise ValueError(problem)
    lengths = [len(m) for m in memories]
    offsets = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
    memory = Batch.of(concatenate(memories))
    with torch.no_grad():  # line 11: π_θold, V_μ of every unit's memory, and Â per unit (Eq. 2)
        head, values = net(memory.obs)
        old_log_probs = variants.old_policy(net, head, memory)
        advantages = unit_advantages(memory, values, net.value_of(memory.next_obs), offsets, cfg)
    windows = [
        [sample_window(n, cfg.batch_size, rng) for _ in range(cfg.n_optimisations)]
        for n, rng in zip(lengths, window_rngs, strict=True)
    ]
    units = len(lengths)
    unit_weights = None if weights is None else torch.as_tensor(weights, dtype=torch.float32)
    total_weight = units if unit_weights is None else unit_weights.sum()
    totals = np.zeros((units, 5))  # per unit: actor loss, critic loss, entropy, approx KL, clip fraction
    actor_gradient: Gradient = []
    for k in range(cfg.n_optimisations):  # line 12
        groups = _same_length_groups([windows[u][k] for u in range(units)])
        rows = torch.from_numpy(np.concatenate([
            ((offsets[group] + starts)[:, None] + np.arange(length)).reshape(-1)
            for group, starts, length in groups
        ]))  # fmt: skip
        head, v = net(memory.obs[rows])  # line 14, one forward pass for every unit's window
        v_next = next_values(model, memory.next_obs[rows])
        adv, baseline = advantages[rows], values[rows]  # line 15
        targets = variants.critic_target(memory, rows, v_next, adv, baseline, cfg.gamma)  # type: ignore[arg-type]
        log_probs, behaviour = net.log_probs_and_entropy(head, memory.actions[rows])[0], old_log_probs[rows]
        entropies = net.entropies(head)
        objective = torch.zeros(())
        value_loss = torch.zeros(())
        at = 0
        for group, _, length in groups:  # lines 16-18 for each unit, on its own window
            shape = (group.shape[0], length)
            part = slice(at, at + group.shape[0] * length)
            at = part.stop
            unit_adv = adv[part].reshape(shape)
            if cfg.normalise_advantages and length > 1:  # per minibatch, as a worker of one unit does
                unit_adv = (unit_adv - unit_adv.mean(1, keepdim=True)) / (
                    unit_adv.std(1, keepdim=True) + 1e-8
                )
            new, old = log_probs[part].reshape(shape), behaviour[part].reshape(shape)
            l_clip = clipped_surrogate(new, old, unit_adv, cfg.clip_eps, dim=1)
            entropy = entropies[part].reshape(shape).mean(1)
            l_v = critic_loss(v[part].reshape(shape), targets[part].reshape(shape), cfg.critic_loss, dim=1)
            unit_objective, unit_value_loss = -l_clip - cfg.entropy_coef * entropy, l_v
            if unit_weights is not None:  # Σ_u w_u L_u: each unit's loss weighted by its need
                unit_objective = unit_objective * unit_weights[group]
                unit_value_loss = unit_value_loss * unit_weights[group]
            objective = objective + unit_objective.sum()
            value_loss = value_loss + unit_value_loss.sum()
            with torch.no_grad():
                log_ratio = new - old
                ratio = log_ratio.exp()
                kl = ((ratio - 1.0) - log_ratio).mean(1)
                clipped = ((ratio - 1.0).abs() > cfg.clip_eps).float().mean(1)
                totals[group] += torch.stack([-l_clip, l_v, entropy, kl, clipped], 1).numpy()
        # lines 19-23: the (weighted) mean of the units' losses, differentiated once, stepped as a worker
        # steps (the schedule reads the batch's head and critic loss; its window is the units' ``rows``)
        batch = Minibatch(slice(0, 0), memory.obs[rows], head, adv, value_loss / total_weight)
        actor_gradient = yield from both_models_at_once(model, batch, _fixed(objective / total_weight))
    means = totals / cfg.n_optimisations
    unit_stats = tuple(UpdateStats(*(float(x) for x in row)) for row in means)
    host_stats = UpdateStats(*(float(x) for x in means.mean(0)))
    return HostFinished(unit_stats, host_stats, actor_gradient)


def _fixed(objective: torch.Tensor) -> Objective:
    """The schedule's objective for a host's step: the mean of its units' objectives, computed above."""
    return lambda batch, head: objective


def _same_length_groups(spans: list[tuple[int, int]]) -> list[tuple[np.ndarray, np.ndarray, int]]:
    """The units grouped by the length of their window this step: (units, their window starts, length),
    longest first (a unit whose memory is shorter than U has a shorter window: all of it)."""
    starts = np.array([start for start, _ in spans], dtype=np.int64)
    lengths = np.array([stop - start for start, stop in spans], dtype=np.int64)
    groups = []
    for length in sorted(set(lengths.tolist()), reverse=True):
        members = np.flatnonzero(lengths == length)
        groups.append((members, starts[members], int(length)))
    return groups
