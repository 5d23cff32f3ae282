"""``fedprox``: fedavg with the proximal term μ/2‖θ − θ_global‖² in every worker's local training (Li et al.,
MLSys 2020), θ_global being the model the round started from; the chief sends μ in each round's
configuration (as Flower's ``proximal_mu``). μ = 0 is fedavg, bit for bit.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from fleetrl.federation.schemes.agent import ExtraLoss, FederatedAgent
from fleetrl.federation.schemes.fedavg import FedAvgScheme
from fleetrl.federation.wire.messages import RoundConfig


class FedProxScheme(FedAvgScheme):
    """Model averaging with a proximal term of weight ``mu`` (μ ≥ 0) in local training."""

    name = "fedprox"
    summary = "fedavg with the proximal term mu/2 ||theta - theta_global||^2 in every worker's local training"

    def __init__(self, *, mu: float = 0.01) -> None:
        if not (math.isfinite(mu) and mu >= 0.0):
            raise ValueError(f"mu = {mu!r}: must be a finite number >= 0")
        self.mu = float(mu)

    def params(self) -> dict[str, Any]:
        """μ."""
        return {"mu": self.mu}

    def configure(self, round: int, members: tuple[str, ...]) -> RoundConfig:
        """Every worker is asked for the same μ each round."""
        del round, members
        return {"mu": self.mu}

    def local_loss(self, agent: FederatedAgent, config: RoundConfig) -> ExtraLoss | None:
        """μ/2‖θ − θ_global‖² over the whole actor-critic, θ_global = the agent's model now; μ from the
        chief's configuration (else this scheme's); None when μ is 0."""
        mu = float(config.get("mu", self.mu))
        if mu == 0.0:
            return None
        return proximal_term(mu, agent.model_layout(), agent.model_parameters())


def proximal_term(mu: float, layout: list[tuple[str, tuple[int, ...]]], flat: np.ndarray) -> ExtraLoss:
    """``fn(model) = mu/2 · Σ ‖p − θ_global[name]‖²`` over ``model``'s parameters named in ``layout``
    (θ_global: ``flat`` split by ``layout``)."""
    import torch  # the worker's: a chief reading this module does not load it

    anchors, start = {}, 0
    for name, shape in layout:
        size = math.prod(shape)
        anchors[name] = torch.from_numpy(np.array(flat[start : start + size], np.float32).reshape(shape))
        start += size

    def term(model: torch.nn.Module) -> torch.Tensor:
        params = dict(model.named_parameters())
        total = sum(((params[name] - anchor) ** 2).sum() for name, anchor in anchors.items())
        return 0.5 * mu * torch.as_tensor(total)

    return term
