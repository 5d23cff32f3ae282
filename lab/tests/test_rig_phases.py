"""Where a unit's time on the rigs goes, split at its first long episode (hand-computed)."""

import pytest

from fleetrl_lab.records import RunRecord
from fleetrl_lab.rig_phases import phases_lines, phases_table, unit_phases


def test_a_unit_splits_at_its_first_long_episode_up_to_its_completion() -> None:
    # cap 1000: long from 400 steps; completed at round 5, so round 6 is not counted
    split = unit_phases([10, 20, 900, 1000, 1000, 1000], 5, cap=1000, period=0.1)
    assert split is not None
    assert (split.rounds_before, split.rounds_after) == (2, 3)
    assert split.minutes_before == pytest.approx(30 * 0.1 / 60)
    assert split.minutes_after == pytest.approx(2900 * 0.1 / 60)
    # never completed: every round counts; never long: no split
    assert unit_phases([10, 500], None, cap=1000, period=0.1).rounds_after == 1  # type: ignore[union-attr]
    assert unit_phases([10, 399], None, cap=1000, period=0.1) is None


def qube_record(steps: dict[str, list[int]], completed: dict[str, int]) -> RunRecord:
    workers = {
        k: {
            "score": [float(n) for n in s],
            "steps": s,
            "wma": [],
            "events": {},
            "completed_at_round": completed[k],
        }
        for k, s in steps.items()
    }
    settings = {"env": "qube", "units": len(steps), "max_rounds": 1000}
    return RunRecord({"result_settings": settings, "workers": workers, "max_rounds": 1000})


def test_the_table_gives_each_arm_s_medians_over_its_units(monkeypatch: pytest.MonkeyPatch) -> None:
    # QUBE: 6 ms a step, cap 2500, long from 1000 steps; resets of 0 s first
    monkeypatch.setattr("fleetrl_lab.rig_phases.reset_seconds", lambda *_: 0.0)
    a = qube_record({"0": [100, 1000, 2500], "1": [100, 100, 2500, 2500]}, {"0": 3, "1": 4})
    b = qube_record({"0": [50] * 10}, {"0": 10})  # never long: left out
    table = phases_table([("fleet", [a, b]), ("empty", [b])])
    rows = table.splitlines()
    assert len(rows) == 3 and "empty" not in table  # header, rule, one arm
    cells = [c.strip() for c in rows[2].strip("|").split("|")]
    # units 2; rounds before 1 and 2 → 1.5; after 2 and 2 → 2; minutes before 0.01 and 0.02; after
    # 3500 and 5000 steps → 0.35 and 0.5 min, median 0.425; share 3500/3600 and 5000/5200 → median 0.967
    assert cells[:4] == ["fleet", "2", "1.5", "2"]
    assert cells[4:] == ["0.0", "0.4", "97%"]
    # resets of 6 s: before 6.6 and 13.2 s, after 33 and 42 s → medians 0.165 and 0.625 min; shares 0.833
    # and 0.761 → 0.797
    monkeypatch.setattr("fleetrl_lab.rig_phases.reset_seconds", lambda *_: 6.0)
    cells = [c.strip() for c in phases_table([("fleet", [a, b])]).splitlines()[2].strip("|").split("|")]
    assert cells[4:] == ["0.2", "0.6", "80%"]
    assert phases_lines([("empty", [b])]) == []
