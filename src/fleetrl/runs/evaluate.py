"""A saved policy on one unit: loaded and checked against the env's shapes, run greedily."""

from collections.abc import Callable
from pathlib import Path

import torch

from fleetrl.agent.ppo import PPOAgent
from fleetrl.control.policies import check_fits, greedy_scores
from fleetrl.envs.catalog import EnvSpec, UnitDescription, describe_env, get_env_spec
from fleetrl.link.base import DeviceLink


def load_policy(model: Path, env: str) -> tuple[EnvSpec, PPOAgent, UnitDescription]:
    """The env's spec, the saved agent in ``model`` and a unit's description, the agent checked to fit it.

    :raises FileNotFoundError: no such model file
    :raises ValueError: the file is not a fleetrl model, or it was made for another env's shapes
    """
    if not Path(model).is_file():
        raise FileNotFoundError(f"no model file at {model}")
    torch.set_num_threads(1)
    spec = get_env_spec(env)
    describe_env(env)  # a bad factory fails before the model is read
    agent = PPOAgent.load(model)
    description = describe_env(env, agent.config.last_step)
    check_fits(agent.obs_dim, agent.action_space, description, env, model)
    return spec, agent, description


def evaluate_model(
    model: Path,
    env: str,
    unit: int,
    fleet_seed: int,
    episodes: int,
    seed: int = 0,
    fleet_profile: str | None = None,
    open_link: Callable[[], DeviceLink] | None = None,
) -> list[float]:
    """Scores of ``episodes`` greedy episodes of the saved policy on ``unit`` (of fleet ``fleet_seed`` drawn
    with ``fleet_profile``), or on the device at the other end of the link ``open_link`` opens once the
    model is checked (:func:`load_policy`)."""
    if episodes < 1:
        raise ValueError(f"--episodes must be at least 1, got {episodes}")
    spec, agent, _ = load_policy(model, env)
    last_step = agent.config.last_step
    if open_link is None:
        gym_env, _ = spec.make(unit, fleet_seed, fleet_profile=fleet_profile, last_step=last_step)
    else:
        gym_env, _ = spec.make(unit, fleet_seed, link=open_link(), last_step=last_step)
    try:
        return greedy_scores(gym_env, agent.act_greedy, episodes, seed)
    finally:
        gym_env.close()
