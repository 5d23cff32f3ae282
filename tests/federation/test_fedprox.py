"""``fedprox`` on hand-computed arrays: fedavg's average, μ in every round's configuration, and the proximal
term μ/2‖θ − θ_global‖² a worker adds to its local training."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from torch import nn

from fleetrl.federation.aggregation import get_aggregator
from fleetrl.federation.schemes import SCHEMES, RoundContext, get_scheme
from fleetrl.federation.schemes.fedprox import FedProxScheme
from fleetrl.federation.wire.messages import Message


class LinearAgent:
    """An agent whose whole model is one ``nn.Linear(2, 1)``: ``weight`` (1, 2) and ``bias`` (1,)."""

    def __init__(self, values: list[float]) -> None:
        self.net = nn.Linear(2, 1)
        self.set_model_parameters(np.array(values, np.float32))

    def model_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        return [("weight", (1, 2)), ("bias", (1,))]

    def model_parameters(self) -> np.ndarray:
        return np.concatenate([p.detach().numpy().reshape(-1) for p in self.net.parameters()])

    def set_model_parameters(self, flat: np.ndarray) -> None:
        with torch.no_grad():
            self.net.weight.copy_(torch.from_numpy(flat[:2].reshape(1, 2)))
            self.net.bias.copy_(torch.from_numpy(flat[2:]))


def test_fedprox_is_found_by_its_module_and_checks_mu() -> None:
    assert SCHEMES["fedprox"] is FedProxScheme
    assert get_scheme("fedprox").params() == {"mu": 0.01}
    assert get_scheme("fedprox", mu=1).params() == {"mu": 1.0}
    with pytest.raises(ValueError, match=r"scheme 'fedprox': mu = -0.5: must be a finite number >= 0"):
        get_scheme("fedprox", mu=-0.5)


def test_the_chief_averages_models_as_fedavg_and_asks_every_worker_for_mu() -> None:
    scheme = get_scheme("fedprox", mu=0.1)
    answers = {
        "1": Message("model", "r", "1", 1, flat=np.array([1.0, 2.0, 3.0], np.float32)),
        "2": Message("model", "r", "2", 1, flat=np.array([3.0, 4.0, 5.0], np.float32)),
    }
    answer = scheme.combine(answers, RoundContext(get_aggregator("mean"), ("1", "2"), {}))
    assert answer.kind == "average" and answer.fleet_model and answer.contributors == ("1", "2")
    np.testing.assert_array_equal(answer.flat, [2.0, 3.0, 4.0])
    assert scheme.configure(4, ("1", "2")) == {"mu": 0.1}


def test_the_proximal_term_and_its_gradient_by_hand() -> None:
    scheme, agent = get_scheme("fedprox", mu=0.1), LinearAgent([1.0, 2.0, 3.0])
    assert isinstance(scheme, FedProxScheme)
    term = scheme.local_loss(agent, {"mu": 0.1})  # θ_global = [1, 2, 3], the round's start
    assert term is not None
    agent.set_model_parameters(np.array([2.0, 0.0, 3.0], np.float32))  # local training moved θ
    value = term(agent.net)
    # μ/2 ‖θ − θ_global‖² = 0.1 / 2 · (1² + 2² + 0²) = 0.25
    assert value.item() == pytest.approx(0.25)
    value.backward()
    # ∇ = μ (θ − θ_global) = [0.1, −0.2] for the weight, [0] for the bias
    assert agent.net.weight.grad is not None and agent.net.bias.grad is not None
    np.testing.assert_allclose(agent.net.weight.grad.numpy(), [[0.1, -0.2]], rtol=1e-6)
    np.testing.assert_allclose(agent.net.bias.grad.numpy(), [0.0])


def test_mu_comes_from_the_chief_s_configuration_and_zero_adds_nothing() -> None:
    scheme, agent = FedProxScheme(mu=0.1), LinearAgent([0.0, 0.0, 0.0])
    assert scheme.local_loss(agent, {"mu": 0.0}) is None
    term = scheme.local_loss(agent, {"mu": 2.0})
    agent.set_model_parameters(np.array([1.0, 0.0, 0.0], np.float32))
    assert term is not None and term(agent.net).item() == pytest.approx(1.0)  # 2 / 2 · 1²
    fallback = scheme.local_loss(agent, {})  # no configuration: its own μ
    agent.set_model_parameters(np.array([1.0, 0.0, 1.0], np.float32))
    assert fallback is not None and fallback(agent.net).item() == pytest.approx(0.05)  # 0.1 / 2 · 1²
