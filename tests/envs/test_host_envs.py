"""A unit host's envs: in-process CartPoles stepped in one batch, in-process QUBEs in another, every other
unit through its own env, and every unit's steps what its own env gives alone; a host of such mixed units
plays its first round as each unit's own learner would."""

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

import gymnasium
import numpy as np
import pytest

from fleetrl.agent.config import get_preset
from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.learner import Learner
from fleetrl.agent.ppo import PPOAgent
from fleetrl.agent.row_acting import FEW_ROWS
from fleetrl.devices.cartpole import CartPoleDevice
from fleetrl.envs.cartpole_unit import CartPoleUnitEnv
from fleetrl.envs.host_envs import HostEnvs, batched_device
from fleetrl.envs.qube_balance import QubeBalanceEnv
from fleetrl.envs.registration import CARTPOLE_UNIT_ID, QUBE_BALANCE_CONTINUOUS_ID, QUBE_BALANCE_ID
from fleetrl.envs.wrappers import PacedEnv
from fleetrl.link.base import NO_INFO


class ForwardingLink:
    """A link that is not the in-process one (as a device bridge's is not): the unit is stepped alone."""

    def __init__(self, device: CartPoleDevice) -> None:
        self.device = device

    def reset(self, seed: int | None = None) -> np.ndarray:
        return self.device.reset(seed)

    def step(self, action: Any) -> tuple[np.ndarray, Mapping[str, float]]:
        return self.device.step(action), NO_INFO

    def close(self) -> None:
        self.device.close()


def unit_envs(cap: int | None = 15, units: int = 6) -> list[gymnasium.Env[Any, Any]]:
    """Units 0 … ``units`` - 1 of fleet 0: unit 2 behind a link of its own, unit 4 paced (both stepped
    alone), the others in-process (batched); episodes capped at ``cap`` steps (None: the registered 500)."""
    limit = {} if cap is None else {"max_episode_steps": cap}
    envs = [gymnasium.make(CARTPOLE_UNIT_ID, unit=u, fleet_seed=0, **limit) for u in range(units)]
    envs[2] = gymnasium.make(
        CARTPOLE_UNIT_ID, unit=2, fleet_seed=0, link=ForwardingLink(CartPoleDevice.from_fleet(2, 0)), **limit
    )
    envs[4] = PacedEnv(envs[4], 1e-6)
    return envs


def qube_envs(cap: int = 40, units: int = 5) -> list[gymnasium.Env[Any, Any]]:
    """QUBE units 0 … ``units`` - 1 of fleet 0, unit 1 paced (stepped alone), episodes capped at ``cap``."""
    limit = {"max_episode_steps": cap}
    envs = [gymnasium.make(QUBE_BALANCE_ID, unit=u, fleet_seed=0, **limit) for u in range(units)]
    envs[1] = PacedEnv(envs[1], 1e-6)
    return envs


def test_only_in_process_cartpoles_and_qubes_are_batched() -> None:
    assert HostEnvs(unit_envs()).batched.tolist() == [0, 1, 3, 5]
    assert HostEnvs(unit_envs() + qube_envs(units=3)).batched.tolist() == [0, 1, 3, 5, 6, 8]
    rendered = gymnasium.make(CARTPOLE_UNIT_ID, unit=0, fleet_seed=0, render_mode="rgb_array")
    assert batched_device(rendered) is None
    assert batched_device(CartPoleUnitEnv(1, 0)) is not None  # no TimeLimit: never truncated
    assert batched_device(QubeBalanceEnv(1, 0)) is not None
    assert batched_device(gymnasium.make(QUBE_BALANCE_CONTINUOUS_ID, unit=0, fleet_seed=0)) is None


@pytest.mark.parametrize(
    ("envs", "steps"),
    [(unit_envs, 400), (lambda: unit_envs() + qube_envs(units=3), 300)],
    ids=["cartpoles", "cartpoles-and-qubes"],
)
def test_every_unit_steps_as_its_env_alone_bit_for_bit(
    envs: Callable[[], list[gymnasium.Env[Any, Any]]], steps: int
) -> None:
    host, alone = HostEnvs(envs()), envs()
    rng = np.random.default_rng(7)
    for u, env in enumerate(alone):
        assert np.array_equal(host.reset(u, 100 + u), env.reset(seed=100 + u)[0])
    ends = truncations = 0
    for _ in range(steps):
        units = np.flatnonzero(rng.random(len(alone)) < 0.8)
        actions = rng.integers(0, 2, size=units.size)  # a push either way, or QUBE power -60 and 0
        step = host.step(units, actions)
        for j, u in enumerate(units.tolist()):
            next_obs, reward, terminated, truncated, _ = alone[u].step(int(actions[j]))
            assert np.array_equal(step.obs[j], next_obs)
            assert (step.rewards[j], step.terminated[j], step.truncated[j]) == (reward, terminated, truncated)
            if terminated or truncated:
                ends += 1
                truncations += int(truncated)
                first = host.reset(u, None)
                assert np.array_equal(first, alone[u].reset()[0])
    assert ends > 30 and 0 < truncations < ends  # episodes end both ways, in the batch and alone


def test_judge_rows_judges_each_row_as_judge_does() -> None:
    rng = np.random.default_rng(8)
    limits = np.array([2.4, 1.0, 12 * 2 * np.pi / 360, 1.0], dtype=np.float32)
    obs = (limits * rng.choice([-1, 1], size=(2000, 4))).astype(np.float32)
    obs += (
        rng.choice([0.0, 1.0], size=(2000, 1)).astype(np.float32)
        * np.spacing(obs)
        * rng.integers(-2, 3, size=(2000, 4))
    )
    obs[:5, 0] = np.nan
    rewards, terminated = CartPoleUnitEnv.judge_rows(obs)
    env = CartPoleUnitEnv(0, 0)
    assert [(r, t) for r, t in zip(rewards, terminated, strict=True)] == [env.judge(o) for o in obs]
    assert 0 < terminated.sum() < 2000


def test_a_host_of_mixed_units_plays_its_first_round_as_each_unit_alone() -> None:
    config = dataclasses.replace(
        get_preset("standard"), hidden=(16, 16), memory_size=60, batch_size=32, trajectory_memory="per_round"
    )
    seeds = [30 + u for u in range(FEW_ROWS + 4)]  # enough units to act by matrix products
    agent = PPOAgent(4, 2, config, seeds)
    host = Learner(unit_envs(None, len(seeds)), agent, [CompletionCriterion(1e9) for _ in seeds], seeds)
    played = host.play_episodes()
    for u, (env, seed) in enumerate(zip(unit_envs(None, len(seeds)), seeds, strict=True)):
        own = PPOAgent(4, 2, config, seed=seed)
        own.set_model_parameters(agent.model_parameters())  # the host's one network, before any update
        episodes = Learner(env, own, CompletionCriterion(1e9), seed=seed).play_episodes()[0]
        assert (played[u].scores, played[u].steps) == (episodes.scores, episodes.steps)
        mine, theirs = agent.memories[u].transitions(), own.memory.transitions()
        for field in dataclasses.fields(mine):
            assert np.array_equal(getattr(mine, field.name), getattr(theirs, field.name)), field.name
    assert sum(len(p.scores) for p in played) > 2 * len(played)  # whole episodes until 60 transitions
