"""Format-1 records migrate to what a run writes now: every result setting, every round's steps."""

import pytest

from fleetrl_lab.migrate import LEFT_OUT_IN_FORMAT_1, migrated
from fleetrl_lab.records import FORMAT
from fleetrl_lab.sweep import result_settings


@pytest.mark.parametrize("env", ["cartpole", "qube"])
def test_a_format_1_record_gets_the_result_settings_a_run_of_its_settings_has_now(env: str) -> None:
    now = result_settings({"env": env, "units": 3, "mode": "federated", "scheme": "fedavg"})
    left_out = {*LEFT_OUT_IN_FORMAT_1, "target_score"}
    old = {"format": 1, "result_settings": {k: v for k, v in now.items() if k not in left_out}, "workers": {}}
    new = migrated(old)
    assert new["format"] == FORMAT and new["result_settings"] == now
    assert list(new["result_settings"]) == sorted(now)


def test_single_episode_rounds_get_their_steps_and_rounds_of_several_episodes_none() -> None:
    workers = {"0": {"score": [9.0, 20.4, None]}, "1": {"score": [30.0], "episodes": [3]}}
    settings = {"env": "cartpole", "target_score": 400.0}
    new = migrated({"format": 1, "result_settings": settings, "workers": workers})
    assert new["workers"]["0"]["steps"] == [9, 20, 0] and "steps" not in new["workers"]["1"]
    assert new["result_settings"]["target_score"] == 400.0
    with pytest.raises(ValueError, match="not a format-1 record"):
        migrated(new)
