"""The actor-critic network: a shared trunk with a softmax actor head and a scalar critic head."""

from __future__ import annotations

import itertools
import math

import torch
from torch import nn

from fleetrl.agent.config import PPOConfig


class ActorCritic(nn.Module):
    """MLP trunk (section 5.1: three hidden layers of 128) feeding two output layers.

    Parameter names are stable and form the wire layout: ``trunk.{i}.weight``, ``trunk.{i}.bias``,
    ``policy.weight``, ``policy.bias`` (the actor head, logits of π_θ) and ``value.weight``,
    ``value.bias`` (the critic head, V_μ).

    :param obs_dim: length of the observation vector
    :param n_actions: number of discrete actions (the actor's softmax width)
    :param hidden: widths of the trunk layers
    :param activation: ``tanh`` or ``relu`` after each trunk layer
    :param generator: torch generator used for the (orthogonal) initialisation
    """

    def __init__(
        self,
        obs_dim: int,
        n_actions: int,
        hidden: tuple[int, ...],
        activation: str,
        generator: torch.Generator,
    ) -> None:
        super().__init__()
        if obs_dim < 1 or n_actions < 2:
            raise ValueError(f"need obs_dim >= 1 and n_actions >= 2, got {obs_dim}, {n_actions}")
        self.obs_dim = obs_dim
        self.n_actions = n_actions
        self.activation = activation
        widths = [obs_dim, *hidden]
        layers = [nn.Linear(a, b) for a, b in itertools.pairwise(widths)]
        self.trunk = nn.ModuleList(layers)
        self.trunk_layers: list[nn.Linear] = layers
        """the trunk's layers, typed (the same modules as ``trunk``)"""
        self.policy = nn.Linear(widths[-1], n_actions)
        self.value = nn.Linear(widths[-1], 1)
        # CleanRL's initialisation: orthogonal, gain √2 in the trunk, 0.01 for the policy (near-uniform
        # π at the start), 1 for the value; zero biases.
        for layer in self.trunk_layers:
            _init(layer, math.sqrt(2.0), generator)
        _init(self.policy, 0.01, generator)
        _init(self.value, 1.0, generator)
        self._act = torch.tanh if activation == "tanh" else torch.relu

    @classmethod
    def from_config(
        cls, obs_dim: int, n_actions: int, config: PPOConfig, generator: torch.Generator
    ) -> ActorCritic:
        """Build the network a config describes."""
        return cls(obs_dim, n_actions, config.hidden, config.activation, generator)

    def features(self, obs: torch.Tensor) -> torch.Tensor:
        """Output of the shared trunk (the three hidden layers)."""
        x = obs
        for layer in self.trunk_layers:
            x = self._act(layer(x))
        return x

    def forward(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Logits of π_θ(·|s) (batch, n_actions) and V_μ(s) (batch,)."""
        h = self.features(obs)
        return self.policy(h), self.value(h).squeeze(-1)

    def value_of(self, obs: torch.Tensor) -> torch.Tensor:
        """V_μ(s) alone (batch,)."""
        return self.value(self.features(obs)).squeeze(-1)

    def trunk_parameters(self) -> list[tuple[str, nn.Parameter]]:
        """Named parameters of the shared trunk, in layout order."""
        return [(f"trunk.{n}", p) for n, p in self.trunk.named_parameters()]

    def head_parameters(self, head: str) -> list[tuple[str, nn.Parameter]]:
        """Named parameters of ``policy`` or ``value`` head, in layout order."""
        module = {"policy": self.policy, "value": self.value}[head]
        return [(f"{head}.{n}", p) for n, p in module.named_parameters()]


def _init(layer: nn.Linear, gain: float, generator: torch.Generator) -> None:
    nn.init.orthogonal_(layer.weight, gain=gain, generator=generator)
    nn.init.zeros_(layer.bias)
