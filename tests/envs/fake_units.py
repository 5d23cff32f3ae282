"""A user's own unit type, as the tests name it: ``--env tests.envs.fake_units:factory``, and broken ones.

``factory`` is what a user writes: Gymnasium's CartPole-v1 with each unit's pole length drawn from the fleet
seed (±10 %). The others fail the seam's checks one way each.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np

FACTORY = "tests.envs.fake_units:factory"


def pole_length(unit: int, fleet_seed: int) -> float:
    """Unit ``unit``'s pole half-length in fleet ``fleet_seed``."""
    return 0.5 * float(np.random.default_rng([fleet_seed, unit]).uniform(0.9, 1.1))


def factory(unit: int, fleet_seed: int) -> gymnasium.Env[Any, Any]:
    """Unit ``unit`` of fleet ``fleet_seed``: CartPole-v1 (its TimeLimit 500, reward_threshold 475) with its
    own pole."""
    env = gymnasium.make("CartPole-v1")
    cartpole: Any = env.unwrapped
    cartpole.length = pole_length(unit, fleet_seed)
    cartpole.polemass_length = cartpole.masspole * cartpole.length
    return env


class SpacesEnv(gymnasium.Env[Any, Any]):
    """An env with the given spaces that ends every episode after one step (no spec: built directly)."""

    def __init__(self, observation_space: gymnasium.Space[Any], action_space: gymnasium.Space[Any]) -> None:
        self.observation_space = observation_space
        self.action_space = action_space

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> Any:
        """The observation space's sample."""
        super().reset(seed=seed)
        return self.observation_space.sample(), {}

    def step(self, action: Any) -> Any:
        """Reward 1, and the episode is over."""
        return self.observation_space.sample(), 1.0, True, False, {}


FLOATS = gymnasium.spaces.Box(-1.0, 1.0, (4,), np.float32)


def no_threshold(unit: int, fleet_seed: int) -> SpacesEnv:
    """Supported spaces, but no env spec: no reward_threshold to default the target to."""
    return SpacesEnv(FLOATS, gymnasium.spaces.Discrete(2))


def not_an_env(unit: int, fleet_seed: int) -> dict[str, int]:
    """Returns something that is not a gymnasium.Env."""
    return {"unit": unit}


def raising(unit: int, fleet_seed: int) -> gymnasium.Env[Any, Any]:
    """Fails to build any unit."""
    raise RuntimeError(f"no unit {unit} on the bus")


def only_unit_0(unit: int, fleet_seed: int) -> gymnasium.Env[Any, Any]:
    """Builds unit 0 (the one settings validation checks) and fails on any other."""
    if unit > 0:
        raise RuntimeError(f"no unit {unit} on the bus")
    return factory(unit, fleet_seed)


def image_observations(unit: int, fleet_seed: int) -> SpacesEnv:
    """A 2-D observation."""
    return SpacesEnv(gymnasium.spaces.Box(0.0, 1.0, (8, 8), np.float32), gymnasium.spaces.Discrete(2))


def integer_observations(unit: int, fleet_seed: int) -> SpacesEnv:
    """An integer observation vector."""
    return SpacesEnv(gymnasium.spaces.Box(0, 9, (4,), np.int64), gymnasium.spaces.Discrete(2))


def multi_discrete_actions(unit: int, fleet_seed: int) -> SpacesEnv:
    """Two discrete choices at once."""
    return SpacesEnv(FLOATS, gymnasium.spaces.MultiDiscrete([2, 3]))


def unbounded_actions(unit: int, fleet_seed: int) -> SpacesEnv:
    """A 1-D Box action without bounds: the Gaussian head scales its mean to the box, so it needs one."""
    return SpacesEnv(FLOATS, gymnasium.spaces.Box(-np.inf, np.inf, (1,), np.float32))


def fractional_sensor_size(unit: int, fleet_seed: int) -> SpacesEnv:
    """Declares the length of its device's sensor vector as something that is not a length."""
    env = SpacesEnv(FLOATS, gymnasium.spaces.Discrete(2))
    env.sensor_size = 2.5  # type: ignore[attr-defined]
    return env


NOT_CALLABLE = 42
"""not a factory"""
