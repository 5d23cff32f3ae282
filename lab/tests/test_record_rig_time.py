"""A run record's time on the rigs, from the steps it kept."""

from __future__ import annotations

import pytest

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
