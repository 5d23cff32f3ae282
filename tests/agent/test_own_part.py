"""A unit's own part of the policy: offsets learned from its own gradient alone, never in what it shares."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import torch

from fleetrl.agent.config import get_preset
from fleetrl.agent.policy_file import read_policy_file
from fleetrl.agent.ppo import PPOAgent
from fleetrl.federation.shared_settings import LearningSettings
from fleetrl.runs.setting_values import SettingError
from fleetrl.runs.settings import RunSettings


def _agent(own_part: str, seed: int = 0) -> PPOAgent:
    config = dataclasses.replace(get_preset("standard"), own_part=own_part, memory_size=300, batch_size=64)
    return PPOAgent(4, 3, config, seed)


def _fill(agent: PPOAgent, data_seed: int) -> None:
    rng = np.random.default_rng(data_seed)
    for t in range(300):
        obs = rng.normal(size=4).astype(np.float32)
        agent.remember(obs, agent.act(obs), float(rng.random()), obs * 0.9, t % 60 == 59, False)


@pytest.mark.parametrize("own_part", ["input", "heads", "biases"])
def test_what_a_unit_shares_holds_no_own_offset(own_part: str) -> None:
    one_policy, own = _agent("none"), _agent(own_part)
    assert own.net.own, "the own part has offsets"
    for layout in ("actor_layout", "model_layout"):
        assert getattr(own, layout)() == getattr(one_policy, layout)()
    assert own.step_layout(0) == one_policy.step_layout(0)
    assert own.optimiser_layout() == one_policy.optimiser_layout()
    np.testing.assert_array_equal(own.model_parameters(), one_policy.model_parameters())


def test_a_fleet_step_moves_the_shared_part_by_the_fleet_gradient_and_the_own_part_by_its_own() -> None:
    units = [_agent("input"), _agent("input")]
    for data_seed, agent in enumerate(units):
        _fill(agent, data_seed)
        agent.begin_update()
    gradients = [agent.step_gradients(0) for agent in units]
    mean = (gradients[0] + gradients[1]) / 2.0  # the fleet's gradient, as pergrad's chief averages it
    own_before = [agent.net.own["trunk_0_bias"].detach().clone() for agent in units]
    for agent in units:
        agent.apply_step(mean)
    np.testing.assert_array_equal(units[0].model_parameters(), units[1].model_parameters())
    moved = [
        (agent.net.own["trunk_0_bias"] - before).abs().sum().item()
        for agent, before in zip(units, own_before, strict=True)
    ]
    assert min(moved) > 0.0, "each unit's own offset took its own step"
    assert not torch.equal(units[0].net.own["trunk_0_bias"], units[1].net.own["trunk_0_bias"])


def test_a_straggler_catching_up_leaves_its_own_part_where_it_was() -> None:
    agent = _agent("heads")
    _fill(agent, 0)
    before = {k: v.detach().clone() for k, v in agent.net.own.items()}
    shared_before = agent.model_parameters()
    agent.apply_fleet_step(0, np.full(sum(int(np.prod(s)) for _, s in agent.step_layout(0)), 0.1, np.float32))
    assert all(torch.equal(before[k], v) for k, v in agent.net.own.items())
    assert not np.array_equal(agent.model_parameters(), shared_before)


def test_the_unit_acts_with_its_own_offsets() -> None:
    agent = _agent("heads")
    observations = np.random.default_rng(5).normal(size=(50, 4)).astype(np.float32)
    shared_only = {int(agent.act_greedy(obs)) for obs in observations}
    with torch.no_grad():
        agent.net.own["policy_bias"].copy_(torch.tensor([0.0, 0.0, 50.0]))
    agent.refresh_policy()
    assert shared_only != {2}
    assert {int(agent.act_greedy(obs)) for obs in observations} == {2}
    head, _ = agent.net(torch.from_numpy(observations))
    assert set(head.argmax(1).tolist()) == {2}


def test_a_units_model_file_keeps_its_own_part_and_its_policy_folds_it_in(tmp_path: Path) -> None:
    agent = _agent("biases")
    with torch.no_grad():
        for offset in agent.net.own.values():
            offset.normal_(generator=torch.Generator().manual_seed(1))
    agent.refresh_policy()
    path = tmp_path / "worker-0.safetensors"
    agent.save(path)
    loaded = PPOAgent.load(path)
    for key, offset in agent.net.own.items():
        assert torch.equal(loaded.net.own[key], offset)
    policy = read_policy_file(path)
    weight, bias = policy.layers[-1]
    np.testing.assert_allclose(bias, (agent.net.policy.bias + agent.net.own["policy_bias"]).detach().numpy())
    np.testing.assert_array_equal(weight, agent.net.policy.weight.detach().numpy())
    observations = np.random.default_rng(2).normal(size=(20, 4)).astype(np.float32)
    file_policy = policy.numpy_policy()
    assert [file_policy.act_greedy(obs) for obs in observations] == [
        agent.act_greedy(o) for o in observations
    ]


def test_an_own_part_belongs_to_one_unit() -> None:
    config = dataclasses.replace(get_preset("standard"), own_part="input")
    with pytest.raises(ValueError, match="one unit"):
        PPOAgent(4, 3, config, [0, 1])


def _run(tmp_path: Path, **settings: object) -> RunSettings:
    learning = LearningSettings(env="cartpole", overrides={"own_part": "input"})
    return RunSettings(learning=learning, transport="local", out=tmp_path / "run", **settings)  # type: ignore[arg-type]


def test_an_own_part_needs_a_federation_and_a_worker_per_unit(tmp_path: Path) -> None:
    with pytest.raises(SettingError, match="--mode federated"):
        _run(tmp_path, mode="individual").resolved()
    with pytest.raises(SettingError, match="a worker per unit"):
        _run(tmp_path, units=4, units_per_host=2).resolved()
    assert _run(tmp_path, units=40).resolved().per_host == 1
