"""The paper's losses as pure functions of tensors: GAE (Eq. 2), critic loss (Eq. 3), L^CLIP (Eq. 6)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch.nn import functional


def td_targets(
    rewards: torch.Tensor, next_values: torch.Tensor, terminated: torch.Tensor, gamma: float
) -> torch.Tensor:
    """V^target(s_t) = r_{t+1} + γ·V(s_{t+1}) (Eq. 3), with no bootstrap where s_{t+1} is terminal.

    A time-limit truncation is not terminal, so it bootstraps from V(s_{t+1}) like any other step.
    """
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
    """Generalised advantage estimates Â_t over chronological runs of transitions (Eq. 2).

    δ_t = r_{t+1} + γ·V(s_{t+1})·(1 − terminated_t) − V(s_t) and Â_t = δ_t + (γλ)·Â_{t+1}, the sum
    running to the end of its run and stopping at the end of an episode (``episode_end``). The inputs are
    1-D, one run (None) or runs of ``lengths`` one after the other (each unit's memory or window), whose
    recursions run side by side in the same float64 arithmetic. The result is detached from the graph.
    """
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
    """L^V(μ) = Ê[|V^target(s_t) − V_μ(s_t)|] (Eq. 3); for ``kind='huber'`` the smooth L1 loss of the
    authors' code, Ê[½e²] where |e| < 1 and Ê[|e| − ½] elsewhere.

    ``targets`` carry no gradient (semi-gradient TD). Ê is the mean over every element, or with ``dim``
    over that dimension only (a unit host: one loss per unit's row of transitions).
    """
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
    """L^CLIP(θ) = Ê[min(R_t·Â_t, clip(R_t, 1 − ε, 1 + ε)·Â_t)] (Eq. 6), R_t = π_θ / π_θold (to maximise).

    Eq. 6 as printed puts Â_t outside the min; the min must hold the two products (Schulman et al.
    2017), otherwise the clip does nothing for negative advantages, so this is the original form. Ê is the
    mean over every element, or with ``dim`` over that dimension only (a unit host: one per unit).
    """
    ratio = torch.exp(log_probs - old_log_probs.detach())
    unclipped = ratio * advantages
    clipped = torch.clamp(ratio, 1.0 - clip_eps, 1.0 + clip_eps) * advantages
    surrogate = torch.min(unclipped, clipped)
    return surrogate.mean() if dim is None else surrogate.mean(dim)
