"""The experiments that are not about the paper's rig (learning, cartpole-scaling) train a user's unit type
with ``--env package.module:factory``; the built-ins' arms and keys are as before."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from fleetrl.runs.setting_values import SettingError
from fleetrl_lab.arms import FULL, QUICK
from fleetrl_lab.catalog import PLANS
from fleetrl_lab.runner import ExperimentRequest, experiment_command, run_experiment, section_name

REPO = Path(__file__).resolve().parents[2]
FACTORY = "tests.envs.fake_units:factory"


@pytest.fixture(autouse=True)
def _from_the_repository(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(REPO)  # a factory's module is imported from the current directory


@pytest.mark.parametrize("name", ["learning", "cartpole-scaling"])
def test_every_arm_trains_the_unit_type_with_its_target(name: str) -> None:
    plan = PLANS[name](replace(QUICK, unit_type=FACTORY, target_score=50.0))
    assert plan.arms and all(arm.settings["env"] == FACTORY for arm in plan.arms)
    assert all(arm.settings["target_score"] == 50.0 for arm in plan.arms)
    assert all(arm.key.startswith("tests.envs.fake_units-factory-") for arm in plan.arms)
    assert {arm.settings["max_rounds"] for arm in plan.arms} == {QUICK.cartpole_rounds}


def test_the_builtins_arms_keep_their_keys() -> None:
    keys = {arm.key for arm in PLANS["learning"](FULL).arms}
    assert {"cartpole-3-individual-standard-m400", "qube-3-federated-standard-m1000-fedavg"} <= keys
    assert all("target_score" not in arm.settings for arm in PLANS["cartpole-scaling"](FULL).arms)


def test_the_section_and_the_command_name_the_unit_type(tmp_path: Path) -> None:
    assert section_name("learning", 0, unit_type=FACTORY) == "learning-tests.envs.fake_units-factory"
    request = ExperimentRequest(tmp_path, [100], True, unit_type=FACTORY, target_score=50.0)
    command = experiment_command("learning", request)
    assert command.endswith(f"--env {FACTORY} --target-score 50 --quick")


@pytest.mark.parametrize(
    ("name", "env", "target", "message"),
    [
        ("fig5", FACTORY, None, "experiment 'fig5' is about the paper's rig: --env applies to learning and "),
        ("learning", None, 50.0, "--target-score needs --env"),
        ("learning", "tests.envs.fake_units:not_an_env", None, "unit 0 is a dict, not a gymnasium.Env"),
        ("learning", "tests.envs.fake_units:no_threshold", None, "give one with --target-score X"),
    ],
)
def test_a_unit_type_that_cannot_run_is_refused_before_any_run(
    tmp_path: Path, name: str, env: str | None, target: float | None, message: str
) -> None:
    out = tmp_path / "experiments"
    with pytest.raises(ValueError, match=message) as refused:
        run_experiment(name, out, [100], True, unit_type=env, target_score=target)
    assert not out.exists()
    assert "Traceback" not in str(refused.value)


def test_all_with_a_unit_type_means_the_experiments_it_applies_to(tmp_path: Path) -> None:
    with pytest.raises(SettingError, match="unit 0 could not be built"):  # checked before any experiment
        run_experiment("all", tmp_path / "x", [100], True, unit_type="tests.envs.fake_units:raising")
