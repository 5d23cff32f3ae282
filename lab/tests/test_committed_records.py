"""The run records committed under lab/records are what ``make results`` builds the report from: a
change to what a run's result settings hold must leave every committed record matching its arm, or the
report silently turns back to "not run yet" (a scheme parameter added at its default did exactly that)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from fleetrl_lab.arms import FULL, Places
from fleetrl_lab.catalog import PLANS
from fleetrl_lab.records import read_record

RECORDS = Path(__file__).resolve().parents[1] / "records"


def test_every_committed_record_of_a_plans_arm_is_still_its_runs_record(tmp_path: Path) -> None:
    places = Places(tmp_path / "runs", RECORDS)
    checked, stale = 0, []
    for fleet_seed in (0, 1):
        budget = replace(FULL, fleet_seed=fleet_seed)
        for name, make in PLANS.items():
            for arm in make(budget).arms:
                for path in sorted((RECORDS / arm.key).glob("seed-*.json")):
                    run = arm.run(places, int(path.stem.removeprefix("seed-")))
                    record = read_record(path)
                    assert record is not None, path
                    checked += 1
                    if not run.done:
                        stale.append(f"{name}: {arm.key}/{path.name}")
    assert checked >= 100, f"only {checked} committed records belong to a plan's arm"
    assert not stale, f"{len(stale)} of {checked} records no longer match their arm, e.g. {stale[:5]}"
