"""A learner's state as JSON fields and tensors (weights, Adam states, memory, RNG states), to checkpoint
between rounds and resume exactly where it stopped."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from fleetrl.agent.learner import Learner
from fleetrl.agent.ppo import PPOAgent

STATE_VERSION = 1  # :func:`load_learner_state` refuses any other


def agent_state(agent: PPOAgent) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """(fields, tensors) of one agent: weights, Adam states, trajectory memory, RNG states."""
    tensors = {f"net.{k}": v.detach().numpy().copy() for k, v in agent.net.state_dict().items()}
    steps: dict[str, dict[str, float]] = {}
    for which, optimiser in agent.optimisers().items():
        state = optimiser.state_dict()["state"]
        steps[which] = {}
        for index, slots in state.items():
            for slot, value in slots.items():
                if slot == "step":  # a scalar (a tensor in recent torch): keep it exact in JSON
                    steps[which][str(index)] = float(value)
                else:
                    tensors[f"optim.{which}.{index}.{slot}"] = value.detach().numpy().copy()
    tensors.update({f"memory.{k}": v for k, v in agent.memories[0].state_arrays().items()})
    return {"optimiser_steps": steps, "rng": agent.rng_states()}, tensors


def load_agent_state(agent: PPOAgent, fields: dict[str, Any], tensors: dict[str, np.ndarray]) -> None:
    """Restore :func:`agent_state` into an agent of the same architecture and configuration (else
    ValueError)."""
    net = agent.net.state_dict()
    weights = {k: _tensor(tensors, f"net.{k}", tuple(v.shape)) for k, v in net.items()}
    agent.net.load_state_dict(weights)
    for which, optimiser in agent.optimisers().items():
        current = optimiser.state_dict()
        restored: dict[int, dict[str, torch.Tensor]] = {}
        for index_text, step in fields["optimiser_steps"][which].items():
            index = int(index_text)
            slots = {"step": torch.tensor(float(step))}
            for slot in ("exp_avg", "exp_avg_sq"):
                slots[slot] = _tensor(tensors, f"optim.{which}.{index}.{slot}", None)
            restored[index] = slots
        optimiser.load_state_dict({"state": restored, "param_groups": current["param_groups"]})
    memory = {k.removeprefix("memory."): v for k, v in tensors.items() if k.startswith("memory.")}
    agent.memories[0].load_state_arrays(memory)
    agent.load_rng_states(fields["rng"])
    agent.refresh_policy()


def learner_state(learner: Learner) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """(fields, tensors) of a learner between rounds: its agent, criterion, round counter and env RNG."""
    fields, tensors = agent_state(learner.agent)
    tensors["torch.rng"] = torch.get_rng_state().numpy().copy()
    fields.update(
        version=STATE_VERSION,
        rounds=learner.rounds,
        episodes=learner.episodes,
        completed=learner.completed,
        criterion=learner.criterion.history(),
        env_rng=_env_generator(learner).bit_generator.state,
    )
    return fields, tensors


def load_learner_state(learner: Learner, fields: dict[str, Any], tensors: dict[str, np.ndarray]) -> None:
    """Restore :func:`learner_state` into a learner built the same way (env, preset, seed)."""
    if fields.get("version") != STATE_VERSION:
        raise ValueError(f"learner state version {fields.get('version')!r}, expected {STATE_VERSION}")
    load_agent_state(learner.agent, fields, tensors)
    torch.set_rng_state(torch.from_numpy(np.asarray(tensors["torch.rng"], dtype=np.uint8).copy()))
    learner.rounds = int(fields["rounds"])
    learner.unit_episodes = [int(fields.get("episodes", learner.rounds))]  # states before rounds of episodes
    learner.completed_once = [bool(fields["completed"])]
    learner.criterion.load_history([float(s) for s in fields["criterion"]])
    _env_generator(learner).bit_generator.state = fields["env_rng"]


def _env_generator(learner: Learner) -> np.random.Generator:
    """The env's ``np_random`` (created now, from entropy, if the env was never reset)."""
    generator: np.random.Generator = learner.env.unwrapped.np_random
    return generator


def _tensor(tensors: dict[str, np.ndarray], name: str, shape: tuple[int, ...] | None) -> torch.Tensor:
    if name not in tensors:
        raise ValueError(f"state has no tensor {name!r} (written for another architecture?)")
    value = np.asarray(tensors[name])
    if shape is not None and tuple(value.shape) != shape:
        raise ValueError(f"state tensor {name!r} has shape {tuple(value.shape)}, expected {shape}")
    return torch.from_numpy(value.copy())
