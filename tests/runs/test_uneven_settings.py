"""The uneven fleet as a run setting: parsed from flags or a config file, checked before anything starts with
one line, recorded in config.json and config.toml, carried to the named units only, not shared at join, and
invisible in an even run (its specs and result settings are those of before)."""

from __future__ import annotations

import json
import re
import tomllib
from pathlib import Path

import pytest

from fleetrl.cli.main import build_parser, main
from fleetrl.cli.settings_args import settings_from_args
from fleetrl.envs.catalog import CARTPOLE_CONTROL_PERIOD, QUBE_CONTROL_PERIOD
from fleetrl.envs.wrappers import PacedEnv
from fleetrl.federation.shared_settings import shared_text
from fleetrl.runs.factory import make_learner
from fleetrl.runs.launch import worker_specs
from fleetrl.runs.role_settings import WorkerSettings
from fleetrl.runs.settings import RunSettings
from fleetrl.runs.spec import WorkerSpec
from fleetrl.runs.uneven import UnitConditions

UNEVEN = ["--pace", "0.1", "--slow", "w2=4", "--link-delay", "1=0.05", "--absent", "0.2"]


def settings(tmp_path: Path, *argv: str) -> RunSettings:
    args = build_parser().parse_args(["train", "--out", str(tmp_path / "run"), *argv])
    built = settings_from_args(RunSettings, args)
    assert isinstance(built, RunSettings)
    return built


def test_the_flags_resolve_with_units_named_as_the_live_view_names_them(tmp_path: Path) -> None:
    uneven = settings(tmp_path, "--env", "cartpole", *UNEVEN).uneven
    assert uneven.pace == 0.1 and uneven.absent == 0.2 and uneven.absent_rounds == 3.0
    assert uneven.slow == {"w2": 4.0} and uneven.link_delay == {"w1": 0.05}


def test_each_unit_gets_its_own_conditions_and_the_shared_settings_stay_the_same(tmp_path: Path) -> None:
    run = settings(tmp_path, "--env", "cartpole", *UNEVEN)
    specs = worker_specs(run, None, "r")
    step = CARTPOLE_CONTROL_PERIOD * 0.1
    paced = {"step_seconds": step, "reset_scale": 0.1, "absent": 0.2}
    assert specs[0].uneven == UnitConditions(**paced)
    assert specs[1].uneven == UnitConditions(**paced, link_delay=0.05)
    assert specs[2].uneven == UnitConditions(**paced, slowdown=4.0)
    assert WorkerSpec.from_json(specs[2].to_json()) == specs[2]
    even = settings(tmp_path, "--env", "cartpole")
    assert shared_text(run.learning) == shared_text(even.learning)  # not a learning setting


def test_an_even_run_is_what_it_was(tmp_path: Path) -> None:
    even = settings(tmp_path, "--env", "cartpole")
    assert even.uneven.even
    specs = worker_specs(even, None, "r")
    assert all(s.uneven is None and "uneven" not in json.loads(s.to_json()) for s in specs.values())
    values = even.result_settings()
    assert (values["pace"], values["slow"], values["link_delay"], values["absent"]) == (None, {}, {}, 0.0)
    uneven = settings(tmp_path, "--env", "cartpole", "--slow", "w0=2").result_settings()
    assert uneven["slow"] == {"w0": 2.0} and uneven["pace"] is None


def test_the_settings_are_recorded_and_a_config_file_reruns_them(tmp_path: Path) -> None:
    run = settings(tmp_path, "--env", "qube", *UNEVEN)
    config = run.to_config()
    assert config["pace"] == 0.1 and config["slow"] == {"w2": 4.0} and config["absent"] == 0.2
    assert config["result_settings"]["link_delay"] == {"w1": 0.05}
    table = tomllib.loads(run.to_toml())
    assert table["slow"] == {"w2": 4.0} and table["link_delay"] == {"w1": 0.05}
    path = tmp_path / "config.toml"
    path.write_text(run.to_toml())
    again = settings(tmp_path, "--config", str(path))
    assert again.uneven == run.uneven
    assert worker_specs(again, None, "r")[0].uneven.step_seconds == pytest.approx(QUBE_CONTROL_PERIOD * 0.1)  # type: ignore[union-attr]


def test_a_paced_unit_steps_in_a_paced_env(tmp_path: Path) -> None:
    spec = worker_specs(settings(tmp_path, "--env", "cartpole", "--pace", "0.5"), None, "r")[1]
    learner = make_learner(spec)
    assert isinstance(learner.env, PacedEnv) and learner.env.period == pytest.approx(0.01)
    assert learner.env.reset_scale == 0.5  # its resets too
    even = worker_specs(settings(tmp_path, "--env", "cartpole"), None, "r")[1]
    assert not isinstance(make_learner(even).env, PacedEnv)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--slow", "w3=4"], r"--slow w3=4: unknown unit 'w3' \(this fleet: w0 … w2\)"),
        (["--slow", "x=4"], r"--slow x=4: unknown unit 'x'"),
        (["--slow", "w1=0.5"], r"--slow w1=0.5: must be ≥ 1"),
        (["--slow", "w1=fast"], r"--slow w1='fast': expected a number"),
        (["--link-delay", "w0=-0.1"], r"--link-delay w0=-0.1: must be ≥ 0 seconds"),
        (["--stall", "w2=1"], r"--stall w2=1: must be in \[0, 1\) \(the share of each second paused\)"),
        (["--stall", "w2=-0.25"], r"--stall w2=-0.25: must be in \[0, 1\)"),
        (["--stall", "w5=0.5"], r"--stall w5=0.5: unknown unit 'w5' \(this fleet: w0 … w2\)"),
        (["--stall", "w2=often"], r"--stall w2='often': expected a number"),
        (["--absent", "1"], r"--absent = 1.0: must be in \[0, 1\)"),
        (["--absent", "-0.1"], r"--absent = -0.1: must be in \[0, 1\)"),
        (["--absent", "0.8"], r"with absences of 3 rounds a unit is absent at most 0.75"),
        (["--absent-rounds", "0.5"], r"--absent-rounds = 0.5: must be ≥ 1"),
        (["--pace", "0"], r"--pace = 0.0: must be > 0"),
        (["--pace", "-1"], r"--pace = -1.0: must be > 0"),
        (["--link-delay", "w0=0.1", "--mode", "individual"], r"--link-delay .* needs --mode federated"),
    ],
)
def test_a_bad_value_is_one_line_before_anything_starts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    out = tmp_path / "run"
    code = main(
        ["train", "--env", "cartpole", "--units", "3", "--transport", "local", "--out", str(out), *argv]
    )
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err
    assert re.search(message, err), err
    assert not out.exists()


def test_a_stalling_unit_from_a_flag_or_a_stall_table(tmp_path: Path) -> None:
    run = settings(tmp_path, "--env", "cartpole", "--stall", "2=0.75", "--slow", "w1=2")
    assert run.uneven.stall == {"w2": 0.75}
    specs = worker_specs(run, None, "r")
    assert specs[2].uneven == UnitConditions(stall=0.75) and specs[0].uneven is None
    assert run.result_settings()["stall"] == {"w2": 0.75}
    assert tomllib.loads(run.to_toml())["stall"] == {"w2": 0.75}
    path = tmp_path / "config.toml"
    path.write_text('env = "cartpole"\n\n[stall]\nw1 = 0.5\n')
    assert settings(tmp_path, "--config", str(path)).uneven.stall == {"w1": 0.5}
    assert settings(tmp_path, "--env", "cartpole").result_settings()["stall"] == {}


def test_pacing_a_unit_type_without_a_control_period_is_refused(tmp_path: Path) -> None:
    from fleetrl.runs.setting_values import SettingError
    from fleetrl.runs.uneven import UnevenFleet

    with pytest.raises(SettingError, match="declares no control period"):
        UnevenFleet(pace=0.1).resolved_uneven(None, 3)


def test_a_standalone_worker_takes_its_own_entry(tmp_path: Path) -> None:
    argv = [
        "worker",
        "--broker",
        "mqtt://127.0.0.1:1883",
        "--run-id",
        "r",
        "--worker-id",
        "2",
        "--env",
        "cartpole",
    ]
    argv += ["--out", str(tmp_path / "w2"), "--slow", "w2=4", "--slow", "w0=9", "--link-delay", "2=0.1"]
    worker = settings_from_args(WorkerSettings, build_parser().parse_args(argv))
    assert worker.worker_spec().uneven == UnitConditions(slowdown=4.0, link_delay=0.1)
    from fleetrl.cli.roles import worker_config

    assert worker_config(worker)["slow"] == {"w0": 9.0, "w2": 4.0}
