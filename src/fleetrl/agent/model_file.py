"""A trained agent as a model file: safetensors weights with the config, the architecture and the seed as JSON
metadata (:mod:`.checkpoint` reads and writes the file; never pickle)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol, TypeVar

import numpy as np
from torch import nn

from fleetrl.agent.action_space import ActionSpace
from fleetrl.agent.checkpoint import CheckpointError, check_architecture, read_checkpoint, write_checkpoint
from fleetrl.agent.config import PPOConfig


class SavedAgent(Protocol):
    """What a model file is written from and loaded into (``fleetrl.agent.ppo.PPOAgent``)."""

    @property
    def obs_dim(self) -> int: ...
    @property
    def n_actions(self) -> int: ...
    @property
    def action_space(self) -> ActionSpace: ...
    @property
    def config(self) -> PPOConfig: ...
    @property
    def seed(self) -> int: ...
    @property
    def net(self) -> nn.Module: ...
    def load_weights(self, tensors: dict[str, np.ndarray], source: str) -> None: ...


A = TypeVar("A", bound=SavedAgent)


def architecture(agent: SavedAgent) -> dict[str, Any]:
    """What a model file must match to be loaded into ``agent``: for a box also ``action_space`` (its
    bounds; ``n_actions`` is 0). A discrete agent's is what it has always been, so the model files written
    before continuous actions load unchanged."""
    arch: dict[str, Any] = {
        "obs_dim": agent.obs_dim,
        "n_actions": agent.n_actions,
        "hidden": list(agent.config.hidden),
        "activation": agent.config.activation,
    }
    if not agent.action_space.is_discrete:
        arch["action_space"] = agent.action_space.to_dict()
    return arch


def save_agent(agent: SavedAgent, path: str | Path) -> None:
    """Write ``agent``'s network weights with its config, architecture and seed."""
    tensors = {name: t.detach().numpy().copy() for name, t in agent.net.state_dict().items()}
    metadata = {"architecture": architecture(agent), "config": agent.config.to_dict(), "seed": agent.seed}
    write_checkpoint(path, tensors, metadata)


def load_agent(
    build: Callable[[int, ActionSpace, PPOConfig, int], A],
    path: str | Path,
    obs_dim: int | None = None,
    n_actions: int | None = None,
    action_space: ActionSpace | None = None,
) -> A:
    """The agent ``build(obs_dim, action_space, config, seed)`` makes from a model file's metadata (discrete
    actions when the file names none), with its weights; ``obs_dim``/``n_actions``/``action_space``, if
    given, must match it.

    :raises FileNotFoundError: no file at ``path``
    :raises CheckpointError: corrupt file, not a fleetrl model, or a model for another architecture
    """
    tensors, metadata = read_checkpoint(path)
    try:
        arch = metadata["architecture"]
        config = PPOConfig.from_dict(metadata["config"])
        space = ActionSpace.from_architecture(arch)
        agent = build(int(arch["obs_dim"]), space, config, int(metadata.get("seed", 0)))
    except (KeyError, TypeError, ValueError) as exc:
        raise CheckpointError(f"{path}: fleetrl metadata is incomplete or invalid ({exc})") from exc
    check_architecture(path, architecture(agent), {"obs_dim": obs_dim, "n_actions": n_actions})
    if action_space is not None and action_space != agent.action_space:
        raise CheckpointError(
            f"{path} is a model for actions {agent.action_space}, but {action_space} is needed here "
            "(a model trained for another environment)"
        )
    agent.load_weights(tensors, str(path))
    return agent
