"""Building a worker's learner (env + PPO agent + completion criterion) from its spec."""

import dataclasses

import gymnasium
import torch

from fleetrl.agent.config import PPOConfig, get_preset
from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.learner import Learner
from fleetrl.agent.ppo import PPOAgent
from fleetrl.envs.catalog import get_env_spec
from fleetrl.federation.schemes import get_scheme
from fleetrl.link.mqtt import open_mqtt_link
from fleetrl.runs.spec import WorkerSpec


def make_learner(spec: WorkerSpec) -> Learner:
    """The learner for one worker: its unit's env, a seeded agent with the preset (and overrides).

    Under a scheme whose mature workers stay in the federation (``fedavg``) the learner keeps learning after
    its criterion holds; under one that needs a shared start (``pergrad``) every worker's network starts from
    the one the run's seed draws (its actions and windows still come from its own seed).
    """
    torch.set_num_threads(1)
    env_spec = get_env_spec(spec.env)
    config = dataclasses.replace(get_preset(spec.preset), **spec.overrides)
    if spec.device_url is None:
        fleet = env_spec.make_kwargs(spec.fleet_profile)
        env = gymnasium.make(env_spec.gym_id, unit=spec.unit, fleet_seed=spec.fleet_seed, **fleet)
    else:  # the device bridge draws the unit (with the same fleet profile)
        link = open_mqtt_link(spec.device_url, spec.device_run_id, spec.unit)
        env = gymnasium.make(env_spec.gym_id, unit=spec.unit, fleet_seed=spec.fleet_seed, link=link)
    obs_dim = int(env.observation_space.shape[0])  # type: ignore[index]
    n_actions = int(env.action_space.n)  # type: ignore[attr-defined]
    agent = PPOAgent(obs_dim, n_actions, config, seed=spec.worker_seed)
    scheme = get_scheme(spec.scheme, **spec.scheme_params)
    if scheme.shared_start:  # every worker from the same initial network: the run's, not its own
        agent.set_model_parameters(PPOAgent(obs_dim, n_actions, config, seed=spec.seed).model_parameters())
    criterion = CompletionCriterion(env_spec.completion_threshold)
    return Learner(env, agent, criterion, seed=spec.worker_seed, keep_learning=scheme.stays_after_completion)


def probe_agent(env: str, config: PPOConfig) -> PPOAgent:
    """An agent of the shapes of ``env`` with ``config`` (seed 0): what a scheme's layout and step count are
    read from before any worker exists."""
    gym_env = gymnasium.make(get_env_spec(env).gym_id)
    obs_dim = int(gym_env.observation_space.shape[0])  # type: ignore[index]
    n_actions = int(gym_env.action_space.n)  # type: ignore[attr-defined]
    gym_env.close()
    return PPOAgent(obs_dim, n_actions, config, seed=0)
