"""Model files: safetensors tensors with JSON metadata (never pickle), and an agent saved as one (its weights
with the config, the architecture and the seed as metadata). No torch: a policy is read without it."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

import numpy as np
from safetensors import SafetensorError
from safetensors.numpy import load_file, save_file

from fleetrl.agent.action_space import ActionSpace
from fleetrl.agent.config import PPOConfig

if TYPE_CHECKING:
    from torch import nn

FORMAT = "fleetrl.agent/1"  # the ``format`` metadata key of every model file


class CheckpointError(ValueError):
    """A checkpoint file that cannot be used: unreadable, not an agent, or for another architecture."""


def write_checkpoint(path: str | Path, tensors: dict[str, np.ndarray], metadata: dict[str, Any]) -> None:
    """Write ``tensors`` and ``metadata`` (one JSON string under ``fleetrl``) to ``path``, through a file
    beside it renamed into place (a crash never leaves half a model)."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    header = {"format": FORMAT, "fleetrl": json.dumps(metadata, sort_keys=True)}
    contiguous = {name: np.ascontiguousarray(t) for name, t in tensors.items()}
    partial = target.with_name(target.name + ".partial")
    save_file(contiguous, str(partial), metadata=header)
    partial.replace(target)


def read_checkpoint(path: str | Path) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Tensors and metadata of a checkpoint written by :func:`write_checkpoint` (FileNotFoundError, or
    CheckpointError if it is not a readable fleetrl model)."""
    source = Path(path)
    if not source.is_file():
        raise FileNotFoundError(f"no model file at {source}")
    try:
        tensors = load_file(str(source))
        with open(source, "rb") as handle:
            header_len = int.from_bytes(handle.read(8), "little")
            header = json.loads(handle.read(header_len))
    except (SafetensorError, OSError, ValueError) as exc:
        raise CheckpointError(f"{source} is not a readable safetensors model file ({exc})") from exc
    raw = header.get("__metadata__") or {}
    if raw.get("format") != FORMAT or "fleetrl" not in raw:
        raise CheckpointError(
            f"{source} is a safetensors file but not a fleetrl agent model (format {FORMAT})"
        )
    try:
        metadata = json.loads(raw["fleetrl"])
    except json.JSONDecodeError as exc:
        raise CheckpointError(f"{source} has unreadable fleetrl metadata ({exc})") from exc
    if not isinstance(metadata, dict):
        raise CheckpointError(f"{source} has fleetrl metadata that is not a JSON object")
    return tensors, metadata


def check_tensors_fit(
    tensors: dict[str, np.ndarray], shapes: dict[str, tuple[int, ...]], source: str
) -> None:
    """CheckpointError naming every missing, unexpected or wrongly shaped tensor of ``source``, if any."""
    problems = [f"missing {k}" for k in shapes if k not in tensors]
    problems += [f"unexpected {k}" for k in tensors if k not in shapes]
    problems += [
        f"{k} has shape {tuple(tensors[k].shape)}, expected {shape}"
        for k, shape in shapes.items()
        if k in tensors and tuple(tensors[k].shape) != shape
    ]
    if problems:
        raise CheckpointError(f"{source} does not fit this architecture: " + "; ".join(problems))


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
    """What a model file must match to be loaded into ``agent`` (for a box also ``action_space``)."""
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
    """The agent ``build(obs_dim, action_space, config, seed)`` makes from a model file, with its weights;
    ``obs_dim``/``n_actions``/``action_space``, if given, must match it (else CheckpointError)."""
    tensors, metadata = read_checkpoint(path)
    try:
        arch = metadata["architecture"]
        config = PPOConfig.from_dict(metadata["config"])
        space = ActionSpace.from_architecture(arch)
        agent = build(int(arch["obs_dim"]), space, config, int(metadata.get("seed", 0)))
    except (KeyError, TypeError, ValueError) as exc:
        raise CheckpointError(f"{path}: fleetrl metadata is incomplete or invalid ({exc})") from exc
    arch = architecture(agent)
    for key, want in (("obs_dim", obs_dim), ("n_actions", n_actions)):
        if want is not None and want != arch[key]:
            raise CheckpointError(
                f"{path} is a model for {key}={arch[key]}, but {want} is needed here "
                "(a model trained for another environment or architecture)"
            )
    if action_space is not None and action_space != agent.action_space:
        raise CheckpointError(
            f"{path} is a model for actions {agent.action_space}, but {action_space} is needed here "
            "(a model trained for another environment)"
        )
    agent.load_weights(tensors, str(path))
    return agent
