"""A run record's time on the rigs, from the steps it kept."""

from __future__ import annotations

import pytest

from fleetrl_lab.plan import controlled_minutes
from fleetrl_lab.records import RunRecord


def _record(mode: str, workers: dict[str, dict[str, object]], scheme: str = "pergrad") -> RunRecord:
    settings = {"env": "cartpole", "mode": mode, "scheme": scheme}
    return RunRecord({"result_settings": settings, "max_rounds": 3, "workers": workers})


STEPS = {"0": [10, 40, 5], "1": [30, 20, 50], "2": [20, 20, 20]}
COMPLETED = {"0": 2, "1": 3, "2": None}


def test_a_record_gives_its_time_on_the_rigs_from_its_steps() -> None:
    with_steps = {
        k: {"score": [0] * 3, "steps": s, "completed_at_round": COMPLETED[k]} for k, s in STEPS.items()
    }
    t = _record("federated", with_steps).rig_time()
    assert t is not None and t.per_unit == pytest.approx({"0": 1.4, "1": 2.4, "2": 2.4})  # 20 ms steps
    alone = _record("individual", with_steps).rig_time()
    assert alone is not None and alone.fleet == pytest.approx(2.0)  # unit 1: 100 steps
    fedasync = _record("federated", with_steps, "fedasync").rig_time()
    assert fedasync is not None and fedasync.per_unit == pytest.approx(alone.per_unit)
    several = {"0": {"score": [5.0], "episodes": [3], "completed_at_round": 1}}
    assert _record("individual", several).rig_time() is None  # rounds of several episodes, no steps kept


def _alone(rounds: dict[str, tuple[int, int | None]]) -> RunRecord:
    """4 units alone, each round 3,000 steps of 20 ms (1 min): unit → (rounds played, round completed)."""
    workers = {
        k: {"score": [0] * n, "steps": [3000] * n, "completed_at_round": done}
        for k, (n, done) in rounds.items()
    }
    return _record("individual", workers)


def test_an_arm_gives_the_median_minutes_until_50_90_and_100_percent_of_its_units_completed() -> None:
    """Run 1's units complete after 4, 1, 3, 2 min: 50 % of 4 (2 units) at 2 min, 90 % (3.6: 4 units) and
    100 % at 4. Run 2's: 1, 1, 2 min, one never (it played 5): 1 min, then never (at least its 5 min). Run
    3's: 2, 5, 5, 6 min. Medians: 2 of 2, 1, 5; 5 of 4, ≥ 5, 6 (a lower bound, marked)."""
    runs = [
        _alone({"0": (4, 4), "1": (1, 1), "2": (3, 3), "3": (2, 2)}),
        _alone({"0": (1, 1), "1": (1, 1), "2": (2, 2), "3": (5, None)}),
        _alone({"0": (2, 2), "1": (5, 5), "2": (5, 5), "3": (6, 6)}),
    ]
    assert controlled_minutes(runs) == "2.0 / ≥ 5.0 / ≥ 5.0"
    assert controlled_minutes([runs[0], runs[2]]) == "3.5 / 5.0 / 5.0"
    assert controlled_minutes([runs[1]]) == "1.0 / ≥ 5.0 / ≥ 5.0"
    several = {"0": {"score": [5.0], "episodes": [3], "completed_at_round": 1}}
    assert controlled_minutes([runs[0], _record("individual", several)]) == "-"  # no steps kept: unknown
