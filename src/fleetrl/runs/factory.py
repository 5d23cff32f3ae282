"""Building a worker's learner (env + PPO agent + completion criterion) from its spec."""

from typing import Any

import gymnasium
import torch

from fleetrl.agent.action_space import ActionSpace
from fleetrl.agent.config import PPOConfig
from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.learner import Learner
from fleetrl.agent.ppo import PPOAgent
from fleetrl.envs.catalog import UnitDescription, describe_env, get_env_spec
from fleetrl.envs.wrappers import PacedEnv, StalledEnv
from fleetrl.link.mqtt import MqttLink, open_mqtt_link
from fleetrl.runs.spec import WorkerSpec
from fleetrl.runs.uneven import unit_stall
from fleetrl.transport.base import Transport


def action_space_of(unit: UnitDescription) -> ActionSpace:
    """The agent's action space for ``unit``'s: Discrete n (a softmax head) or a 1-D Box (a Gaussian head)."""
    return ActionSpace.of_unit(unit.action)


def agent_for(unit: UnitDescription, config: PPOConfig, seed: int) -> PPOAgent:
    """A PPO agent of ``unit``'s shapes (the one place that maps a unit's spaces to the agent's).

    :raises ValueError: the unit's actions are not a space the agent handles (named, with what is)
    """
    return PPOAgent(unit.obs_dim, action_space_of(unit), config, seed=seed)


def bridge_link(env: str, url: str, run_id: str, unit: int, transport: Transport | None = None) -> MqttLink:
    """A device link to the bridge serving ``unit`` of run ``run_id``: over ``transport`` (a role's login and
    TLS files), else over a plain transport to ``url``. Every state must have the size ``env`` reads.

    :raises DeviceTimeoutError: no bridge announced itself in time (a ``TimeoutError`` naming the unit)
    """
    obs_size = describe_env(env).sensor_dim
    if transport is None:
        return open_mqtt_link(url, run_id, unit, obs_size=obs_size)
    return MqttLink(transport, run_id, unit, obs_size=obs_size)


def make_learner(spec: WorkerSpec, device_transport: Transport | None = None) -> Learner:
    """The learner for one worker: its unit's env, a seeded agent with the preset (and overrides).

    With ``spec.device_url`` the unit is driven through its device bridge, over ``device_transport`` (a
    role's login and TLS files) or else a plain transport to that URL.

    Under a scheme whose mature workers stay in the federation (``fedavg``) the learner keeps learning after
    its criterion holds; under one that needs a shared start (``pergrad``) every worker's network starts from
    the one the run's seed draws (its actions and windows still come from its own seed).

    A unit paced in real time (``spec.uneven.step_seconds``) has its env wrapped in a
    :class:`~fleetrl.envs.paced.PacedEnv`, a stalling one (``spec.uneven.stall``) in a
    :class:`~fleetrl.envs.stalled.StalledEnv`.
    """
    torch.set_num_threads(1)
    learning = spec.learning
    env, unit = unit_env(spec, device_transport)
    config = learning.ppo()
    agent = agent_for(unit, config, seed=spec.worker_seed)
    scheme = learning.federation_scheme()
    if scheme.shared_start:  # every worker from the same initial network: the run's, not its own
        agent.set_model_parameters(agent_for(unit, config, seed=learning.seed).model_parameters())
    criterion = unit_criterion(spec, unit)
    return Learner(env, agent, criterion, seed=spec.worker_seed, keep_learning=scheme.stays_after_completion)


def unit_env(
    spec: WorkerSpec, device_transport: Transport | None = None
) -> tuple[gymnasium.Env[Any, Any], UnitDescription]:
    """The env of the spec's unit and its description: simulated in-process, or through its device bridge
    (``spec.device_url``, over ``device_transport`` or a plain transport), paced and stalling if its spec
    says so."""
    learning = spec.learning
    env_spec, last_step = get_env_spec(learning.env), learning.ppo().last_step
    if spec.device_url is None:
        env, unit = env_spec.make(
            spec.unit, learning.fleet_seed, fleet_profile=learning.fleet_profile, last_step=last_step
        )
    else:  # the device bridge draws the unit (with the same fleet profile)
        link = bridge_link(learning.env, spec.device_url, spec.device_run_id, spec.unit, device_transport)
        env, unit = env_spec.make(spec.unit, learning.fleet_seed, link=link, last_step=last_step)
    if spec.uneven is not None and spec.uneven.step_seconds is not None:
        env = PacedEnv(env, spec.uneven.step_seconds, reset_scale=spec.uneven.reset_scale)
    stall = unit_stall(spec.uneven, seed=learning.seed, worker=spec.worker)
    if stall is not None:
        env = StalledEnv(env, stall.wait)
    return env, unit


def unit_criterion(spec: WorkerSpec, unit: UnitDescription) -> CompletionCriterion:
    """The completion criterion of the spec's unit: the run's target score, or the unit type's own."""
    learning = spec.learning
    target = learning.target_score
    return CompletionCriterion(
        target if target is not None else get_env_spec(learning.env).default_target(unit)
    )


def probe_agent(env: str, config: PPOConfig) -> PPOAgent:
    """An agent of the shapes of ``env`` with ``config`` (seed 0): what a scheme's layout and step count are
    read from before any worker exists. Built on one thread: its initial weights are not used, and a
    multi-threaded orthogonal init on a loaded machine took 0.5 s instead of 10 ms."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        return agent_for(describe_env(env, config.last_step), config, seed=0)
    finally:
        torch.set_num_threads(threads)
