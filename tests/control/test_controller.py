"""``fleetrl control`` on the simulated unit: the same episodes as ``fleetrl evaluate`` with the same model,
step for step (lockstep simulation is deterministic), from the model file and from its ONNX export; the
watchdog switches the motor off while the policy stalls; a policy for another unit type is refused."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from fleetrl.agent.ppo import PPOAgent
from fleetrl.control.controller import run_on_unit
from fleetrl.control.export import export_policy
from fleetrl.control.policies import GreedyPolicy, greedy_scores, load_policy
from fleetrl.envs.catalog import get_env_spec
from fleetrl.link.driver import SimulatedDriver, simulated_driver
from fleetrl.runs.evaluate import evaluate_model

UNIT, FLEET_SEED, SEED = 1, 0, 7


class Wrapped:
    """A policy around another: its observation size, actions and env are the inner policy's."""

    def __init__(self, policy: Any) -> None:
        self.policy = policy
        self.obs_dim, self.action_space, self.env = policy.obs_dim, policy.action_space, policy.env
        self.last_step = policy.last_step


class Recording(Wrapped):
    """A policy wrapper that keeps every observation it was shown."""

    def __init__(self, policy: Any) -> None:
        super().__init__(policy)
        self.seen: list[np.ndarray] = []

    def act(self, obs: np.ndarray) -> Any:
        self.seen.append(np.array(obs))
        return self.policy.act(obs)


class AgentPolicy:
    """``PPOAgent.act_greedy`` (what ``fleetrl evaluate`` acts with) as a policy."""

    env = None

    def __init__(self, model: Path) -> None:
        self.agent = PPOAgent.load(model)
        self.obs_dim, self.action_space = self.agent.obs_dim, self.agent.action_space
        self.last_step = self.agent.config.last_step

    def act(self, obs: np.ndarray) -> Any:
        return self.agent.act_greedy(obs)


def in_process(model: Path, env: str, episodes: int) -> tuple[list[float], list[np.ndarray]]:
    """``fleetrl evaluate``'s path: the in-process unit, the torch-loaded agent; scores and observations."""
    recording = Recording(AgentPolicy(model))
    gym_env, _ = get_env_spec(env).make(UNIT, FLEET_SEED, last_step=recording.last_step)
    scores = greedy_scores(gym_env, recording.act, episodes, SEED)
    gym_env.close()
    return scores, recording.seen


def on_unit(policy: GreedyPolicy, env: str, episodes: int) -> tuple[list[float], list[np.ndarray]]:
    """The controller's path: the unit behind its bridge, driven through the driver in lockstep."""
    recording = Recording(policy)
    driver = simulated_driver(get_env_spec(env).device or "", UNIT, FLEET_SEED)
    scores = run_on_unit(recording, env, driver, episodes, seed=SEED, unit=UNIT, fleet_seed=FLEET_SEED)
    return scores, recording.seen


@pytest.mark.parametrize(
    ("name", "env", "episodes"),
    [
        pytest.param("balancing", "qube", 2, marks=pytest.mark.slow),
        ("fresh", "qube", 6),
        pytest.param("balancing-continuous", "qube-continuous", 2, marks=pytest.mark.slow),
        ("fresh-continuous", "qube-continuous", 6),
        ("fresh-last", "qube", 6),
        ("fresh-last-continuous", "qube-continuous", 6),
    ],
)
def test_the_controller_plays_evaluate_s_episodes_step_for_step(
    models: dict[str, Path], name: str, env: str, episodes: int
) -> None:
    model = models[name]
    want = evaluate_model(model, env, UNIT, FLEET_SEED, episodes, SEED)
    scores, seen = on_unit(load_policy(model), env, episodes)
    assert scores == want
    if name.startswith("balancing"):
        assert scores == [2500.0] * episodes  # holds the pendulum for the whole episode
    else:
        assert len(set(scores)) > 1  # episodes that differ: their equality says something
    reference_scores, reference_seen = in_process(model, env, episodes)
    assert reference_scores == want
    assert np.array_equal(np.stack(seen), np.stack(reference_seen))  # every observation, bit for bit


@pytest.mark.parametrize("name", [pytest.param("balancing", marks=pytest.mark.slow), "fresh", "fresh-last"])
def test_the_onnx_export_plays_the_same_episodes(models: dict[str, Path], tmp_path: Path, name: str) -> None:
    """The graph computes in float32, fleetrl in float64: where the balance law's bang-bang decision is a
    near tie (|V| ≈ 0, every few steps while it holds the pendulum) the two may choose differently, and the
    trajectories part; both hold the pendulum all the same. An untrained policy has no such ties: its
    episodes are the model file's, step for step."""
    out = tmp_path / "policy.onnx"
    assert export_policy(models[name], out, "qube").passed
    onnx_scores, onnx_seen = on_unit(load_policy(out), "qube", 4)
    model_scores, model_seen = on_unit(load_policy(models[name]), "qube", 4)
    assert onnx_scores == model_scores
    if name.startswith("fresh"):
        assert np.array_equal(np.stack(onnx_seen), np.stack(model_seen))
    else:
        assert onnx_scores == [2500.0] * 4


class WatchedDriver(SimulatedDriver):
    """A simulated QUBE that notes each motor-off."""

    offs = 0

    def motor_off(self) -> None:
        self.offs += 1
        super().motor_off()


class Stalling(Wrapped):
    """Acts with ``policy`` but stalls once, for ``seconds``, at step ``at``; notes the driver's command."""

    def __init__(self, policy: GreedyPolicy, driver: WatchedDriver, at: int, seconds: float) -> None:
        super().__init__(policy)
        self.driver, self.at, self.seconds = driver, at, seconds
        self.steps = 0
        self.offs_during_stall = 0
        self.command_after_stall: np.ndarray | None = None

    def act(self, obs: np.ndarray) -> Any:
        self.steps += 1
        if self.steps == self.at:
            assert np.any(self.driver.command != 0.0)  # a command is held when the stall starts
            before = self.driver.offs
            time.sleep(self.seconds)
            self.offs_during_stall = self.driver.offs - before
            self.command_after_stall = self.driver.command.copy()
        return self.policy.act(obs)


def test_the_watchdog_switches_the_motor_off_while_the_policy_stalls(models: dict[str, Path]) -> None:
    from fleetrl.devices.factory import make_device

    driver = WatchedDriver(make_device("qube", UNIT, FLEET_SEED))
    stalling = Stalling(load_policy(models["balancing"]), driver, at=50, seconds=1.0)
    run_on_unit(stalling, "qube", driver, 1, seed=SEED, unit=UNIT, watchdog=0.25)
    assert stalling.offs_during_stall == 1
    assert stalling.command_after_stall is not None and np.all(stalling.command_after_stall == 0.0)


def test_a_policy_for_another_unit_type_is_refused_before_anything_moves(models: dict[str, Path]) -> None:
    driver = simulated_driver("qube", UNIT, FLEET_SEED)
    with pytest.raises(ValueError, match="env 'qube' has 4 and Discrete\\(3\\)"):
        run_on_unit(load_policy(models["cartpole"]), "qube", driver, 1)
    fits = r"driver .cartpole. declares 2 discrete commands; the env has Discrete\(3\) actions"
    with pytest.raises(ValueError, match=fits):
        run_on_unit(load_policy(models["fresh"]), "qube", simulated_driver("cartpole", 0, 0), 1)
