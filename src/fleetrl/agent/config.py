"""Hyper-parameters of the Actor-Critic PPO agent and the named presets (paper, paper-code, standard)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Literal, get_type_hints

from fleetrl.coercion import coerce

Activation = Literal["tanh", "relu"]
GaeScope = Literal["window", "memory"]
CriticTarget = Literal["td", "gae"]
OldPolicy = Literal["round_start", "behaviour"]
CriticLoss = Literal["abs", "huber"]
TrajectoryMemoryKind = Literal["ring", "per_round"]
Optimisers = Literal["per_model", "one_sequential"]
Criterion = Literal["sampled", "argmax"]
OwnPart = Literal["none", "input", "heads", "biases"]

# the network parameters each ``own_part`` gives a unit its own offset of (``*``: every trunk layer)
OWN_PART_NAMES: dict[str, tuple[str, ...]] = {
    "none": (),
    "input": ("trunk.0.bias",),
    "heads": ("policy.weight", "policy.bias", "value.weight", "value.bias"),
    "biases": ("trunk.*.bias", "policy.bias", "value.bias"),
}


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
    """trajectory memory size (Table 1: 200); with 'per_round' the least a round collects"""
    batch_size: int = 64
    """U: length of the contiguous window each optimisation takes from the memory (Table 1: 64)"""
    n_optimisations: int = 10
    """K: optimisations per round (Algorithm 2, line 12; Table 1: 10)"""
    hidden: tuple[int, ...] = (128, 128, 128)
    """widths of the trunk's hidden layers, shared by actor and critic (section 5.1: 3 x 128)"""
    activation: Activation = "tanh"
    """non-linearity after each trunk layer (the paper does not give it)"""
    gae_scope: GaeScope = "window"
    """'window': Eq. 2 inside each U-window with the current critic (the paper); 'memory': once per round
    over the whole memory with the critic of line 11"""
    critic_target: CriticTarget = "td"
    """'td': V_target = r + γV(s') (Eq. 3); 'gae': V_target = Â + V(s) (the λ-return)"""
    critic_loss: CriticLoss = "abs"
    """'abs': |V_target − V| (Eq. 3); 'huber': smooth L1 (the authors' code)"""
    critic_coef: float = 1.0
    """weight of L^V in the critic's step (the authors' code: 0.5)"""
    trajectory_memory: TrajectoryMemoryKind = "ring"
    """'ring': the last memory_size transitions, kept across rounds, a round one episode (the paper's
    text); 'per_round': a round plays whole episodes until the memory holds memory_size, makes one update and
    empties the memory (the authors' code)"""
    optimisers: Optimisers = "per_model"
    """'per_model': one Adam for θ and one for μ, both gradients at the same parameters (Algorithm 2, lines
    20-23); 'one_sequential': one Adam over the whole network, the critic's step then the actor's (the
    authors' code; needs actor_lr == critic_lr)"""
    old_policy: OldPolicy = "round_start"
    """π_θold of Eq. 5-6: 'round_start' = the policy at line 11 (the paper); 'behaviour' = the policy that
    generated each stored transition (standard PPO)"""
    entropy_coef: float = 0.0
    """weight of the policy-entropy bonus added to L^CLIP (the paper has none)"""
    normalise_advantages: bool = False
    """standardise Â inside each window before Eq. 6 (the paper does not)"""
    criterion: Criterion = "sampled"
    """what a unit's completion proves: 'sampled' (the paper's), the WMA of its last 10 sampled rounds
    reaches the target; 'argmax', once a round reached it the next rounds are played by π_θ's arg-max,
    stored nowhere, until one falls short (docs/algorithm.md; needs trajectory_memory 'ring')"""
    own_part: OwnPart = "none"
    """a unit's own offset of these shared parameters, learned from its own gradient and never sent:
    'input' the first layer's bias, 'heads' the actor and critic heads, 'biases' every bias; 'none'"""
    last_step: bool = False
    """the policy's input holds the unit's last observation and action (:mod:`fleetrl.envs.wrappers`)"""

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
        """Raise ValueError naming the first field whose value cannot work: its type, range or fit."""
        for name, kind in get_type_hints(PPOConfig).items():
            coerce(name, getattr(self, name), kind)
        checks: list[tuple[bool, str]] = [
            (0.0 <= self.gamma <= 1.0, f"gamma must be in [0, 1], got {self.gamma}"),
            (0.0 <= self.gae_lambda <= 1.0, f"gae_lambda must be in [0, 1], got {self.gae_lambda}"),
            (self.clip_eps > 0.0, f"clip_eps must be > 0, got {self.clip_eps}"),
            (self.actor_lr > 0.0 and self.critic_lr > 0.0, "learning rates must be > 0"),
            (self.batch_size >= 1, f"batch_size must be >= 1, got {self.batch_size}"),
            (self.memory_size >= self.batch_size, "memory_size must be >= batch_size"),
            (self.n_optimisations >= 1, f"n_optimisations must be >= 1, got {self.n_optimisations}"),
            (len(self.hidden) >= 1 and min(self.hidden) >= 1, f"hidden must be positive, got {self.hidden}"),
            (self.critic_coef > 0.0, f"critic_coef must be > 0, got {self.critic_coef}"),
            (
                self.optimisers != "one_sequential" or self.actor_lr == self.critic_lr,
                f"optimisers 'one_sequential' is one Adam with one learning rate: actor_lr ({self.actor_lr}) "
                f"must equal critic_lr ({self.critic_lr})",
            ),
            (
                self.criterion == "sampled" or self.trajectory_memory == "ring",
                "criterion 'argmax' plays a held unit's episodes without storing them, and a 'per_round' "
                "memory would have nothing to update on: it needs trajectory_memory 'ring'",
            ),
        ]
        for ok, message in checks:
            if not ok:
                raise ValueError(message)


DEFAULT_PRESET = "standard"  # the preset of every command when none is named (docs/algorithm.md, "Presets")

PRESETS: dict[str, PPOConfig] = {
    # Table 1 exactly; the choices the paper leaves open take their literal reading (docs/algorithm.md).
    "paper": PPOConfig(),
    # What the authors' public code ran where the text is silent or disagrees (docs/algorithm.md).
    "paper-code": PPOConfig(
        clip_eps=0.1,
        gamma=0.98,
        old_policy="behaviour",
        trajectory_memory="per_round",
        critic_loss="huber",
        critic_coef=0.5,
        entropy_coef=0.01,
        normalise_advantages=True,
        optimisers="one_sequential",
    ),
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
        *others, last = sorted(PRESETS)
        choices = f"{', '.join(others)} or {last}" if others else last
        raise ValueError(f"unknown preset {name!r} (choose {choices})") from None
    return dataclasses.replace(preset)
