"""A user's own unit type (``--env package.module:factory``) trains end to end, through the same path as the
built-ins: its units built by the factory, its target from ``--target-score`` (recorded and shared), its
episode cap its own TimeLimit."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from fake_units import FACTORY, factory, pole_length

from fleetrl.cli.main import main
from fleetrl.envs.catalog import describe_env, get_env_spec
from fleetrl.runs.setting_values import flat_values
from fleetrl.runs.settings import NOT_RESULT_SETTINGS, LearningSettings, RunSettings

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(autouse=True)
def _from_the_repository(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(REPO)  # a factory's module is imported from the current directory


def train(out: Path, *argv: str) -> dict:
    assert main(["train", "--units", "2", "--max-rounds", "3", "--out", str(out), "--no-live", *argv]) == 0
    return json.loads((out / "config.json").read_text())


def rounds(out: Path) -> list[tuple[int, int]]:
    return sorted((int(r["worker"]), int(r["round"])) for r in csv.DictReader((out / "metrics.csv").open()))


@pytest.mark.slow
def test_a_factory_fleet_trains_federated_and_its_policy_evaluates(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    argv = ["--env", FACTORY, "--mode", "federated", "--transport", "local", "--target-score", "50"]
    config = train(out, *argv)
    assert rounds(out) == [(w, r) for w in (0, 1) for r in (1, 2, 3)]
    assert config["completion_threshold"] == 50.0 and config["episode_cap"] == 500
    assert config["env_id"] == "CartPole-v1"
    assert config["result_settings"]["env"] == FACTORY
    assert config["result_settings"]["target_score"] == 50.0  # not a built-in's default: in the run's key
    capsys.readouterr()
    model = out / "models" / "worker-1.safetensors"
    assert main(["evaluate", str(model), "--env", FACTORY, "--unit", "1", "--episodes", "2"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["env"] == FACTORY and len(result["scores"]) == 2


@pytest.mark.slow
def test_a_factory_fleet_trains_in_worker_processes(tmp_path: Path) -> None:
    """Each worker process imports the factory's module itself (from the current directory)."""
    out = tmp_path / "run"
    train(out, "--env", FACTORY, "--mode", "individual")
    assert rounds(out) == [(w, r) for w in (0, 1) for r in (1, 2, 3)]
    summary = json.loads((out / "summary.json").read_text())
    assert all(not str(info["state"]).startswith("failed") for info in summary["workers"].values())


@pytest.mark.slow
def test_a_unit_the_factory_cannot_build_fails_its_worker_naming_the_unit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    argv = ["--env", "tests.envs.fake_units:only_unit_0", "--units", "2", "--mode", "individual"]
    assert main(["train", *argv, "--max-rounds", "2", "--out", str(out), "--no-live"]) == 1
    assert "worker 1 failed (see logs/)" in capsys.readouterr().err
    logs = "".join(p.read_text() for p in (out / "logs").glob("*1*"))
    assert "unit 1 could not be built: RuntimeError: no unit 1 on the bus" in logs
    assert rounds(out) == [(0, 1), (0, 2)]


def test_the_factory_builds_each_unit_of_the_fleet() -> None:
    built = get_env_spec(FACTORY).make(1, 7)
    assert built.env.unwrapped.length == pole_length(1, 7) != pole_length(0, 7)  # type: ignore[attr-defined]
    assert built.description.action.kind == "discrete" and built.description.action.n == 2
    assert built.description.obs_shape == (4,) and built.description.episode_cap == 500
    assert factory(1, 7).unwrapped.length == built.env.unwrapped.length  # type: ignore[attr-defined]


def test_the_target_defaults_to_the_reward_threshold_and_a_builtins_to_its_own(tmp_path: Path) -> None:
    mine = RunSettings(learning=LearningSettings(env=FACTORY), out=tmp_path / "a").resolved()
    assert mine.learning.target_score == 475.0 == describe_env(FACTORY).reward_threshold
    assert mine.result_settings()["target_score"] == 475.0
    qube = RunSettings(learning=LearningSettings(env="qube"), out=tmp_path / "b").resolved()
    assert qube.learning.target_score == 2450.0 == qube.result_settings()["target_score"]
    learning = LearningSettings(env="cartpole", target_score=400.0)
    cartpole = RunSettings(learning=learning, out=tmp_path / "c").resolved()
    assert cartpole.result_settings()["target_score"] == 400.0


def test_the_result_settings_are_every_setting_but_where_a_run_writes_and_shows(tmp_path: Path) -> None:
    learning = LearningSettings(env="cartpole", preset="standard", scheme="fedavg")
    settings = RunSettings(learning=learning, out=tmp_path / "a").resolved()
    assert set(settings.result_settings()) == set(flat_values(settings)) - set(NOT_RESULT_SETTINGS)
    assert settings.to_config()["completion_threshold"] == 475.0


def role_settings(command: str, *argv: str) -> object:
    from fleetrl.cli.main import build_parser
    from fleetrl.cli.settings_args import settings_from_args
    from fleetrl.runs.role_settings import ChiefSettings, WorkerSettings

    cls = ChiefSettings if command == "chief" else WorkerSettings
    common = ["--env", FACTORY, "--broker", "mqtt://127.0.0.1:1", "--run-id", "r"]
    return settings_from_args(cls, build_parser().parse_args([command, *common, *argv]))


def test_the_chief_and_a_worker_of_a_factory_run_agree_only_on_the_same_target(tmp_path: Path) -> None:
    from fleetrl.federation.shared_settings import shared_text
    from fleetrl.runs.role_settings import ChiefSettings, WorkerSettings

    chief = role_settings("chief", "--workers", "2", "--target-score", "50")
    worker = role_settings("worker", "--worker-id", "1", "--out", str(tmp_path / "w"), "--target-score", "50")
    assert isinstance(chief, ChiefSettings) and isinstance(worker, WorkerSettings)
    ours = shared_text(chief.learning)
    assert ours["env"] == FACTORY and ours["target_score"] == "50.0"
    assert shared_text(worker.worker_spec().learning) == ours
    default = role_settings("worker", "--worker-id", "1", "--out", str(tmp_path / "d"))
    assert (
        isinstance(default, WorkerSettings) and default.learning.target_score == 475.0
    )  # CartPole-v1's threshold
    assert shared_text(default.worker_spec().learning)["target_score"] != ours["target_score"]
