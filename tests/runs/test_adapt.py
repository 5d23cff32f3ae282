"""``fleetrl adapt``: the fleet's policy fitted to one unit, the shared part held, the own part learned."""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import torch

from fleetrl.agent.config import get_preset
from fleetrl.agent.ppo import PPOAgent
from fleetrl.cli.main import main
from fleetrl.runs.adapt import keep_fit, update_own_part, with_own_part


def _fleet_agent(seed: int = 4) -> PPOAgent:
    agent = PPOAgent(4, 3, get_preset("standard"), seed)
    with torch.no_grad():
        agent.net.policy.weight.mul_(50.0)
    agent.refresh_policy()
    return agent


def test_the_unit_starts_from_the_fleets_shared_policy_with_zero_offsets() -> None:
    fleet = _fleet_agent()
    unit = with_own_part(fleet, "biases", seed=0)
    np.testing.assert_array_equal(unit.model_parameters(), fleet.model_parameters())
    assert unit.net.own and all(torch.count_nonzero(v) == 0 for v in unit.net.own.values())
    with pytest.raises(ValueError, match="--own-part"):
        with_own_part(fleet, "none", seed=0)


def test_adapting_moves_the_own_part_and_holds_the_shared_part_exactly() -> None:
    unit = with_own_part(_fleet_agent(), "input", seed=0)
    shared = unit.model_parameters()
    rng = np.random.default_rng(0)
    for t in range(400):
        obs = rng.normal(size=4).astype(np.float32)
        unit.remember(obs, unit.act(obs), float(rng.random()), obs, t % 80 == 79, False)
    update_own_part(unit)
    np.testing.assert_array_equal(unit.model_parameters(), shared)
    assert torch.count_nonzero(unit.net.own["trunk_0_bias"]) > 0


def test_the_command_writes_the_units_model_and_reports_the_check(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    model = tmp_path / "fleet.safetensors"
    config = dataclasses.replace(get_preset("standard"), memory_size=200, batch_size=32)
    PPOAgent(4, 3, config, 1).save(model)
    out = tmp_path / "unit-5.safetensors"
    argv = ["adapt", str(model), "--env", "qube", "--unit", "5", "--episodes", "2", "--check", "2", "--out"]
    assert main([*argv, str(out)]) == 0
    line = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert line["episodes"] == 2 and len(line["check_before"]) == len(line["check_after"]) == 2
    assert line["rig_seconds"] > 0.0
    adapted = PPOAgent.load(out)
    fitted = any(torch.count_nonzero(v) for v in adapted.net.own.values())
    assert adapted.config.own_part == "biases"
    assert fitted == (line["kept"] == "fit") == keep_fit(line["check_before"], line["check_after"])
    assert main([*argv, str(out)]) == 2  # an existing file is never overwritten
    assert "exists" in capsys.readouterr().err
    assert main([*argv, str(tmp_path / "no" / "unit.safetensors")]) == 2  # refused before any episode
    assert "no directory" in capsys.readouterr().err


def test_a_fit_that_scores_less_on_the_checks_is_not_kept() -> None:
    assert keep_fit([100.0, 300.0], [200.0, 200.0])  # as good on average
    assert keep_fit([2500.0, 2500.0], [2500.0, 2500.0])
    assert not keep_fit([2500.0, 2500.0], [2500.0, 2400.0])
    assert keep_fit([], [])  # no checks, no evidence against the fit
