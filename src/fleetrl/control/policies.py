"""Greedy policies a unit runs without torch: a fleetrl model file on numpy (numba), or an exported ONNX file
on onnxruntime (the ``onnx`` extra), behind one small interface; and the greedy episodes ``fleetrl evaluate``
and ``fleetrl control`` play."""

from __future__ import annotations

import functools
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import gymnasium
import numpy as np

from fleetrl.agent.action_space import ActionSpace
from fleetrl.agent.policy_file import PolicyFile, read_policy_file
from fleetrl.envs.catalog import UnitDescription

ONNX_HINT = "pip install 'fleetrl[onnx]'"


class GreedyPolicy(Protocol):
    """Observation → the greedy action: an action index (discrete) or a float32 command vector (a box)."""

    obs_dim: int
    action_space: ActionSpace
    env: str | None  # the env the policy names (an exported file's metadata; None: not recorded)
    last_step: bool  # its observation holds the unit's last step (:class:`~fleetrl.envs.wrappers.LastStep`)

    def act(self, obs: np.ndarray) -> Any:
        """The greedy action for one observation."""
        ...


class ModelPolicy:
    """A model file's actor on the numba kernels ``PPOAgent.act_greedy`` runs: the same actions."""

    env: str | None = None

    def __init__(self, policy: PolicyFile) -> None:
        self.obs_dim = policy.obs_dim
        self.action_space = policy.action_space
        self.last_step = policy.last_step
        numpy_policy = policy.numpy_policy()
        greedy = functools.partial(numpy_policy.act_continuous, z=None)
        self._act = numpy_policy.act_greedy if self.action_space.is_discrete else greedy

    def act(self, obs: np.ndarray) -> Any:
        """The arg-max action index, or the Gaussian's mean clipped to the box."""
        return self._act(obs)


class OnnxPolicy:
    """An exported policy (``fleetrl export``) on onnxruntime, one thread; a ValueError for another file."""

    def __init__(self, path: str | Path) -> None:
        try:
            import onnxruntime
        except ImportError:
            raise ValueError(f"running an ONNX policy needs onnxruntime: {ONNX_HINT}") from None
        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads = options.inter_op_num_threads = 1
        try:
            self._session = onnxruntime.InferenceSession(
                str(path), options, providers=["CPUExecutionProvider"]
            )
        except Exception as err:  # onnxruntime raises its own exception types for an unreadable file
            raise ValueError(f"{path} is not an ONNX model onnxruntime can load ({err})") from None
        raw = self._session.get_modelmeta().custom_metadata_map.get("fleetrl")
        try:
            meta: dict[str, Any] = json.loads(raw) if raw is not None else {}
            self.obs_dim = int(meta["obs_dim"])
            self.action_space = ActionSpace.from_dict(meta["action_space"])
        except (TypeError, KeyError, ValueError, AttributeError):
            raise ValueError(
                f"{path} is an ONNX model but not a policy fleetrl exported (no valid 'fleetrl' metadata); "
                "export one with: fleetrl export MODEL --out policy.onnx"
            ) from None
        self.env: str | None = meta.get("env")
        self.last_step = bool(meta.get("last_step", False))
        self._input = self._session.get_inputs()[0].name
        self._batch = np.zeros((1, self.obs_dim), dtype=np.float32)

    def act_batch(self, observations: np.ndarray) -> np.ndarray:
        """The actions for a batch of observations (n, obs_dim): int64 (n,) or float32 (n, dim)."""
        batch = np.ascontiguousarray(observations, dtype=np.float32)
        return np.asarray(self._session.run(None, {self._input: batch})[0])

    def act(self, obs: np.ndarray) -> Any:
        """The greedy action for one observation: a plain int index, or a float32 vector."""
        self._batch[0] = np.asarray(obs, dtype=np.float32).reshape(-1)
        action = self._session.run(None, {self._input: self._batch})[0][0]
        return int(action) if self.action_space.is_discrete else np.asarray(action, dtype=np.float32)


def load_policy(path: str | Path) -> GreedyPolicy:
    """The greedy policy in ``path``: a fleetrl model file (``.safetensors``) or an exported ``.onnx``."""
    source = Path(path)
    if not source.is_file():
        raise FileNotFoundError(f"no model file at {source}")
    if source.suffix == ".onnx":
        return OnnxPolicy(source)
    if source.suffix != ".safetensors":
        raise ValueError(
            f"{source}: give a fleetrl model file (models/worker-K.safetensors) or an exported policy (.onnx)"
        )
    return ModelPolicy(read_policy_file(source))


def check_fits(
    obs_dim: int, actions: ActionSpace, description: UnitDescription, env: str, source: object = "the policy"
) -> None:
    """A ValueError, naming ``source``, unless a policy of this size and ``actions`` fits ``env``'s units."""
    wanted = ActionSpace.of_unit(description.action)
    if (obs_dim, actions) != (description.obs_dim, wanted):
        raise ValueError(
            f"{source} is a policy for {obs_dim} observations and {actions} actions; env {env!r} has "
            f"{description.obs_dim} and {wanted} (choose the env it was trained on: --env)"
        )


def greedy_scores(
    env: gymnasium.Env[Any, Any],
    act: Callable[[np.ndarray], Any],
    episodes: int,
    seed: int = 0,
    report: Callable[[int, float], None] | None = None,
) -> list[float]:
    """The scores of ``episodes`` episodes of ``env`` played by ``act``, episode ``k`` seeded ``seed + k``."""
    scores = []
    for episode in range(episodes):
        obs, _ = env.reset(seed=seed + episode)
        score, done = 0.0, False
        while not done:
            obs, reward, terminated, truncated, _ = env.step(act(obs))
            score += float(reward)
            done = terminated or truncated
        scores.append(score)
        if report is not None:
            report(episode, score)
    return scores
