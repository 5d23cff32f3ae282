"""The actor-critic network: a shared trunk, an actor head (softmax or Gaussian) and a critic head."""

from __future__ import annotations

import fnmatch
import itertools
import math

import torch
from torch import nn
from torch.nn import functional

from fleetrl.agent.action_space import ActionSpace, as_action_space
from fleetrl.agent.config import OWN_PART_NAMES, PPOConfig

INITIAL_LOG_STD = 0.0  # in units of half the action range: σ starts at (high − low) / 2, the whole box
_HALF_LOG_2PI = 0.5 * math.log(2.0 * math.pi)


class ActorCritic(nn.Module):
    """MLP trunk (section 5.1: three hidden layers of 128) feeding two output layers.

    Parameter names are stable and form the wire layout: ``trunk.{i}.weight``/``.bias``, ``policy.weight``/
    ``.bias`` (the actor head: logits of π_θ, or its Gaussian mean), for a box ``policy_log_std``, and
    ``value.weight``/``.bias`` (the critic head, V_μ). A Gaussian head's output u is in units of the box:
    mean = centre + half_range·u and σ = half_range·exp(policy_log_std).

    :param generator: torch generator of the (orthogonal) initialisation
    :param own: the parameters the unit holds an offset of its own of (zeros at the start, added to the
        shared value in every pass; ``PPOConfig.own_part``)
    """

    def __init__(
        self,
        obs_dim: int,
        actions: int | ActionSpace,
        hidden: tuple[int, ...],
        activation: str,
        generator: torch.Generator,
        own: tuple[str, ...] = (),
    ) -> None:
        super().__init__()
        space = as_action_space(actions)
        if obs_dim < 1:
            raise ValueError(f"need obs_dim >= 1, got {obs_dim}")
        self.obs_dim = obs_dim
        self.action_space = space
        self.n_actions = space.n  # 0 for a box
        self.activation = activation
        widths = [obs_dim, *hidden]
        layers = [nn.Linear(a, b) for a, b in itertools.pairwise(widths)]
        self.trunk = nn.ModuleList(layers)
        self.trunk_layers: list[nn.Linear] = layers  # the same modules as ``trunk``, typed
        self.policy = nn.Linear(widths[-1], space.head_size)
        self.value = nn.Linear(widths[-1], 1)
        # CleanRL's initialisation: orthogonal, gain √2 in the trunk, 0.01 for the policy, 1 for the value;
        # zero biases.
        for layer in self.trunk_layers:
            _init(layer, math.sqrt(2.0), generator)
        _init(self.policy, 0.01, generator)
        _init(self.value, 1.0, generator)
        self.policy_log_std: nn.Parameter | None = None
        if not space.is_discrete:
            self.policy_log_std = nn.Parameter(torch.full((space.dim,), INITIAL_LOG_STD))
        # constants of the box, not parameters (nor in the state dict: the action space rebuilds them)
        self._centre = torch.tensor(space.centre(), dtype=torch.float32)
        self._half = torch.tensor(space.half_range(), dtype=torch.float32)
        self._act = torch.tanh if activation == "tanh" else torch.relu
        shared = dict(self.named_parameters())
        names = [n for pattern in own for n in shared if fnmatch.fnmatchcase(n, pattern)]
        self.own = nn.ParameterDict({own_key(n): nn.Parameter(torch.zeros_like(shared[n])) for n in names})

    @classmethod
    def from_config(
        cls, obs_dim: int, actions: int | ActionSpace, config: PPOConfig, generator: torch.Generator
    ) -> ActorCritic:
        """Build the network a config describes."""
        own = OWN_PART_NAMES[config.own_part]
        return cls(obs_dim, actions, config.hidden, config.activation, generator, own)

    def features(self, obs: torch.Tensor) -> torch.Tensor:
        """Output of the shared trunk (the three hidden layers)."""
        x = obs
        for i, layer in enumerate(self.trunk_layers):
            x = self._act(self._pass(f"trunk.{i}", layer, x))
        return x

    def forward(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The actor head's output (batch, head_size): logits of π_θ(·|s), or the Gaussian mean in units
        of the box; and V_μ(s) (batch,)."""
        h = self.features(obs)
        return self._pass("policy", self.policy, h), self._pass("value", self.value, h).squeeze(-1)

    def value_of(self, obs: torch.Tensor) -> torch.Tensor:
        """V_μ(s) alone (batch,)."""
        return self._pass("value", self.value, self.features(obs)).squeeze(-1)

    def _pass(self, name: str, layer: nn.Linear, x: torch.Tensor) -> torch.Tensor:
        if not self.own:
            return layer(x)
        weight, bias = self.effective(name)
        return functional.linear(x, weight, bias)

    def effective(self, layer: str) -> tuple[torch.Tensor, torch.Tensor]:
        """The weight and bias of ``layer`` (``trunk.0``...) this unit acts with: shared plus own offsets."""
        module = self.get_submodule(layer)
        assert isinstance(module, nn.Linear)
        weight, bias = module.weight, module.bias
        own_weight, own_bias = (self.own.get(own_key(f"{layer}.{p}")) for p in ("weight", "bias"))
        return (
            weight if own_weight is None else weight + own_weight,
            bias if own_bias is None else bias + own_bias,
        )

    def own_parameters(self, names: list[str]) -> list[tuple[str, nn.Parameter]]:
        """The unit's own offsets of the parameters ``names`` that have one, in their order."""
        return [(f"own.{own_key(n)}", self.own[own_key(n)]) for n in names if own_key(n) in self.own]

    def gaussian(self, head: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Mean (batch, dim) and log σ (dim,) of π_θ(·|s) in the env's units, from the head's output."""
        if self.policy_log_std is None:
            raise TypeError("a discrete policy head has no Gaussian")
        return self._centre + self._half * head, torch.log(self._half) + self.policy_log_std

    def log_probs_and_entropies(
        self, head: torch.Tensor, actions: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """log π_θ(a_t|s_t) (batch,) of stored actions and the entropy of π_θ(·|s_t): one per row for
        discrete actions (−Σ p·log p), one scalar for a Gaussian (Σ_d [½ + ½ log 2π + log σ_d]), whose
        log-density is Σ_d [−½((a_d − m_d)/σ_d)² − log σ_d − ½ log 2π]."""
        if self.policy_log_std is None:
            log_probs_all = functional.log_softmax(head, dim=-1)
            log_probs = log_probs_all.gather(1, actions[:, None]).squeeze(1)
            return log_probs, -(log_probs_all.exp() * log_probs_all).sum(-1)
        mean, log_std = self.gaussian(head)
        z = (actions - mean) / log_std.exp()
        log_probs = (-0.5 * z**2 - log_std - _HALF_LOG_2PI).sum(-1)
        return log_probs, (0.5 + _HALF_LOG_2PI + log_std).sum()

    def log_probs(self, obs: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
        """log π_θ(a_t|s_t) (batch,) of stored actions at observations ``obs``."""
        head, _ = self(obs)
        return self.log_probs_and_entropies(head, actions)[0]

    def trunk_parameters(self) -> list[tuple[str, nn.Parameter]]:
        """Named parameters of the shared trunk, in layout order."""
        return [(f"trunk.{n}", p) for n, p in self.trunk.named_parameters()]

    def head_parameters(self, head: str) -> list[tuple[str, nn.Parameter]]:
        """Named parameters of the ``policy`` (a Gaussian's ``policy_log_std`` last) or ``value`` head."""
        module = {"policy": self.policy, "value": self.value}[head]
        named = [(f"{head}.{n}", p) for n, p in module.named_parameters()]
        if head == "policy" and self.policy_log_std is not None:
            named.append(("policy_log_std", self.policy_log_std))
        return named


def own_key(name: str) -> str:
    """The key of parameter ``name``'s own offset (``trunk.0.bias`` → ``trunk_0_bias``)."""
    return name.replace(".", "_")


def _init(layer: nn.Linear, gain: float, generator: torch.Generator) -> None:
    nn.init.orthogonal_(layer.weight, gain=gain, generator=generator)
    nn.init.zeros_(layer.bias)
