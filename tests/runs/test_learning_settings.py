"""The learning settings as one frozen value: resolved into a new value, the probe agent built once, carried
by the worker's spec and the join, read back from the config files earlier runs wrote."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import pytest

from fleetrl.cli.main import build_parser
from fleetrl.cli.settings_args import settings_from_args
from fleetrl.federation.schemes import DEFAULT_SCHEME
from fleetrl.federation.shared_settings import LearningSettings, shared_text
from fleetrl.runs import factory
from fleetrl.runs.role_settings import WorkerSettings
from fleetrl.runs.setting_values import build, field_docs
from fleetrl.runs.settings import ALONE_SCHEME, RunSettings, resolve_learning
from fleetrl.runs.spec import WorkerSpec


def test_resolution_returns_a_new_value_and_leaves_the_given_one_as_it_was() -> None:
    given = LearningSettings(env="cartpole", scheme="fedavgm", overrides={"clip_eps": 1})
    resolved = resolve_learning(given)
    assert given == LearningSettings(env="cartpole", scheme="fedavgm", overrides={"clip_eps": 1})
    assert resolved.scheme_params == {"optimizer": "momentum", "server_lr": 1.0, "momentum": 0.0}
    assert resolved.overrides == {"clip_eps": 1.0} and isinstance(resolved.overrides["clip_eps"], float)
    assert resolved.target_score == 475.0 and resolve_learning(resolved) == resolved
    with pytest.raises(dataclasses.FrozenInstanceError):
        resolved.seed = 1  # type: ignore[misc]


def test_the_default_scheme_is_the_one_definition_for_a_fleet_and_the_alone_scheme_for_units_alone(
    tmp_path: Path,
) -> None:
    fleet = build(RunSettings, {}, {"env": "cartpole", "out": tmp_path / "a"}, resolve=False)
    alone = build(
        RunSettings, {}, {"env": "cartpole", "out": tmp_path / "b", "mode": "individual"}, resolve=False
    )
    assert fleet.learning_resolved().learning.scheme == DEFAULT_SCHEME
    assert alone.learning_resolved().learning.scheme == ALONE_SCHEME


def test_the_probe_agent_is_built_once_per_resolution_and_not_for_the_result_settings(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    built: list[str] = []
    probe = factory.probe_agent

    def counting(env: str, config: Any) -> Any:
        built.append(env)
        return probe(env, config)

    monkeypatch.setattr(factory, "probe_agent", counting)
    settings = build(RunSettings, {}, {"env": "cartpole", "out": tmp_path / "run", "quorum": 1})
    assert built == ["cartpole"]
    assert settings.result_settings() == settings.result_settings() and built == ["cartpole"]
    unresolved = build(
        RunSettings, {}, {"env": "cartpole", "out": tmp_path / "run", "quorum": 1}, resolve=False
    )
    assert unresolved.learning_resolved().result_settings() == settings.result_settings()
    assert built == ["cartpole"]


def test_a_worker_spec_carries_the_value_through_json() -> None:
    learning = resolve_learning(LearningSettings(env="cartpole", seed=7, overrides={"hidden": [16]}))
    spec = WorkerSpec(worker=2, unit=5, learning=learning, out="run", device_run_id="r")
    again = WorkerSpec.from_json(spec.to_json())
    assert again.learning.to_json() == learning.to_json() and (again.worker, again.unit) == (2, 5)
    assert json.loads(spec.to_json())["learning"]["seed"] == 7


def test_a_workers_own_seed_is_accepted_and_not_compared_at_join(tmp_path: Path) -> None:
    common = ["worker", "--env", "cartpole", "--broker", "mqtt://127.0.0.1:1", "--run-id", "r", "--worker-id"]

    def worker(seed: int) -> WorkerSettings:
        args = build_parser().parse_args(
            [*common, str(seed), "--seed", str(seed), "--out", str(tmp_path / f"{seed}")]
        )
        settings = settings_from_args(WorkerSettings, args)
        assert isinstance(settings, WorkerSettings)
        return settings

    a, b = worker(40), worker(41)
    assert (a.learning.seed, b.learning.seed) == (40, 41)
    assert shared_text(a.worker_spec().learning) == shared_text(b.worker_spec().learning)


OLD_CONFIG_TOML = """# fleetrl train settings of this run (no password is ever written here).
env = "cartpole"
target_score = 475.0
preset = "standard"
max_rounds = 40
scheme = "fedavgm"
aggregation = "mean"
quorum = 1.0
out = "runs/old"
mode = "federated"
units = 2
seed = 3
fleet_seed = 1
transport = "local"
device_link = "inprocess"
live = false

[scheme_params]
optimizer = "momentum"
server_lr = 1.0
momentum = 0.9

[overrides]
hidden = [32, 32]
"""


def test_a_config_toml_an_earlier_run_wrote_is_read_and_written_back_to_the_same_settings(
    tmp_path: Path,
) -> None:
    import tomllib

    table = tomllib.loads(OLD_CONFIG_TOML)
    settings = build(RunSettings, table, {"out": str(tmp_path / "again")})
    assert settings.learning.fleet_seed == 1 and settings.learning.seed == 3
    assert settings.learning.overrides == {"hidden": (32, 32)}
    written = tomllib.loads(settings.to_toml())
    assert written.items() >= (table | {"out": str(tmp_path / "again")}).items()
    assert build(RunSettings, written, {}) == settings


def test_a_flags_help_is_its_fields_docstring_with_the_fields_default() -> None:
    train = build_parser().parse_args(["train", "--out", "x"])
    assert train.max_rounds is None  # not given: the settings value's default applies
    help_text = build_parser()._subparsers._group_actions[0].choices["train"].format_help()  # type: ignore[union-attr]
    docs = field_docs(RunSettings)
    assert docs["max_rounds"].startswith("the paper's M") and "(default: 1000)" in " ".join(help_text.split())
    assert "(default: mqtt)" in " ".join(help_text.split())  # RunSettings.transport's default
