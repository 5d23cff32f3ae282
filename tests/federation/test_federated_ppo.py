"""The real PPO agent federated on CartPole: same seeds, identical scores on the local bus and over MQTT."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest

pytest.importorskip("fleetrl.agent.learner")

import gymnasium
import torch

from fleetrl.agent.config import PPOConfig
from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.learner import Learner
from fleetrl.agent.ppo import PPOAgent
from fleetrl.transport.broker import EmbeddedBroker, find_mosquitto
from fleetrl.transport.local import LocalBus
from fleetrl.transport.mqtt import MqttTransport

pytestmark = pytest.mark.mqtt

ROUNDS = 8
Runner = Callable[..., Any]


def ppo_fleet() -> dict[str, Learner]:
    """Three CartPole workers with their own seeds; a low completion bar so model transfer happens early."""
    torch.set_num_threads(1)
    learners = {}
    for worker_id, seed in (("1", 101), ("2", 202), ("3", 303)):
        env = gymnasium.make("CartPole-v1")
        agent = PPOAgent(4, 2, PPOConfig(), seed=seed)
        learners[worker_id] = Learner(env, agent, CompletionCriterion(30.0, window=3), seed=seed)
    return learners


def outcome(result: Any) -> tuple[dict[str, list[tuple[float, str]]], Any]:
    return {w: [(r.score, r.event) for r in rs] for w, rs in result.records.items()}, result.chief.transfers


@pytest.mark.slow
def test_federated_ppo_is_identical_over_local_bus_and_mqtt(fleet_runner: Runner) -> None:
    local = fleet_runner(LocalBus().client, ppo_fleet(), run_id="ppo-local", max_rounds=ROUNDS)
    again = fleet_runner(LocalBus().client, ppo_fleet(), run_id="ppo-local", max_rounds=ROUNDS)
    assert outcome(local) == outcome(again)
    assert all(len(rs) >= 1 for rs in local.records.values())
    kind = "mosquitto" if find_mosquitto() else "amqtt"
    with EmbeddedBroker(kind) as broker:
        remote = fleet_runner(
            lambda: MqttTransport(broker.url), ppo_fleet(), run_id="ppo-mqtt", max_rounds=ROUNDS
        )
    assert outcome(remote) == outcome(local)
