"""The large-fleet update: a rule of the unit type and the fleet's size, under the default preset only."""

from pathlib import Path

import pytest

from fleetrl.envs.catalog import CARTPOLE_LARGE_FLEET, get_env_spec
from fleetrl.federation.shared_settings import LearningSettings
from fleetrl.runs.learning_resolution import with_large_fleet_update
from fleetrl.runs.settings import RunSettings

LARGE = dict(CARTPOLE_LARGE_FLEET.settings)


def _overrides(units: int, env: str = "cartpole", **learning: object) -> dict[str, object]:
    return with_large_fleet_update(LearningSettings(env=env, **learning), units).overrides  # type: ignore[arg-type]


def test_a_thousand_cartpole_units_learn_with_the_large_fleet_update() -> None:
    assert _overrides(1000) == LARGE
    assert LARGE == {"batch_size": 16, "n_optimisations": 40, "actor_lr": 2e-3, "critic_lr": 2e-3}


def test_a_smaller_fleet_keeps_the_preset_update() -> None:
    assert _overrides(CARTPOLE_LARGE_FLEET.from_units - 1) == {}


def test_an_explicit_setting_wins_and_the_others_fill_in() -> None:
    assert _overrides(1000, overrides={"n_optimisations": 30}) == LARGE | {"n_optimisations": 30}


@pytest.mark.parametrize("env", ["qube", "qube-continuous"])
def test_qube_keeps_the_preset_update_at_every_size(env: str) -> None:
    assert get_env_spec(env).large_fleet is None
    assert _overrides(1000, env=env) == {}


@pytest.mark.parametrize("preset", ["paper", "paper-code"])
def test_the_paper_presets_are_left_as_written(preset: str) -> None:
    assert _overrides(1000, preset=preset) == {}


def test_a_train_run_of_a_thousand_units_resolves_to_the_rule(tmp_path: Path) -> None:
    learning = LearningSettings(env="cartpole")
    federated = RunSettings(
        learning=learning, units=1000, mode="federated", transport="local", out=tmp_path / "f"
    )
    alone = RunSettings(learning=learning, units=1, mode="federated", transport="local", out=tmp_path / "a")
    assert federated.resolved().learning.ppo().batch_size == 16
    assert alone.resolved().learning.ppo().batch_size != 16
