"""The real PPO agent federated on CartPole: same seeds, identical scores on the local bus and over MQTT."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest

pytest.importorskip("fleetrl.agent.learner")

import gymnasium
import torch

from fleetrl.agent.config import get_preset
from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.learner import Learner
from fleetrl.agent.ppo import PPOAgent
from fleetrl.transport.broker import EmbeddedBroker, find_mosquitto
from fleetrl.transport.local import LocalBus
from fleetrl.transport.mqtt import MqttTransport

pytestmark = pytest.mark.mqtt

ROUNDS = 8
Runner = Callable[..., Any]


def ppo_fleet(keep_learning: bool = False, preset: str = "paper") -> dict[str, Learner]:
    """Three CartPole workers with their own seeds; a low completion bar so model transfer happens early."""
    torch.set_num_threads(1)
    learners = {}
    for worker_id, seed in (("1", 101), ("2", 202), ("3", 303)):
        env = gymnasium.make("CartPole-v1")
        agent = PPOAgent(4, 2, get_preset(preset), seed=seed)
        criterion = CompletionCriterion(30.0, window=3)
        learners[worker_id] = Learner(env, agent, criterion, seed=seed, keep_learning=keep_learning)
    return learners


def outcome(result: Any) -> tuple[dict[str, list[tuple[float, str]]], Any]:
    scores = {w: [(r.result.score, r.event) for r in rs] for w, rs in result.records.items()}
    return scores, result.chief.transfers


@pytest.mark.slow
def test_federated_ppo_is_identical_over_local_bus_and_mqtt(
    fleet_runner: Runner, broker: EmbeddedBroker
) -> None:
    """Real PPO learners, on mosquitto and on the embedded amqtt broker (which carries it where mosquitto is
    missing)."""
    local = fleet_runner(LocalBus().client, ppo_fleet(), run_id="ppo-local", max_rounds=ROUNDS)
    again = fleet_runner(LocalBus().client, ppo_fleet(), run_id="ppo-local", max_rounds=ROUNDS)
    assert outcome(local) == outcome(again)
    assert all(len(rs) >= 1 for rs in local.records.values())
    remote = fleet_runner(
        lambda: MqttTransport(broker.url), ppo_fleet(), run_id=f"ppo-{broker.kind}", max_rounds=ROUNDS
    )
    assert outcome(remote) == outcome(local)


@pytest.mark.slow
def test_fedavg_ends_together_with_one_shared_model_over_both_transports(fleet_runner: Runner) -> None:
    fedavg = {"chief_kwargs": {"scheme": "fedavg"}, "worker_kwargs": {"scheme": "fedavg"}}
    learners = ppo_fleet(True, "standard")
    local = fleet_runner(LocalBus().client, learners, run_id="avg", max_rounds=40, **fedavg)
    assert local.chief.end_reason == "every unit completed" and local.chief.transfers == ()
    last = local.chief.rounds
    assert last < 40 and dict(local.chief.completed).keys() == {"1", "2", "3"}
    for worker, summary in local.workers.items():
        # every worker stopped with the run's last average: no round played after the run ended
        assert (summary.rounds, summary.finished, summary.reason) == (last, True, "every unit completed")
        assert [r.round for r in local.records[worker]][-1] == last
    models = {learner.agent.model_parameters().tobytes() for learner in learners.values()}
    assert len(models) == 1  # each worker replaced its whole network with the same average
    kind = "mosquitto" if find_mosquitto() else "amqtt"
    with EmbeddedBroker(kind) as broker:
        remote = fleet_runner(
            lambda: MqttTransport(broker.url),
            ppo_fleet(True, "standard"),
            run_id="avg-mqtt",
            max_rounds=40,
            **fedavg,
        )
    assert outcome(remote) == outcome(local)
