"""A bad ``--env package.module:factory`` is one line on stderr and exit code 2, before anything is created:
each way a factory can be wrong has its own message (``tests/envs/fake_units.py`` holds the factories)."""

from __future__ import annotations

from pathlib import Path

import pytest
from cli_helpers import refused_in_process as refused

from fleetrl.cli.main import main

REPO = Path(__file__).resolve().parents[2]
UNITS = "tests.envs.fake_units"


@pytest.fixture(autouse=True)
def _from_the_repository(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(REPO)  # a factory's module is imported from the current directory


NOT_FACTORY_FORM = "is not in package.module:factory form"
SIGNATURE = "(it must be factory(unit: int, fleet_seed: int, link=None) -> gymnasium.Env)"
MISSING = "tests.envs.no_such_module"
BROKEN = "tests.envs.fake_units_missing_dependency"


@pytest.mark.parametrize(
    ("env", "message"),
    [
        (f"{UNITS}.factory", f"unknown env '{UNITS}.factory' (choose cartpole, qube or qube-continuous, "
         "or your own"),
        (f"{UNITS}.factory", f"package.module:factory); did you mean '{UNITS}:factory'?"),
        (f"{UNITS}:", f"unit factory '{UNITS}:' {NOT_FACTORY_FORM}"),
        ("a:b:c", f"unit factory 'a:b:c' {NOT_FACTORY_FORM}"),
        (f"{MISSING}:factory", f"unit factory '{MISSING}:factory': cannot import module '{MISSING}' "
         f"(ModuleNotFoundError: No module named '{MISSING}')"),
        (f"{BROKEN}:factory", f"cannot import module '{BROKEN}' "
         "(ModuleNotFoundError: No module named 'fleetrl_no_such_dependency')"),
        (f"{UNITS}:no_such_factory", f"module '{UNITS}' has no attribute 'no_such_factory'"),
        (f"{UNITS}:NOT_CALLABLE", f"'NOT_CALLABLE' is a int, not callable {SIGNATURE}"),
        (f"{UNITS}:raising", f"unit factory '{UNITS}:raising': unit 0 could not be built: "
         "RuntimeError: no unit 0 on the bus"),
        (f"{UNITS}:not_an_env", f"unit factory '{UNITS}:not_an_env': unit 0 is a dict, not a gymnasium.Env"),
        (f"{UNITS}:image_observations", "has observation space Box(0.0, 1.0, (8, 8), float32): "
         "not supported (supported: a 1-D Box of floats)"),
        (f"{UNITS}:integer_observations", "has observation space Box(0, 9, (4,), int64): not supported"),
        (f"{UNITS}:multi_discrete_actions", "has action space MultiDiscrete([2 3]): not supported "
         "(supported: Discrete (at least 2 actions) or a 1-D Box of floats)"),
        (f"{UNITS}:unbounded_actions", "a box needs finite bounds, got low [-inf], high [inf] (supported: "),
        (f"{UNITS}:fractional_sensor_size", "declares sensor_size 2.5: give the length of the sensor vector "
         "its device link returns, an int 1 to 64 (or no sensor_size when the observation is that vector)"),
        (f"{UNITS}:no_threshold", f"--target-score: unit factory '{UNITS}:no_threshold' declares no "
         "target score and its env spec has no reward_threshold: give one with --target-score X"),
    ],
)  # fmt: skip
def test_a_bad_factory_is_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], env: str, message: str
) -> None:
    line = refused(tmp_path, capsys, "--env", env)
    assert line.startswith("fleetrl train: error: --") and message in line


def test_a_fleet_profile_with_a_factory_says_why_not(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    line = refused(tmp_path, capsys, "--env", f"{UNITS}:factory", "--fleet-profile", "v1")
    assert f"--fleet-profile: unit factory '{UNITS}:factory' has no fleet profiles (got 'v1')" in line
    assert "draws each unit from (unit, fleet_seed) itself" in line


def test_a_target_score_must_be_a_finite_number(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    line = refused(tmp_path, capsys, "--env", "cartpole", "--target-score", "inf")
    assert "--target-score = inf: must be a finite number" in line


def test_the_roles_and_evaluate_refuse_a_bad_factory_the_same_way(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    common = ["--env", f"{UNITS}:not_an_env", "--broker", "mqtt://127.0.0.1:1", "--run-id", "r"]
    assert main(["chief", *common, "--workers", "2"]) == 2
    assert "fleetrl chief: error: --env: unit factory" in capsys.readouterr().err
    assert main(["worker", *common, "--worker-id", "0", "--out", str(tmp_path / "w")]) == 2
    assert "fleetrl worker: error: --env: unit factory" in capsys.readouterr().err
    model = tmp_path / "worker-0.safetensors"
    model.write_bytes(b"")  # the env is built (and refused) before the model is read
    assert main(["evaluate", str(model), "--env", f"{UNITS}:raising"]) == 2
    assert "fleetrl evaluate: error: unit factory" in capsys.readouterr().err
