"""``--units-per-host auto`` (the default): about one unit host per core for a fleet of more than 16 units
that can have hosts; one worker per unit otherwise, so small runs and their records stay as they were."""

from pathlib import Path

import pytest

from fleetrl.cli.main import build_parser, main
from fleetrl.cli.settings_args import settings_from_args
from fleetrl.runs.host_settings import AUTO_HOSTS_ABOVE_UNITS, auto_units_per_host, usable_cores
from fleetrl.runs.setting_values import build
from fleetrl.runs.settings import RunSettings


def test_auto_is_a_host_per_core_above_the_threshold_where_hosts_are_possible() -> None:
    assert auto_units_per_host(1000, possible=True, cores=2) == 500
    assert auto_units_per_host(1001, possible=True, cores=2) == 501  # the last host carries one fewer
    assert auto_units_per_host(AUTO_HOSTS_ABOVE_UNITS, possible=True, cores=2) == 1
    assert auto_units_per_host(1000, possible=False, cores=2) == 1


def chosen(tmp_path: Path, units: int, **values: object) -> RunSettings:
    settings = {"env": "cartpole", "units": units, "out": str(tmp_path / "run"), "units_per_host": "auto"}
    return build(RunSettings, {**settings, **values}, {}, resolve=False).learning_resolved()


def test_auto_resolves_to_a_number_before_the_run_and_its_records(tmp_path: Path) -> None:
    large = chosen(tmp_path, 40, mode="federated", transport="local")
    assert large.per_host == -(-40 // usable_cores())
    assert f"units_per_host = {large.per_host}" in large.to_toml()  # a rerun of config.toml: the same hosts
    small = chosen(tmp_path, AUTO_HOSTS_ABOVE_UNITS, mode="federated", transport="local")
    assert small.per_host == 1 == small.result_settings()["units_per_host"]
    assert chosen(tmp_path, 40, transport="mqtt").per_host == large.per_host  # processes on the broker
    assert chosen(tmp_path, 40, mode="individual").per_host == 1  # units alone are not members
    values = {"env": "cartpole", "units": 40, "out": str(tmp_path / "run")}
    unnamed = build(RunSettings, values, {}, resolve=False)
    assert unnamed.units_per_host == "auto" and unnamed.learning_resolved().per_host == large.per_host
    assert chosen(tmp_path, 40, transport="local", scheme="fedavg").per_host == 1  # not a one-policy scheme


def test_the_flag_takes_auto_or_a_number_and_refuses_anything_else(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = str(tmp_path / "run")
    args = build_parser().parse_args(["train", "--out", out, "--units-per-host", "auto", "--units", "2"])
    assert settings_from_args(RunSettings, args).units_per_host == 1
    argv = ["train", "--out", out, "--no-live", "--units-per-host", "many"]
    assert main(argv) == 2
    assert "--units-per-host = 'many': expected an integer or one of 'auto'" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()
