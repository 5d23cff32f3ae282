"""Presets and config validation."""

import dataclasses
import json

import pytest

from fleetrl.agent.config import PPOConfig, get_preset


def test_paper_preset_is_table_1() -> None:
    paper = get_preset("paper")
    assert paper.clip_eps == 0.9
    assert paper.gae_lambda == 0.99
    assert paper.actor_lr == 0.001 and paper.critic_lr == 0.001
    assert paper.memory_size == 200 and paper.batch_size == 64 and paper.n_optimisations == 10
    assert paper.hidden == (128, 128, 128)
    assert paper.critic_loss == "abs" and paper.critic_target == "td" and paper.gae_scope == "window"


def test_standard_preset_clips_at_0_2() -> None:
    assert get_preset("standard").clip_eps == 0.2


def test_get_preset_returns_a_copy() -> None:
    get_preset("paper").clip_eps = 0.5
    assert get_preset("paper").clip_eps == 0.9


def test_unknown_preset_lists_choices() -> None:
    with pytest.raises(ValueError, match=r"unknown preset 'papr' \(choose paper, paper-code or standard\)"):
        get_preset("papr")


def test_paper_code_preset_is_what_the_authors_code_ran() -> None:
    code = get_preset("paper-code")
    assert code.clip_eps == 0.1 and code.gamma == 0.98 and code.old_policy == "behaviour"
    assert code.trajectory_memory == "per_round" and code.memory_size == 200
    assert code.batch_size == 64 and code.n_optimisations == 10 and code.gae_lambda == 0.99
    assert code.critic_loss == "huber" and code.critic_coef == 0.5 and code.entropy_coef == 0.01
    assert code.optimisers == "one_sequential" and code.normalise_advantages
    assert code.critic_target == "td" and code.gae_scope == "window"


def test_new_fields_default_to_the_old_behaviour_in_paper_and_standard() -> None:
    for name in ("paper", "standard"):
        preset = get_preset(name)
        assert preset.critic_coef == 1.0 and preset.trajectory_memory == "ring"
        assert preset.optimisers == "per_model" and preset.critic_loss == "abs"


@pytest.mark.parametrize("preset", ["paper", "paper-code", "standard"])
def test_dict_round_trip_is_json_ready(preset: str) -> None:
    config = get_preset(preset)
    data = json.loads(json.dumps(config.to_dict()))
    assert PPOConfig.from_dict(data) == config


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"critic_loss": "l2"}, "critic_loss = 'l2': expected one of 'abs', 'huber'"),
        ({"critic_coef": 0.0}, "critic_coef must be > 0"),
        ({"trajectory_memory": "fifo"}, "trajectory_memory = 'fifo': expected one of 'ring', 'per_round'"),
        ({"optimisers": "three"}, "optimisers = 'three': expected one of 'per_model', 'one_sequential'"),
        ({"optimisers": "one_sequential", "critic_lr": 3e-4}, "actor_lr .* must equal critic_lr"),
    ],
)
def test_new_fields_are_validated(overrides: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        dataclasses.replace(PPOConfig(), **overrides).validate()  # type: ignore[arg-type]


def test_from_dict_rejects_unknown_and_bad_values() -> None:
    with pytest.raises(ValueError, match="unknown PPOConfig fields"):
        PPOConfig.from_dict({"clip": 0.2})
    with pytest.raises(ValueError, match="activation"):
        PPOConfig.from_dict({"activation": "gelu"})
    with pytest.raises(ValueError, match="memory_size"):
        dataclasses.replace(PPOConfig(), memory_size=10).validate()
