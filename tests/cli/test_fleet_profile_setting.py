"""The fleet profile as a run setting: validated once (the default's name filled in; CartPole's default
left unset, as every CartPole run's settings held it), carried to every worker's unit and device bridge,
recorded in the run directory, and refused when the unit type has no profile of that name."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from fleetrl.cli.main import build_parser, main
from fleetrl.cli.settings_args import settings_from_args
from fleetrl.devices.cartpole import CartPoleDevice
from fleetrl.devices.qube.device import QubeDevice
from fleetrl.link.driver import simulated_driver
from fleetrl.runs.factory import make_learner
from fleetrl.runs.launch import worker_specs
from fleetrl.runs.role_settings import WorkerSettings
from fleetrl.runs.setting_values import SettingError
from fleetrl.runs.settings import LearningSettings, RunSettings, resolve_learning
from fleetrl.runs.spec import WorkerSpec


def train_settings(*argv: str) -> RunSettings:
    args = build_parser().parse_args(["train", *argv])
    settings = settings_from_args(RunSettings, args)
    assert isinstance(settings, RunSettings)
    return settings


def test_validation_names_the_default_profile_and_the_file_records_it(tmp_path: Path) -> None:
    settings = train_settings("--out", str(tmp_path / "a"))
    assert settings.learning.fleet_profile == "table2"
    assert tomllib.loads(settings.to_toml())["fleet_profile"] == "table2"
    assert settings.to_config()["fleet_profile"] == "table2"
    old = train_settings("--out", str(tmp_path / "b"), "--fleet-profile", "v1")
    assert old.learning.fleet_profile == "v1"
    assert all(spec.learning.fleet_profile == "v1" for spec in worker_specs(old, None, "r").values())
    assert train_settings("--env", "cartpole", "--out", str(tmp_path / "c")).learning.fleet_profile is None


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["--fleet-profile", "tabel2"],
            r"--fleet-profile: unknown fleet profile 'tabel2' \(choose v1, table2 or wide\)",
        ),
        (
            ["--env", "cartpole", "--fleet-profile", "v1"],
            r"--fleet-profile: unknown cartpole fleet profile 'v1' \(choose standard or wide\)",
        ),
    ],
)
def test_a_bad_profile_is_refused_before_anything_starts(
    tmp_path: Path, argv: list[str], message: str
) -> None:
    out = tmp_path / "run"
    with pytest.raises(SettingError, match=message):
        train_settings("--out", str(out), *argv)
    assert not out.exists()


def test_the_worker_role_takes_the_profile(tmp_path: Path) -> None:
    args = build_parser().parse_args(
        [
            "worker",
            "--worker-id",
            "1",
            "--run-id",
            "r",
            "--out",
            str(tmp_path),
            "--fleet-profile",
            "v1",
            "--broker",
            "mqtt://h:1",
        ]
    )
    assert settings_from_args(WorkerSettings, args).learning.fleet_profile == "v1"


@pytest.mark.parametrize("profile", ["v1", "table2"])
def test_a_workers_unit_and_its_device_bridges_unit_are_drawn_with_the_profile(profile: str) -> None:
    learning = resolve_learning(LearningSettings(fleet_seed=3, max_rounds=5, fleet_profile=profile))
    spec = WorkerSpec(worker=0, unit=2, learning=learning, out="unused")
    learner = make_learner(WorkerSpec.from_json(spec.to_json()))
    expected = QubeDevice.from_fleet(2, 3, profile=profile).params
    assert learner.env.unwrapped.link.device.params == expected  # type: ignore[attr-defined]
    assert simulated_driver("qube", 2, 3, fleet_profile=profile).device.params == expected


def test_a_cartpole_run_takes_wide_and_leaves_standard_unset(tmp_path: Path) -> None:
    wide = train_settings("--env", "cartpole", "--fleet-profile", "wide", "--out", str(tmp_path / "w"))
    assert wide.learning.fleet_profile == "wide"
    assert tomllib.loads(wide.to_toml())["fleet_profile"] == "wide"
    assert wide.result_settings()["fleet_profile"] == "wide"
    assert all(spec.learning.fleet_profile == "wide" for spec in worker_specs(wide, None, "r").values())
    named = train_settings("--env", "cartpole", "--fleet-profile", "standard", "--out", str(tmp_path / "s"))
    unnamed = train_settings("--env", "cartpole", "--out", str(tmp_path / "s"))
    assert named.learning.fleet_profile is None and named.result_settings() == unnamed.result_settings()


@pytest.mark.parametrize("profile", ["standard", "wide"])
def test_a_cartpole_workers_unit_and_its_device_bridges_unit_are_drawn_with_the_profile(profile: str) -> None:
    settings = LearningSettings(env="cartpole", fleet_seed=3, max_rounds=5, fleet_profile=profile)
    learning = resolve_learning(settings)
    spec = WorkerSpec(worker=0, unit=2, learning=learning, out="unused")
    learner = make_learner(WorkerSpec.from_json(spec.to_json()))
    expected = CartPoleDevice.from_fleet(2, 3, profile=profile).params
    assert learner.env.unwrapped.link.device.params == expected  # type: ignore[attr-defined]
    bridge = simulated_driver("cartpole", 2, 3, fleet_profile=learning.fleet_profile)  # as the run starts it
    assert bridge.device.params == expected


def test_evaluate_and_homogeneity_refuse_an_unknown_profile_with_exit_2(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["homogeneity", "--fleet-profile", "nope", "--impulses", "3"]) == 2
    assert "unknown fleet profile 'nope'" in capsys.readouterr().err
    assert main(["evaluate", "missing.safetensors", "--fleet-profile", "nope"]) == 2
