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
    with pytest.raises(ValueError, match=r"unknown preset 'papr' \(choose paper or standard\)"):
        get_preset("papr")


def test_dict_round_trip_is_json_ready() -> None:
    config = get_preset("standard")
    data = json.loads(json.dumps(config.to_dict()))
    assert PPOConfig.from_dict(data) == config


def test_from_dict_rejects_unknown_and_bad_values() -> None:
    with pytest.raises(ValueError, match="unknown PPOConfig fields"):
        PPOConfig.from_dict({"clip": 0.2})
    with pytest.raises(ValueError, match="activation"):
        PPOConfig.from_dict({"activation": "gelu"})
    with pytest.raises(ValueError, match="memory_size"):
        dataclasses.replace(PPOConfig(), memory_size=10).validate()
