"""Issue 14 (item 2): one typed settings object per command, from a --config TOML file and the flags (flags
win); a run directory's config.toml reruns the run."""

from __future__ import annotations

import argparse
import csv
import tomllib
from pathlib import Path

import pytest

from fleetrl.agent.config import DEFAULT_PRESET
from fleetrl.cli.main import build_parser, main
from fleetrl.cli.settings_args import NOT_SETTINGS, settings_from_args
from fleetrl.runs.role_settings import ChiefSettings, WorkerSettings
from fleetrl.runs.setting_values import SettingError, setting_fields
from fleetrl.runs.settings import RunSettings

COMMANDS = {"train": RunSettings, "chief": ChiefSettings, "worker": WorkerSettings}


def subparser(command: str) -> argparse.ArgumentParser:
    actions = build_parser()._subparsers._group_actions  # type: ignore[union-attr]
    return actions[0].choices[command]  # type: ignore[index,no-any-return]


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_flag_is_a_setting_with_a_config_file_key(command: str) -> None:
    fields = set(setting_fields(COMMANDS[command]))  # its groups' fields too (a flat file)
    dests = {a.dest for a in subparser(command)._actions if a.dest not in ("help", *NOT_SETTINGS)}
    assert dests <= fields, dests - fields
    assert fields <= dests, f"settings without a flag: {fields - dests}"


def parse(*argv: str) -> object:
    args = build_parser().parse_args(list(argv))
    return settings_from_args(COMMANDS[argv[0]], args)


def test_flags_override_the_file_and_the_file_overrides_the_defaults(tmp_path: Path) -> None:
    config = tmp_path / "run.toml"
    config.write_text(
        'env = "cartpole"\nunits = 2\nscheme = "fedavg"\nquorum = 0.5\nround_timeout = 3\nout = "from-file"\n'
        "[overrides]\nclip_eps = 0.3\nhidden = [16, 16]\n"
    )
    settings = parse("train", "--config", str(config), "--units", "4", "--set", "clip_eps=0.25")
    assert isinstance(settings, RunSettings)
    assert (settings.learning.env, settings.units, settings.quorum, settings.round_timeout) == (
        "cartpole",
        4,
        0.5,
        3.0,
    )
    assert settings.out == Path("from-file") and settings.learning.preset == DEFAULT_PRESET  # the one default
    assert settings.learning.overrides == {"clip_eps": 0.25, "hidden": (16, 16)}  # merged key by key


def test_the_roles_read_the_same_file(tmp_path: Path) -> None:
    config = tmp_path / "roles.toml"
    config.write_text('broker = "mqtt://127.0.0.1:1883"\nrun_id = "r7"\nenv = "cartpole"\nworkers = 3\n')
    chief = parse("chief", "--config", str(config), "--idle-timeout", "5")
    assert isinstance(chief, ChiefSettings)
    assert (chief.run_id, chief.workers, chief.idle_timeout, chief.learning.env) == ("r7", 3, 5.0, "cartpole")
    with pytest.raises(SettingError, match=r"unknown setting\(s\) workers"):  # a worker has no such setting
        parse("worker", "--config", str(config), "--worker-id", "0", "--out", str(tmp_path / "w"))


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("quorum = 'high'\n", "--quorum = 'high': expected a number (or unset) in "),
        ("unit = 3\n", "unknown setting(s) unit (known: "),
        ("units = 2.5\n", "--units = 2.5: expected an integer in "),
        ("live = 'no'\n", "live (flag --no-live) = 'no': expected true or false in "),
        ("[overrides]\nclip_eps = 'x'\n", "--set clip_eps = 'x': expected a number"),
        ("env = \n", "not valid TOML"),
    ],
)
def test_a_bad_config_file_is_refused_in_one_line_naming_the_setting(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, message: str
) -> None:
    config = tmp_path / "bad.toml"
    config.write_text(text)
    assert main(["train", "--config", str(config), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and err.count("\n") == 1
    assert not (tmp_path / "run").exists()


def metrics(out: Path) -> list[dict[str, str]]:
    """metrics.csv without wall times, by worker and round (worker threads interleave their rows)."""
    with (out / "metrics.csv").open(newline="") as f:
        rows = [{k: v for k, v in r.items() if k != "wall_time"} for r in csv.DictReader(f)]
    return sorted(rows, key=lambda r: (int(r["worker"]), int(r["round"])))


@pytest.mark.slow
@pytest.mark.timeout(240)
def test_a_run_directorys_config_toml_reruns_the_run(tmp_path: Path) -> None:
    first, again = tmp_path / "first", tmp_path / "again"
    argv = ["--env", "cartpole", "--preset", "standard", "--units", "2", "--max-rounds", "4", "--seed", "3"]
    assert (
        main(
            [
                "train",
                *argv,
                "--transport",
                "local",
                "--set",
                "hidden=[32,32]",
                "--no-live",
                "--out",
                str(first),
            ]
        )
        == 0
    )
    saved = (first / "config.toml").read_text()
    table = tomllib.loads(saved)
    assert "--config" in saved and table["transport"] == "local" and table["overrides"]["hidden"] == [32, 32]
    assert main(["train", "--config", str(first / "config.toml"), "--out", str(again)]) == 0
    assert metrics(again) == metrics(first) and len(metrics(first)) == 8
