"""A saved policy read without torch: the actor of a model file as arrays, run by the same numba kernels as
``PPOAgent.act_greedy`` (so it picks the same actions); the ONNX export builds its graph from them."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fleetrl.agent.action_space import ActionSpace
from fleetrl.agent.checkpoint import CheckpointError, check_tensors_fit, read_checkpoint
from fleetrl.agent.policy_numpy import Layer, NumpyPolicy

ACTIVATIONS = ("tanh", "relu")


@dataclass(frozen=True)
class PolicyFile:
    """The actor of one model file (read from ``source``): its layers, the trunk's then the policy head's, as
    float32 arrays, a Gaussian's log-std (None: discrete), and the ``last_step`` setting it was trained on."""

    source: str
    obs_dim: int
    action_space: ActionSpace
    activation: str
    layers: tuple[Layer, ...]
    log_std: np.ndarray | None
    last_step: bool = False

    def numpy_policy(self) -> NumpyPolicy:
        """The numba acting copy of this actor (what ``PPOAgent`` acts with)."""
        return NumpyPolicy.from_layers(self.layers, self.activation, self.action_space, self.log_std)


def read_policy_file(path: str | Path) -> PolicyFile:
    """The actor of the model file at ``path``, every tensor's shape checked against its architecture
    (FileNotFoundError, or CheckpointError if it is no readable fleetrl model)."""
    tensors, metadata = read_checkpoint(path)
    try:
        arch = metadata["architecture"]
        obs_dim = int(arch["obs_dim"])
        hidden = [int(width) for width in arch["hidden"]]
        activation = str(arch["activation"])
        space = ActionSpace.from_architecture(arch)
        last_step = bool(metadata.get("config", {}).get("last_step", False))
    except (KeyError, TypeError, ValueError) as exc:
        raise CheckpointError(f"{path}: fleetrl metadata is incomplete or invalid ({exc})") from exc
    if obs_dim < 1 or not hidden or min(hidden) < 1 or activation not in ACTIVATIONS:
        raise CheckpointError(f"{path}: fleetrl metadata describes no network this version builds: {arch}")
    tensors = fold_own(tensors, network_shapes(obs_dim, hidden, space), str(path))
    names = [f"trunk.{i}" for i in range(len(hidden))] + ["policy"]
    layers = tuple(_layer(tensors, name) for name in names)
    log_std = None if space.is_discrete else np.asarray(tensors["policy_log_std"], dtype=np.float32)
    arrays = [array for layer in layers for array in layer] + ([] if log_std is None else [log_std])
    if not all(np.all(np.isfinite(array)) for array in arrays):
        raise CheckpointError(f"{path}: the policy's weights hold values that are not finite")
    return PolicyFile(str(path), obs_dim, space, activation, layers, log_std, last_step)


def network_shapes(obs_dim: int, hidden: list[int], space: ActionSpace) -> dict[str, tuple[int, ...]]:
    """Every tensor a model file of this architecture holds, with its shape (``ActorCritic``'s state dict)."""
    widths = [obs_dim, *hidden]
    shapes: dict[str, tuple[int, ...]] = {}
    for i in range(len(hidden)):
        shapes[f"trunk.{i}.weight"] = (widths[i + 1], widths[i])
        shapes[f"trunk.{i}.bias"] = (widths[i + 1],)
    shapes["policy.weight"] = (space.head_size, widths[-1])
    shapes["policy.bias"] = (space.head_size,)
    if not space.is_discrete:
        shapes["policy_log_std"] = (space.dim,)
    shapes["value.weight"] = (1, widths[-1])
    shapes["value.bias"] = (1,)
    return shapes


def fold_own(
    tensors: dict[str, Any], shapes: dict[str, tuple[int, ...]], source: str
) -> dict[str, np.ndarray]:
    """The network's tensors with a unit's own offsets (``own.*``) added to the shared values: the policy that
    unit acts with. CheckpointError if a tensor does not fit ``shapes``."""
    own = {k: v for k, v in tensors.items() if k.startswith("own.")}
    shared = {k: v for k, v in tensors.items() if k not in own}
    check_tensors_fit(shared, shapes, source)
    folded = {k: np.asarray(v, dtype=np.float32) for k, v in shared.items()}
    for key, offset in own.items():
        name = key.removeprefix("own.").replace("_", ".")
        if name not in shapes or tuple(np.shape(offset)) != shapes[name]:
            raise CheckpointError(f"{source}: {key} is no offset of a parameter of this network")
        folded[name] = folded[name] + np.asarray(offset, dtype=np.float32)
    return folded


def _layer(tensors: dict[str, Any], name: str) -> Layer:
    weight = np.asarray(tensors[f"{name}.weight"], dtype=np.float32)
    return weight, np.asarray(tensors[f"{name}.bias"], dtype=np.float32)
