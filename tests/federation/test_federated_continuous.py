"""Real PPO learners with a Gaussian head (Gymnasium's Pendulum-v1, a 1-D box) federated over the local bus:
the schemes carry the actor's log-std like any other tensor, whatever the shapes."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium
import numpy as np
import pytest
import torch

from fleetrl.agent.action_space import ActionSpace
from fleetrl.agent.config import get_preset
from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.learner import Learner
from fleetrl.agent.ppo import PPOAgent
from fleetrl.transport.local import LocalBus

Runner = Callable[..., Any]
ROUNDS = 3


def pendulum_fleet(keep_learning: bool) -> dict[str, Learner]:
    """Two Pendulum-v1 workers (200-step episodes) that never complete within the run."""
    torch.set_num_threads(1)
    learners = {}
    for worker_id, seed in (("1", 11), ("2", 22)):
        env = gymnasium.make("Pendulum-v1")
        agent = PPOAgent(3, ActionSpace.of(env.action_space), get_preset("standard"), seed=seed)
        learners[worker_id] = Learner(
            env, agent, CompletionCriterion(1e9), seed=seed, keep_learning=keep_learning
        )
    return learners


@pytest.mark.slow
def test_fedavg_averages_whole_continuous_models_log_std_included(fleet_runner: Runner) -> None:
    learners = pendulum_fleet(keep_learning=True)
    first = {w: learner.agent.model_parameters() for w, learner in learners.items()}
    fedavg = {"chief_kwargs": {"scheme": "fedavg"}, "worker_kwargs": {"scheme": "fedavg"}}
    result = fleet_runner(LocalBus().client, learners, run_id="avg-box", max_rounds=ROUNDS, **fedavg)
    assert all(len(records) == ROUNDS for records in result.records.values())
    agents = [learner.agent for learner in learners.values()]
    assert ("policy_log_std", (1,)) in agents[0].model_layout()
    models = [agent.model_parameters() for agent in agents]
    assert np.array_equal(models[0], models[1])  # both took the run's last average
    assert not np.array_equal(models[0], first["1"])
    assert all(np.all(np.isfinite(m)) for m in models)


@pytest.mark.slow
def test_the_papers_gradient_sharing_runs_on_continuous_actors(fleet_runner: Runner) -> None:
    learners = pendulum_fleet(keep_learning=False)
    result = fleet_runner(LocalBus().client, learners, run_id="paper-box", max_rounds=ROUNDS)
    assert all(len(records) == ROUNDS for records in result.records.values())
    log_stds = [learner.agent.actor_parameters()[-1] for learner in learners.values()]
    assert all(np.isfinite(log_stds)) and all(v != 0.0 for v in log_stds)  # moved from its start, 0
