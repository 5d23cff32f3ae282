"""A fleet whose policy sees each unit's last step (``--set last_step=true``): its model files take the longer
observation, and every command that runs a model on a unit (evaluate, adapt, export) builds the unit the
same way from the model file alone; a unit host carries it too."""

from __future__ import annotations

from pathlib import Path

import pytest
from cli_helpers import Fleetrl

from fleetrl.agent.policy_file import read_policy_file
from fleetrl.control.policies import load_policy

RUN = ["train", "--env", "cartpole", "--units", "2", "--transport", "local", "--no-live", "--max-rounds", "3"]


@pytest.mark.slow
def test_the_fleet_s_model_takes_the_last_step_and_every_command_plays_it(
    tmp_path: Path, fleetrl: Fleetrl
) -> None:
    out = tmp_path / "run"  # both units in one unit host: its learner steps them through their own envs
    done = fleetrl(*RUN, "--units-per-host", "2", "--set", "last_step=true", "--out", str(out))
    assert done.returncode == 0, done.stderr
    model = out / "models" / "worker-1.safetensors"
    policy = read_policy_file(model)
    assert (policy.obs_dim, policy.last_step) == (4 + 4 + 2, True)
    played = fleetrl("evaluate", str(model), "--env", "cartpole", "--unit", "1", "--episodes", "2")
    assert played.returncode == 0, played.stderr
    fitted = tmp_path / "unit-1.safetensors"
    adapted = fleetrl("adapt", str(model), "--env", "cartpole", "--unit", "1", "--episodes", "1",
                      "--check", "1", "--out", str(fitted))  # fmt: skip
    assert adapted.returncode == 0, adapted.stderr
    assert read_policy_file(fitted).last_step
    exported = fleetrl("export", str(fitted), "--env", "cartpole", "--out", str(tmp_path / "unit-1.onnx"))
    assert exported.returncode == 0, exported.stderr
    onnx = load_policy(tmp_path / "unit-1.onnx")  # what the exported file records
    assert (onnx.obs_dim, onnx.last_step) == (10, True)
