"""The paper-code preset and its new PPO fields through the run settings: --preset, --set, config files."""

import tomllib
from pathlib import Path

import pytest

from fleetrl.runs.setting_values import SettingError, build
from fleetrl.runs.settings import RunSettings


def test_paper_code_and_its_overrides_reach_the_run_config(tmp_path: Path) -> None:
    flags = {
        "preset": "paper-code",
        "scheme": "paper",  # the default scheme, pergrad, refuses a preset whose steps alternate
        "out": str(tmp_path / "run"),
        "overrides": {"critic_coef": 1, "trajectory_memory": "ring", "critic_loss": "abs"},
    }
    settings = build(RunSettings, {}, flags)
    ppo = settings.to_config()["ppo"]
    assert ppo["critic_coef"] == 1.0 and isinstance(ppo["critic_coef"], float)  # an int becomes a number
    assert ppo["trajectory_memory"] == "ring" and ppo["critic_loss"] == "abs"
    assert ppo["optimisers"] == "one_sequential" and ppo["clip_eps"] == 0.1  # the preset's own values
    table = tomllib.loads(settings.to_toml())
    again = build(RunSettings, table, {})  # config.toml reruns the same settings
    assert again.learning.ppo() == settings.learning.ppo()


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"optimisers": "one"}, "expected one of 'per_model', 'one_sequential'"),
        ({"trajectory_memory": "per_round", "memory_size": 10}, "memory_size must be >= batch_size"),
        ({"critic_lr": 0.01}, "must equal critic_lr"),
    ],
)
def test_bad_paper_code_overrides_are_setting_errors(
    tmp_path: Path, overrides: dict[str, object], message: str
) -> None:
    with pytest.raises(SettingError, match=message):
        build(RunSettings, {}, {"preset": "paper-code", "out": str(tmp_path / "r"), "overrides": overrides})
