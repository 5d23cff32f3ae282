"""``fleetrl worker --device-link mqtt``: a standalone worker drives its unit through the unit's own device
bridge (``fleetrl device``, another process: the machine at the rig) over the run's broker, and learns what
the same worker with its unit simulated in-process learns; ``fleetrl evaluate --broker`` runs the policy
on that bridge's unit."""

from __future__ import annotations

import csv
import json
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from cli_helpers import Fleetrl, last_line
from device_process import device_process

from fleetrl.cli.main import build_parser, main
from fleetrl.cli.settings_args import settings_from_args
from fleetrl.runs.role_settings import WorkerSettings
from fleetrl.runs.setting_values import SettingError
from fleetrl.transport.broker import EmbeddedBroker

FLEET_SEED = 2


def worker_settings(*argv: str) -> WorkerSettings:
    args = build_parser().parse_args(["worker", "--broker", "mqtt://127.0.0.1:1", "--run-id", "r", *argv])
    return settings_from_args(WorkerSettings, args)


def test_a_device_link_names_the_units_bridge_under_the_runs_id(tmp_path: Path) -> None:
    settings = worker_settings(
        "--worker-id", "1", "--unit", "4", "--device-link", "mqtt", "--out", str(tmp_path)
    )
    spec = settings.worker_spec()
    assert (spec.device_url, spec.device_run_id, spec.unit) == ("mqtt://127.0.0.1:1", "r", 4)
    assert settings.device_transport() is not None
    in_process = worker_settings("--worker-id", "1", "--out", str(tmp_path))
    assert in_process.worker_spec().device_url is None and in_process.device_transport() is None


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--device-link", "radio"], "--device-link: unknown device link 'radio' (choose inprocess or mqtt)"),
        (["--device-link", "mqtt", "--env", "tests.envs.fake_units:factory"], "takes no link keyword"),
    ],
)
def test_a_device_link_that_cannot_work_is_refused_naming_it(
    tmp_path: Path, argv: list[str], message: str
) -> None:
    with pytest.raises(SettingError, match="--device-link") as refused:
        worker_settings("--worker-id", "0", "--out", str(tmp_path), *argv)
    assert message in str(refused.value)


def scores(out: Path) -> list[tuple[str, str]]:
    rows = csv.DictReader((out / "metrics.csv").open())
    return [(row["round"], row["score"]) for row in rows]


def fleetrl_process(*argv: str) -> subprocess.Popen[str]:
    command = [sys.executable, "-m", "fleetrl.cli.main", *argv]
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def federated_run(url: str, run_id: str, tmp_path: Path, *link: str) -> list[Path]:
    """A chief and two ``fleetrl worker`` processes of a 3-round CartPole run; the workers' directories."""
    common = ("--broker", url, "--run-id", run_id, "--env", "cartpole", "--fleet-seed", str(FLEET_SEED),
              "--preset", "standard", "--max-rounds", "3")  # fmt: skip
    chief = fleetrl_process("chief", *common, "--workers", "2", "--idle-timeout", "60")
    outs = [tmp_path / run_id / f"w{k}" for k in range(2)]
    own = ("--seed", "5", "--reply-timeout", "60", *link)
    workers = [
        fleetrl_process("worker", *common, *own, "--worker-id", str(k), "--out", str(out))
        for k, out in enumerate(outs)
    ]
    for worker in workers:
        _, err = worker.communicate(timeout=240)
        assert worker.returncode == 0 and "Traceback" not in err, err
    _, chief_err = chief.communicate(timeout=60)
    assert chief.returncode == 0, chief_err
    return outs


@pytest.mark.slow
@pytest.mark.mosquitto
@pytest.mark.timeout(600)
def test_workers_reach_their_units_bridges_and_learn_as_with_simulated_units(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with EmbeddedBroker("mosquitto") as broker:
        simulated = federated_run(broker.url, "sim", tmp_path)
        with (
            device_process(broker.url, "rig", "sim", 0, FLEET_SEED, tmp_path, env="cartpole") as log0,
            device_process(broker.url, "rig", "sim", 1, FLEET_SEED, tmp_path, env="cartpole") as log1,
        ):
            bridged = federated_run(broker.url, "rig", tmp_path, "--device-link", "mqtt")
            capsys.readouterr()
            model = str(bridged[1] / "models" / "worker-1.safetensors")
            evaluate = [
                "evaluate",
                model,
                "--env",
                "cartpole",
                "--unit",
                "1",
                "--fleet-seed",
                str(FLEET_SEED),
            ]
            assert main([*evaluate, "--episodes", "2", "--broker", broker.url, "--run-id", "rig"]) == 0
            on_bridge = json.loads(capsys.readouterr().out)
    assert main([*evaluate, "--episodes", "2"]) == 0
    assert on_bridge["scores"] == json.loads(capsys.readouterr().out)["scores"]
    for over_bridge, in_process, log in zip(bridged, simulated, (log0, log1), strict=True):
        assert len(scores(over_bridge)) == 3
        assert scores(over_bridge) == scores(in_process)
        # each step of the worker's 3 episodes (CartPole scores 1 a step) and 3 resets reached its bridge, and
        # for unit 1 the 2 greedy episodes of evaluate too
        served = re.search(r"closed \(BridgeStats\(commands=(\d+), rejected=0", log[0])
        assert served is not None, log[0]
        evaluated = sum(on_bridge["scores"]) + 2 if log is log1 else 0
        assert int(served[1]) == sum(float(score) for _, score in scores(over_bridge)) + 3 + evaluated


@pytest.mark.mosquitto
def test_a_worker_whose_bridge_is_not_there_fails_before_its_run_directory(
    tmp_path: Path, fleetrl: Fleetrl
) -> None:
    with EmbeddedBroker("mosquitto") as broker:
        done = fleetrl(
            "worker", "--broker", broker.url, "--run-id", "nobridge", "--env", "cartpole", "--worker-id", "0",
            "--device-link", "mqtt", "--out", str(tmp_path / "w0"),
        )  # fmt: skip
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr
    assert "no bridge online for unit 0" in last_line(done)
    assert not (tmp_path / "w0").exists()


def test_evaluate_on_a_bridge_refuses_what_cannot_work_before_connecting(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    model = str(tmp_path / "missing.safetensors")
    assert main(["evaluate", model, "--env", "cartpole", "--broker", "mqtt://127.0.0.1:1", "--fleet-profile",
                 "v1"]) == 2  # fmt: skip
    assert "--fleet-profile: the bridge's unit has its own dynamics" in capsys.readouterr().err
    assert (
        main(["evaluate", model, "--env", "tests.envs.fake_units:factory", "--broker", "mqtt://127.0.0.1:1"])
        == 2
    )
    assert "takes no link keyword" in capsys.readouterr().err
    assert (
        main(["evaluate", model, "--env", "cartpole", "--broker", "mqtt://127.0.0.1:1"]) == 2
    )  # nobody listens
    assert f"no model file at {model}" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.mosquitto
@pytest.mark.timeout(300)
def test_a_worker_whose_bridge_goes_away_mid_run_exits_1_in_one_line(tmp_path: Path) -> None:
    with EmbeddedBroker("mosquitto") as broker:
        common = ("--broker", broker.url, "--run-id", "lost", "--env", "cartpole", "--max-rounds", "400")
        bridge = fleetrl_process("device", "--driver", "sim", "--env", "cartpole", "--unit", "0",
                                 "--broker", broker.url, "--run-id", "lost")  # fmt: skip
        chief = fleetrl_process("chief", *common, "--workers", "1", "--idle-timeout", "60")
        out = tmp_path / "w0"
        worker = fleetrl_process(
            "worker", *common, "--worker-id", "0", "--device-link", "mqtt", "--out", str(out)
        )
        try:
            deadline = time.monotonic() + 120
            while time.monotonic() < deadline and len(rows(out)) < 3:
                time.sleep(0.1)
            assert len(rows(out)) >= 3, "the worker did not get going"
            bridge.send_signal(signal.SIGTERM)  # the rig's bridge stops: motor off, offline announced
            _, err = worker.communicate(timeout=60)
        finally:
            for process in (bridge, chief, worker):
                process.kill()
                process.communicate()
    assert worker.returncode == 1 and "Traceback" not in err, err
    assert err.strip().splitlines()[-1].startswith("fleetrl worker: error: ")
    assert "unit 0" in err.strip().splitlines()[-1]
    assert (out / "summary.json").is_file()  # what it learned so far is kept


def rows(out: Path) -> list[dict[str, str]]:
    metrics = out / "metrics.csv"
    return list(csv.DictReader(metrics.open())) if metrics.is_file() else []
