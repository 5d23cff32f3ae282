"""``--scheme-param KEY=VALUE`` / ``[scheme_params]``: typed by the scheme, validated once, carried to every
role; a run with a server optimiser learns the same over the in-process bus and over mosquitto."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from test_config_file import metrics

from fleetrl.cli.main import build_parser, main
from fleetrl.cli.settings_args import settings_from_args
from fleetrl.runs.launch import worker_specs
from fleetrl.runs.role_settings import ChiefSettings, WorkerSettings
from fleetrl.runs.settings import RunSettings
from fleetrl.transport.broker import EmbeddedBroker

FEDAVGM = ["--mode", "federated", "--scheme", "fedavgm"]


def parse(*argv: str) -> object:
    args = build_parser().parse_args(list(argv))
    cls = {"train": RunSettings, "chief": ChiefSettings, "worker": WorkerSettings}[argv[0]]
    return settings_from_args(cls, args)


def test_the_flag_is_typed_by_the_scheme_and_filled_with_its_defaults(tmp_path: Path) -> None:
    settings = parse("train", *FEDAVGM, "--scheme-param", "momentum=0.9", "--scheme-param", "server_lr=1",
                     "--out", str(tmp_path / "r"))  # fmt: skip
    assert isinstance(settings, RunSettings)
    assert settings.learning.scheme_params == {"optimizer": "momentum", "server_lr": 1.0, "momentum": 0.9}
    assert settings.result_settings()["scheme_params"] == settings.learning.scheme_params
    (spec, *_) = worker_specs(settings, None, "r").values()
    assert spec.learning == settings.learning
    assert json.loads(spec.to_json())["learning"]["scheme_params"]["momentum"] == 0.9


def test_a_scheme_without_parameters_has_empty_ones_in_the_result_settings(tmp_path: Path) -> None:
    settings = parse("train", "--mode", "federated", "--scheme", "fedavg", "--out", str(tmp_path / "r"))
    assert isinstance(settings, RunSettings)
    assert settings.learning.scheme_params == {} == settings.result_settings()["scheme_params"]


def test_the_config_file_table_and_the_flags_merge_key_by_key(tmp_path: Path) -> None:
    config = tmp_path / "run.toml"
    config.write_text('scheme = "fedadam"\nbroker = "mqtt://127.0.0.1:1883"\nrun_id = "r"\nworkers = 2\n'
                      "[scheme_params]\nserver_lr = 0.05\ntau = 0.01\n")  # fmt: skip
    chief = parse("chief", "--config", str(config), "--scheme-param", "tau=0.1")
    assert isinstance(chief, ChiefSettings)
    adam = {"optimizer": "adam", "server_lr": 0.05, "beta1": 0.9, "beta2": 0.99, "tau": 0.1}
    assert chief.learning.scheme_params == adam
    assert chief.learning.federation_scheme().params() == chief.learning.scheme_params


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["--scheme-param", "momentum=1.2"],
            "--scheme-param: scheme 'fedavgm': momentum = 1.2: must be in [0, 1)",
        ),
        (["--scheme-param", "speed=2"], "--scheme-param: scheme 'fedavgm' has no parameter(s) speed"),
        (["--scheme-param", "server_lr=fast"], "scheme 'fedavgm': server_lr = 'fast': expected a number"),
        (["--scheme-param", "momentum"], "--scheme-param takes KEY=VALUE, got 'momentum'"),
    ],
)
def test_a_bad_scheme_param_is_refused_in_one_line_naming_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    out = tmp_path / "run"
    assert main(["train", *FEDAVGM, *argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and err.count("\n") == 1
    assert not out.exists()


def test_scheme_params_need_a_federated_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["train", "--mode", "individual", "--scheme-param", "momentum=0.5", "--out", str(tmp_path / "r")]
    assert main(argv) == 2
    assert "--scheme-param" in capsys.readouterr().err


RUN = ["--env", "cartpole", "--units", "2", "--preset", "standard", "--max-rounds", "4", "--seed", "1"]
RUN += ["--no-live"]
SERVER_OPTIMISERS = {"fedavgm": {"server_lr": 1.0, "momentum": 0.9}, "fedadam": {"server_lr": 0.03}}


@pytest.mark.slow
@pytest.mark.mosquitto
@pytest.mark.timeout(300)
@pytest.mark.parametrize("scheme", sorted(SERVER_OPTIMISERS))
def test_a_server_optimiser_over_mosquitto_scores_as_over_the_local_bus(tmp_path: Path, scheme: str) -> None:
    params = SERVER_OPTIMISERS[scheme]
    run = [*RUN, "--mode", "federated", "--scheme", scheme]
    run += [arg for key, value in params.items() for arg in ("--scheme-param", f"{key}={value}")]
    local, mqtt = tmp_path / "local", tmp_path / "mqtt"
    assert main(["train", *run, "--transport", "local", "--out", str(local)]) == 0
    with EmbeddedBroker("mosquitto") as broker:
        assert main(["train", *run, "--transport", "mqtt", "--broker", broker.url, "--out", str(mqtt)]) == 0
    config = json.loads((mqtt / "config.json").read_text())
    assert config["scheme"] == scheme and params.items() <= config["scheme_params"].items()
    assert metrics(mqtt) == metrics(local) and len(metrics(local)) == 8
