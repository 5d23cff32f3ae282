"""Flat float32 vectors of named parameters (what the federation exchanges), and the actor's and the
critic's Adam: built and stepped without importing ``torch._dynamo`` (seconds of imports; fleetrl never
compiles), their state as one flat vector (what the chief of a one-policy fleet hands a joining worker)."""

from __future__ import annotations

import inspect
import sys
from collections.abc import Mapping
from typing import Any

import numpy as np
import torch
from torch import nn

from fleetrl.agent.config import PPOConfig

Layout = list[tuple[str, tuple[int, ...]]]
Named = list[tuple[str, nn.Parameter]]  # parameters with their stable names (``trunk.0.weight``...)


def layout(named: Named) -> Layout:
    """Names and shapes, in the order of a flat vector."""
    return [(name, tuple(p.shape)) for name, p in named]


def flatten(named: Named) -> np.ndarray:
    """The parameters' values as one flat float32 vector."""
    return flatten_tensors([p for _, p in named])


def flatten_tensors(tensors: list[torch.Tensor]) -> np.ndarray:
    """Tensors (gradients) concatenated into one flat float32 vector."""
    return np.concatenate([t.detach().numpy().ravel() for t in tensors]).astype(np.float32)


def split(flat: np.ndarray, named: Named, what: str) -> list[torch.Tensor]:
    """``flat`` cut into tensors shaped like ``named``; ValueError if it does not fit or is not finite."""
    array = np.asarray(flat)
    size = sum(p.numel() for _, p in named)
    if array.ndim != 1 or array.shape[0] != size:
        raise ValueError(f"{what} vector must be flat with {size} values, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{what} vector has non-finite values")
    tensor = torch.from_numpy(array.astype(np.float32))
    chunks, offset = [], 0
    for _, p in named:
        chunks.append(tensor[offset : offset + p.numel()].view_as(p).clone())
        offset += p.numel()
    return chunks


SLOTS = ("exp_avg", "exp_avg_sq", "step")
"""per optimiser and parameter, the state in the flat vector (float32 holds a ``step`` count exactly)"""
DEFERRED = ("add_param_group", "zero_grad", "state_dict", "load_state_dict")
"""the methods of ``torch.optim.Optimizer`` that would import ``torch._dynamo`` on their first call"""


def defer_dynamo_import() -> None:
    """Let those methods run without importing ``torch._dynamo`` (idempotent; a no-op once it is imported, or
    on a PyTorch whose methods are not wrapped this way)."""
    if "torch._dynamo" in sys.modules:
        return
    for name in DEFERRED:
        function = getattr(getattr(torch.optim.Optimizer, name), "__wrapped__", None)
        if function is not None and getattr(function, "__dynamo_disable", None) is None:
            # torch._compile._disable_dynamo caches its wrapper here; the function itself runs instead
            setattr(function, "__dynamo_disable", function)


def step_optimiser(optimiser: torch.optim.Optimizer) -> None:
    """``optimiser.step()`` as eager mode runs it: the step itself, gradients off (torch's wrapper also
    imports ``torch._dynamo`` and calls step hooks fleetrl never sets)."""
    with torch.no_grad():
        inspect.unwrap(type(optimiser).step)(optimiser)


def adam(shared: Named, own: Named, lr: float) -> torch.optim.Adam:
    """Adam over ``shared`` parameters and, in a second group marked ``own`` (its state never leaves the
    unit), the unit's own offsets."""
    defer_dynamo_import()
    groups: list[dict[str, Any]] = [{"params": [p for _, p in shared]}]
    if own:
        groups.append({"params": [p for _, p in own], "own": True})
    return torch.optim.Adam(groups, lr=lr)


def adams(
    config: PPOConfig, actor: tuple[Named, Named], critic: tuple[Named, Named], model: tuple[Named, Named]
) -> tuple[torch.optim.Adam, torch.optim.Adam]:
    """The actor's and the critic's Adam over their (shared, own) parameters; with ``optimisers
    'one_sequential'`` one Adam over the whole ``model`` (each step moves only the parameters given a
    gradient), the same object twice."""
    if config.optimisers == "per_model":
        return adam(*actor, config.actor_lr), adam(*critic, config.critic_lr)
    one = adam(*model, config.actor_lr)
    return one, one


def _params(optimiser: torch.optim.Optimizer) -> list[torch.Tensor]:
    """The shared parameters (a unit's own offsets, in a group marked ``own``, stay with the unit)."""
    return [p for group in optimiser.param_groups if not group.get("own") for p in group["params"]]


def optimiser_layout(optimisers: Mapping[str, torch.optim.Optimizer]) -> Layout:
    """Names and shapes of the flat state, in order (``optim.<name>.<index>.<slot>``)."""
    out: Layout = []
    for name, optimiser in optimisers.items():
        for i, p in enumerate(_params(optimiser)):
            shape = tuple(p.shape)
            out += [(f"optim.{name}.{i}.{slot}", shape if slot != "step" else (1,)) for slot in SLOTS]
    return out


def optimiser_flat(optimisers: Mapping[str, torch.optim.Optimizer]) -> np.ndarray:
    """The state as flat float32 in :func:`optimiser_layout` order."""
    chunks: list[np.ndarray] = []
    for optimiser in optimisers.values():
        for p in _params(optimiser):
            state = optimiser.state.get(p, {})
            for slot in SLOTS:
                value = state.get(slot)
                if value is None:
                    chunks.append(np.zeros(1 if slot == "step" else p.numel(), np.float32))
                else:
                    chunks.append(torch.as_tensor(value).detach().reshape(-1).to(torch.float32).numpy())
    return np.concatenate(chunks) if chunks else np.zeros(0, np.float32)


def load_optimiser_flat(optimisers: Mapping[str, torch.optim.Optimizer], flat: np.ndarray) -> None:
    """Replace the state with ``flat`` (:func:`optimiser_flat`'s form); ValueError if it does not fit."""
    named = [(name, nn.Parameter(torch.empty(shape), False)) for name, shape in optimiser_layout(optimisers)]
    chunks = iter(split(flat, named, "optimiser state"))
    for optimiser in optimisers.values():
        for p in _params(optimiser):
            exp_avg, exp_avg_sq, step = next(chunks), next(chunks), next(chunks)
            optimiser.state[p] = {
                "step": step.reshape(()).clone(),
                "exp_avg": exp_avg.clone(),
                "exp_avg_sq": exp_avg_sq.clone(),
            }
