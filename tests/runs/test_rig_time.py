"""Time on the rigs, on hand-computed runs."""

from __future__ import annotations

import pytest

from fleetrl.devices.cartpole import CartPoleParams
from fleetrl.devices.qube.params import QubeConfig
from fleetrl.envs.catalog import get_env_spec
from fleetrl.experiments.records import RunRecord
from fleetrl.runs.rig_time import rig_time, waiting_rule

# unit "0" completes in round 2, unit "1" in round 3, unit "2" never (it played 3 rounds)
STEPS = {"0": [10, 40, 5], "1": [30, 20, 50], "2": [20, 20, 20]}
COMPLETED = {"0": 2, "1": 3, "2": None}


def test_a_synchronous_round_lasts_as_long_as_its_longest_episode() -> None:
    t = rig_time(STEPS, COMPLETED, 0.5, "synchronous")
    # rounds last max(10, 30, 20) = 30, max(40, 20, 20) = 40, max(5, 50, 20) = 50 steps of 0.5 s
    assert t.per_unit == {"0": 35.0, "1": 60.0, "2": 60.0}
    assert t.fleet == 60.0 and not t.complete


def test_units_alone_play_back_to_back_and_the_fleet_waits_for_the_slowest() -> None:
    t = rig_time(STEPS, COMPLETED, 0.5, "alone")
    assert t.per_unit == {"0": 25.0, "1": 50.0, "2": 30.0}
    assert t.fleet == 50.0


def test_a_unit_that_left_the_fleet_no_longer_makes_rounds_longer() -> None:
    # unit "a" transferred and left after round 1: rounds 2 and 3 wait for "b" alone
    t = rig_time({"a": [100], "b": [10, 20, 30]}, {"a": 1, "b": 3}, 1.0, "synchronous")
    assert t.per_unit == {"a": 100.0, "b": 150.0} and t.fleet == 150.0 and t.complete


def test_inconsistent_input_is_refused() -> None:
    with pytest.raises(ValueError, match="completed at round 4 but played up to round 3"):
        rig_time({"0": [1, 2, 3]}, {"0": 4}, 1.0, "alone")
    with pytest.raises(ValueError, match="must be > 0"):
        rig_time(STEPS, COMPLETED, 0.0, "alone")
    with pytest.raises(ValueError, match="units with steps"):
        rig_time(STEPS, {"0": 1}, 1.0, "alone")


def test_the_waiting_rule_follows_the_mode() -> None:
    assert waiting_rule("individual") == "alone" and waiting_rule("federated") == "synchronous"


def test_under_an_asynchronous_scheme_no_unit_waits_for_another() -> None:
    assert waiting_rule("federated", "fedasync") == "asynchronous"
    assert waiting_rule("federated", "pergrad") == waiting_rule("federated", "fedavg") == "synchronous"
    assert waiting_rule("individual", "fedasync") == "alone"
    # each unit's own rounds back to back: 0 until its round 2 (10 + 40), 1 until its round 3, 2 all three
    t = rig_time(STEPS, COMPLETED, 0.5, "asynchronous")
    assert t.per_unit == {"0": 25.0, "1": 50.0, "2": 30.0} and t.fleet == 50.0 and not t.complete


def test_an_asynchronous_record_is_timed_back_to_back() -> None:
    workers = {"0": {"completed_at_round": 1, "score": [10.0], "steps": [10]},
               "1": {"completed_at_round": 2, "score": [30.0, 5.0], "steps": [30, 5]}}  # fmt: skip
    record = RunRecord(
        {"result_settings": {"env": "cartpole", "mode": "federated", "scheme": "fedasync"},
         "max_rounds": 2, "workers": workers}
    )  # fmt: skip
    time = record.rig_time()
    assert time is not None
    period = CartPoleParams().tau
    assert time.per_unit == pytest.approx({"0": 10 * period, "1": 35 * period})  # synchronous: 1 waits 30


def test_the_built_in_control_periods_are_the_devices_own() -> None:
    assert get_env_spec("qube").control_period == QubeConfig().control_period
    assert get_env_spec("qube-continuous").control_period == QubeConfig().control_period
    assert get_env_spec("cartpole").control_period == CartPoleParams().tau


def _record(mode: str, workers: dict[str, dict[str, object]], env: str = "cartpole") -> RunRecord:
    return RunRecord({"result_settings": {"env": env, "mode": mode}, "max_rounds": 3, "workers": workers})


def test_a_record_gives_its_time_on_the_rigs_from_its_steps_or_else_its_scores() -> None:
    with_steps = {
        k: {"score": [0] * 3, "steps": s, "completed_at_round": COMPLETED[k]} for k, s in STEPS.items()
    }
    from_scores = {k: {"score": s, "completed_at_round": COMPLETED[k]} for k, s in STEPS.items()}
    for workers in (with_steps, from_scores):
        t = _record("federated", workers).rig_time()
        assert t is not None and t.per_unit == pytest.approx(
            {"0": 1.4, "1": 2.4, "2": 2.4}
        )  # 70 and 120 steps of 20 ms
    alone = _record("individual", with_steps).rig_time()
    assert alone is not None and alone.fleet == pytest.approx(2.0)  # unit 1: 100 steps
    several = {"0": {"score": [5.0], "episodes": [3], "completed_at_round": 1}}
    assert _record("individual", several).rig_time() is None  # rounds of several episodes, no steps kept


def test_a_straggler_s_rounds_count_where_it_played_them() -> None:
    """Under a quorum a slow unit plays rounds 1 and 4 only: the fleet's rounds last as long as their members'
    episodes, and the straggler has spent the fleet's time until the round it completed in."""
    t = rig_time({"a": [10, 10, 10, 10], "s": {1: 30, 4: 50}}, {"a": 4, "s": 4}, 1.0, "synchronous")
    assert (t.fleet, t.per_unit) == (30 + 10 + 10 + 50, {"a": 100, "s": 100})
    alone = rig_time({"s": {1: 30, 4: 50}}, {"s": 4}, 1.0, "alone")
    assert alone.per_unit == {"s": 80}
    with pytest.raises(ValueError, match="completed at round 5 but played up to round 4"):
        rig_time({"s": {1: 30, 4: 50}}, {"s": 5}, 1.0, "alone")
