"""Saved policies for the on-unit tests, made in a moment without training.

``balancing_model`` writes a model file whose actor *is* Quanser's linear balance law V = −K·x: the first
trunk layer's first unit computes −K·x (the observation is [alpha, alpha_dot, theta, theta_dot]), the other
two layers pass it on (tanh keeps its sign), the policy head turns it into the action. Discrete: the
logits −h, 0, +h, so the argmax is the paper's ±1.44 V the way the law's sign says (a bang-bang law, which
holds the pendulum: ``tests/link/test_qube_spi_bridge.py``); continuous: the mean ≈ V (the law itself,
saturating within the ±3 V box). Everything else is the standard preset's network, as saved by
``PPOAgent.save``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import torch

from fleetrl.agent.config import get_preset
from fleetrl.agent.ppo import PPOAgent
from fleetrl.devices.qube.controllers import K_ALPHA, K_ALPHA_DOT, K_THETA, K_THETA_DOT, controller_constants
from fleetrl.envs.catalog import describe_env
from fleetrl.runs.factory import agent_for

SCALE = 0.1
"""the first layer computes SCALE·(−K·x): inside tanh's near-linear range for small errors"""


def fresh_model(path: Path, env: str, seed: int, last_step: bool = False) -> Path:
    """An untrained agent of ``env``'s shapes (its observation with the last step if ``last_step``), saved;
    its policy head is scaled up so its greedy actions vary from state to state (an untrained head is
    near-uniform: its argmax would hardly change)."""
    config = dataclasses.replace(get_preset("standard"), last_step=last_step)
    agent = agent_for(describe_env(env, last_step), config, seed=seed)
    with torch.no_grad():
        agent.net.policy.weight.mul_(100.0)
    agent.refresh_policy()
    agent.save(path)
    return path


def balancing_model(path: Path, env: str, own_part: str = "none") -> Path:
    """A model file of ``env`` (``qube`` or ``qube-continuous``) whose greedy policy is the balance law. With
    an ``own_part`` of ``heads``: a unit's model whose shared policy head is zero, its own offset the law's
    head (the fleet's shared policy alone does not balance; the unit's own does)."""
    preset = dataclasses.replace(get_preset("standard"), own_part=own_part)
    agent: PPOAgent = agent_for(describe_env(env), preset, seed=0)
    k = controller_constants()
    law = [-k[K_ALPHA], -k[K_ALPHA_DOT], -k[K_THETA], -k[K_THETA_DOT]]  # −K·x in observation order
    net = agent.net
    with torch.no_grad():
        for layer in [*net.trunk_layers, net.policy]:
            layer.weight.zero_()
            layer.bias.zero_()
        net.trunk_layers[0].weight[0] = SCALE * torch.tensor(law)
        for layer in net.trunk_layers[1:]:
            layer.weight[0, 0] = 1.0
        if agent.action_space.is_discrete:
            net.policy.weight[:, 0] = torch.tensor([-10.0, 0.0, 10.0])
        else:  # mean = half_range · w · h with h ≈ SCALE·V: w = 1 / (half_range · SCALE) gives mean ≈ V
            half = float(agent.action_space.half_range()[0])
            net.policy.weight[0, 0] = 1.0 / (half * SCALE)
        if own_part == "heads":
            net.own["policy_weight"].copy_(net.policy.weight)
            net.policy.weight.zero_()
    agent.refresh_policy()
    agent.save(path)
    return path
