"""A run is reused only if its record was made with every setting that changes its result; a finished run
directory with matching settings gets its record without a rerun; anything else runs again."""

import io
import json
from pathlib import Path

import pytest
from experiment_fakes import record, write_record_of, write_run_dir

from fleetrl.cli.main import build_parser as cli_parser
from fleetrl.cli.settings_args import settings_from_args
from fleetrl.runs.setting_values import build
from fleetrl.runs.settings import RunSettings
from fleetrl_lab.arms import Arm, Places, arm
from fleetrl_lab.command import build_parser
from fleetrl_lab.records import read_record
from fleetrl_lab.sweep import Run, result_settings, run_all, train_args

FEDAVG = arm("cartpole", 3, "federated", "standard", 50, "fedavg", "fedavg")


def places(tmp_path: Path) -> Places:
    return Places(tmp_path / "runs", tmp_path / "records")


def test_a_record_made_with_the_same_settings_is_reused(tmp_path: Path) -> None:
    run = FEDAVG.run(places(tmp_path), 100)
    assert not run.done
    write_record_of(run, record(run, fleet=20))
    assert run.done


@pytest.mark.parametrize(
    "change",
    [
        {"fleet_profile": "v1"},
        {"overrides": {"actor_lr": 0.002}},
        {"scheme": "paper"},
        {"preset": "paper"},
        {"fleet_seed": 1},
    ],
)
def test_a_record_made_with_other_settings_is_not_reused(tmp_path: Path, change: dict[str, object]) -> None:
    env = "qube" if "fleet_profile" in change else "cartpole"
    base = arm(env, 3, "federated", "standard", 50, "fedavg", "fedavg")
    old = base.with_settings(**change).run(places(tmp_path), 100)
    now = base.run(places(tmp_path), 100)
    write_record_of(now, record(old, fleet=20))  # the record an earlier sweep left where `now` looks
    assert not now.done
    write_record_of(now, record(now, fleet=20))  # the control: the same record made with `now`'s settings
    assert now.done


def test_the_default_fleet_profile_is_resolved_so_naming_it_matches(tmp_path: Path) -> None:
    implicit = arm("qube", 3, "individual", "standard", 50, "alone")
    explicit = implicit.with_settings(fleet_profile="table2")
    assert result_settings({**implicit.settings, "seed": 1}) == result_settings(
        {**explicit.settings, "seed": 1}
    )
    assert result_settings({**implicit.settings, "seed": 1})["fleet_profile"] == "table2"


def test_the_key_and_the_command_come_from_the_same_settings() -> None:
    tuned = FEDAVG.with_settings(overrides={"actor_lr": 0.002}, fleet_seed=3)
    assert FEDAVG.key == "cartpole-3-federated-standard-m50-fedavg"
    assert (
        tuned.key.startswith("cartpole-3-federated-standard-m50-fedavg-fleet3-") and tuned.key != FEDAVG.key
    )
    args = train_args(tuned.settings)
    assert args[args.index("--fleet-seed") + 1] == "3" and "actor_lr=0.002" in args
    run = tuned.run(places(Path("/tmp/x")), 7)
    assert run.expected["overrides"] == {"actor_lr": 0.002} and run.expected["seed"] == 7
    assert " --set actor_lr=0.002 " in run.command() and tuned.key in run.command()


def test_an_interrupted_run_directory_or_one_with_other_settings_is_not_reusable(tmp_path: Path) -> None:
    run = FEDAVG.run(places(tmp_path), 100)
    assert not run.reusable()
    write_run_dir(run, {0: [10, 20]}, {0: 2})
    assert run.reusable()
    summary = json.loads((run.out / "summary.json").read_text())
    (run.out / "summary.json").write_text(json.dumps(summary | {"interrupted": True}))
    assert not run.reusable()
    (run.out / "summary.json").write_text(json.dumps(summary))
    other = FEDAVG.with_settings(preset="paper").run(places(tmp_path), 100)
    (run.out / "config.json").write_text(json.dumps({"result_settings": other.expected}))
    assert not run.reusable()


def test_a_sweep_writes_the_missing_record_of_a_matching_run_directory_without_running(
    tmp_path: Path,
) -> None:
    run = FEDAVG.run(places(tmp_path), 100)
    write_run_dir(run, {0: [10, 20, 30], 1: [5, 6, 7]}, {0: 3, 1: None})
    stream = io.StringIO()
    run_all([run], stream=stream)  # would start `fleetrl train` if the directory were not reused
    assert run.done
    kept = read_record(run.record)
    assert kept is not None and kept.completion().per_worker == {"0": 3, "1": None}
    assert stream.getvalue() == ""  # nothing ran: no progress line


def test_a_done_run_is_not_started_again(tmp_path: Path) -> None:
    run = FEDAVG.run(places(tmp_path), 100)
    write_record_of(run, record(run, fleet=20))
    run_all([run], stream=io.StringIO())
    assert not run.out.exists()


def test_an_arm_cannot_take_a_switch() -> None:
    with pytest.raises(ValueError, match="switch"):
        train_args({"live": False})


def test_a_run_is_named_by_arm_and_seed(tmp_path: Path) -> None:
    run = Arm(
        "x", {"env": "cartpole", "units": 1, "mode": "individual", "preset": "standard", "max_rounds": 5}
    )
    assert run.run(places(tmp_path), 4).name == "cartpole-1-individual-standard-m5 seed 4"
    assert isinstance(run.run(places(tmp_path), 4), Run)


def test_result_settings_leave_out_only_what_cannot_change_the_result(tmp_path: Path) -> None:
    def settings(**values: object) -> RunSettings:
        return build(RunSettings, {}, values, resolve=False).learning_resolved()

    a = settings(out=tmp_path / "a", live=True, broker="mqtt://u@h:1883", overrides={"actor_lr": 1})
    b = settings(out=tmp_path / "b", live=False, overrides={"actor_lr": 1.0})
    assert a.result_settings() == b.result_settings()
    assert {"out", "live", "broker", "broker_password_file"}.isdisjoint(a.result_settings())
    assert json.dumps(a.result_settings()["overrides"]) == '{"actor_lr": 1.0}'  # typed: a float
    assert b.to_config()["result_settings"] == b.result_settings()


def test_experiment_reports_on_seeds_from_100_by_default() -> None:
    args = build_parser().parse_args(["fig5"])
    assert (args.first_seed, args.seeds, args.fleet_seed, args.records) == (100, 10, 0, None)
    args = build_parser().parse_args(["fig5", "--fleet-seed", "1", "--records", "docs/r"])
    assert (args.fleet_seed, str(args.records)) == (1, "docs/r")


def test_an_experiment_arm_gives_the_result_settings_its_run_records(tmp_path: Path) -> None:
    arm = {"env": "cartpole", "scheme": "fedavg", "slow": {"2": 4}, "absent": 0.2}
    assert train_args(arm)[-4:] == ["--slow", "2=4", "--absent", "0.2"]
    args = cli_parser().parse_args(["train", "--out", str(tmp_path / "run"), *train_args(arm)])
    run = settings_from_args(RunSettings, args)
    assert isinstance(run, RunSettings)
    assert result_settings(arm) == run.result_settings()
