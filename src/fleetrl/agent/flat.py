"""Flat float32 vectors of named parameters (what the federation exchanges) and their layouts."""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

Named = list[tuple[str, nn.Parameter]]
"""parameters with their stable names (``trunk.0.weight`` ...), in layout order"""


def layout(named: Named) -> list[tuple[str, tuple[int, ...]]]:
    """Names and shapes, in the order of a flat vector."""
    return [(name, tuple(p.shape)) for name, p in named]


def flatten(named: Named) -> np.ndarray:
    """The parameters' values as one flat float32 vector."""
    return np.concatenate([p.detach().numpy().ravel() for _, p in named]).astype(np.float32)


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
