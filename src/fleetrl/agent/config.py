"""Hyper-parameters of the Actor-Critic PPO agent, and the two named presets (``paper``, ``standard``)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Literal

Activation = Literal["tanh", "relu"]
TrunkSplit = Literal["shared", "actor"]
GaeScope = Literal["window", "memory"]
CriticTarget = Literal["td", "gae"]
OldPolicy = Literal["round_start", "behaviour"]
CriticLoss = Literal["abs", "mse"]


@dataclass
class PPOConfig:
    """Every hyper-parameter of one worker's Actor-Critic PPO (docs/algorithm.md explains each choice)."""

    gamma: float = 0.99
    """discount factor γ (the paper does not give it)"""
    gae_lambda: float = 0.99
    """GAE parameter λ of Eq. 2 (Table 1: 0.99)"""
    clip_eps: float = 0.9
    """clipping parameter ε of Eq. 6 (Table 1: 0.9)"""
    actor_lr: float = 1e-3
    """Adam learning rate η_θ of the actor (Eq. 7; Table 1: 0.001)"""
    critic_lr: float = 1e-3
    """Adam learning rate η_μ of the critic (Eq. 4; Table 1: 0.001)"""
    memory_size: int = 200
    """trajectory memory: the last this-many transitions are kept across rounds (Table 1: 200)"""
    batch_size: int = 64
    """U: length of the contiguous window each optimisation takes from the memory (Table 1: 64)"""
    n_optimisations: int = 10
    """K: optimisations per round (Algorithm 2, line 12; Table 1: 10)"""
    hidden: tuple[int, ...] = (128, 128, 128)
    """widths of the trunk's hidden layers, shared by actor and critic (section 5.1: 3 x 128)"""
    activation: Activation = "tanh"
    """non-linearity after each trunk layer (the paper does not give it)"""
    trunk_split: TrunkSplit = "shared"
    """'shared': trunk is in both θ and μ, each optimiser steps it with its own loss (Algorithm 2 lines
    21 and 23 read literally); 'actor': trunk belongs to θ only and the critic loss reaches it through the
    actor's gradient, scaled by critic_trunk_coef (μ is then the value head alone)"""
    critic_trunk_coef: float = 0.5
    """weight of the critic loss in the trunk's gradient when trunk_split == 'actor' (0: trunk ignores it)"""
    gae_scope: GaeScope = "window"
    """'window': Eq. 2 run inside each U-window with the current critic (the paper); 'memory': advantages
    computed once per round over the whole memory with the critic as it was at line 11"""
    critic_target: CriticTarget = "td"
    """'td': V_target = r + γV(s') (Eq. 3); 'gae': V_target = Â + V(s) (the λ-return)"""
    critic_loss: CriticLoss = "abs"
    """'abs': |V_target − V| (Eq. 3); 'mse': ½(V_target − V)²"""
    old_policy: OldPolicy = "round_start"
    """π_θold of Eq. 5-6: 'round_start' = the policy at line 11 of this round (the paper); 'behaviour' = the
    policy that generated each stored transition (standard PPO importance sampling)"""
    entropy_coef: float = 0.0
    """weight of the policy-entropy bonus added to L^CLIP (the paper has none)"""
    normalise_advantages: bool = False
    """standardise Â inside each window before Eq. 6 (the paper does not)"""
    max_grad_norm: float = 0.0
    """clip each optimiser's gradient to this global norm before its step (0: no clipping)"""

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready dict (``hidden`` as a list)."""
        data = dataclasses.asdict(self)
        data["hidden"] = list(self.hidden)
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PPOConfig:
        """Inverse of :meth:`to_dict`; unknown keys are an error, missing keys take the defaults."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ValueError(f"unknown PPOConfig fields {unknown} (known: {sorted(names)})")
        values = dict(data)
        if "hidden" in values:
            values["hidden"] = tuple(int(h) for h in values["hidden"])
        config = cls(**values)
        config.validate()
        return config

    def validate(self) -> None:
        """Raise ValueError naming the first field whose value cannot work."""
        checks: list[tuple[bool, str]] = [
            (0.0 <= self.gamma <= 1.0, f"gamma must be in [0, 1], got {self.gamma}"),
            (0.0 <= self.gae_lambda <= 1.0, f"gae_lambda must be in [0, 1], got {self.gae_lambda}"),
            (self.clip_eps > 0.0, f"clip_eps must be > 0, got {self.clip_eps}"),
            (self.actor_lr > 0.0 and self.critic_lr > 0.0, "learning rates must be > 0"),
            (self.batch_size >= 1, f"batch_size must be >= 1, got {self.batch_size}"),
            (self.memory_size >= self.batch_size, "memory_size must be >= batch_size"),
            (self.n_optimisations >= 1, f"n_optimisations must be >= 1, got {self.n_optimisations}"),
            (len(self.hidden) >= 1 and min(self.hidden) >= 1, f"hidden must be positive, got {self.hidden}"),
            (
                self.activation in ("tanh", "relu"),
                f"activation must be tanh or relu, got {self.activation!r}",
            ),
            (
                self.trunk_split in ("shared", "actor"),
                f"trunk_split: shared or actor, got {self.trunk_split!r}",
            ),
            (self.gae_scope in ("window", "memory"), f"gae_scope: window or memory, got {self.gae_scope!r}"),
            (self.critic_target in ("td", "gae"), f"critic_target: td or gae, got {self.critic_target!r}"),
            (self.critic_loss in ("abs", "mse"), f"critic_loss: abs or mse, got {self.critic_loss!r}"),
            (
                self.old_policy in ("round_start", "behaviour"),
                f"old_policy: round_start or behaviour, got {self.old_policy!r}",
            ),
            (self.max_grad_norm >= 0.0, f"max_grad_norm must be >= 0, got {self.max_grad_norm}"),
        ]
        for ok, message in checks:
            if not ok:
                raise ValueError(message)


PRESETS: dict[str, PPOConfig] = {
    # Table 1 exactly; the choices the paper leaves open take their literal reading (docs/algorithm.md).
    "paper": PPOConfig(),
    # clip 0.2 plus what measurement on CartPole showed to learn faster (docs/algorithm.md, "Presets").
    "standard": PPOConfig(
        clip_eps=0.2,
        gamma=0.98,
        old_policy="behaviour",
        gae_scope="memory",
        critic_target="gae",
        normalise_advantages=True,
        n_optimisations=20,
        memory_size=1000,
        batch_size=128,
    ),
}


def get_preset(name: str) -> PPOConfig:
    """A fresh copy of the named preset; ValueError listing the choices if the name is unknown."""
    try:
        preset = PRESETS[name]
    except KeyError:
        choices = " or ".join(sorted(PRESETS))
        raise ValueError(f"unknown preset {name!r} (choose {choices})") from None
    return dataclasses.replace(preset)
