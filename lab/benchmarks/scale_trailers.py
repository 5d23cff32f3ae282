"""Which units of a large QUBE fleet trail: the units that complete last, with their dynamics as
percentiles of their fleet's, from the records of ``fleetrl experiment qube-scale`` (or any fleet's).

    python lab/benchmarks/scale_trailers.py lab/records/qube-1000-federated-standard-m400-pergrad [--late 60]
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path

import numpy as np
from wide_trailers import COLUMNS, spearman, unit_row


def completion_rounds(directory: Path) -> tuple[dict[int, float], int, str, list[int]]:
    """Each unit's median completion round over the directory's records (never completed: the run's last
    round + 1), the fleet seed, its profile and the seeds read."""
    by_unit: dict[int, list[int]] = {}
    seeds, fleets = [], set()
    for path in sorted(directory.glob("seed-*.json")):
        record = json.loads(path.read_text())
        settings = record["result_settings"]
        seeds.append(settings["seed"])
        fleets.add((settings["fleet_seed"], settings["fleet_profile"]))
        for unit, worker in record["workers"].items():
            done = worker.get("completed_at_round")
            by_unit.setdefault(int(unit), []).append(done if done is not None else len(worker["score"]) + 1)
    if len(fleets) != 1:
        raise SystemExit(f"{directory}: records of {len(fleets)} fleets; one fleet's records are compared")
    (fleet_seed, profile) = fleets.pop()
    return {u: statistics.median(r) for u, r in by_unit.items()}, fleet_seed, profile, seeds


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("records", type=Path, help="a directory of seed-*.json records of one fleet")
    p.add_argument("--late", type=float, default=60, help="a unit whose median round is after this trails")
    a = p.parse_args()
    rounds, fleet_seed, profile, seeds = completion_rounds(a.records)
    units = sorted(rounds)
    rows = {u: unit_row(profile, fleet_seed, u) for u in units}
    late = [u for u in units if rounds[u] > a.late] or sorted(units, key=lambda u: rounds[u])[-10:]
    late.sort(key=lambda u: -rounds[u])
    median = statistics.median(rounds.values())
    print(f"{len(units)} units, fleet seed {fleet_seed} ({profile}), seeds {seeds}: median round {median:g}")
    print(f"{len(late)} units with a median round after {a.late:g}")
    print()
    print("| unit | median round | " + " | ".join(f"{c} (pct)" for c in COLUMNS) + " |")
    print("|---" * (2 + len(COLUMNS)) + "|")
    columns = {c: np.array([rows[u][c] for u in units]) for c in COLUMNS}
    for u in late:
        percentiles = {c: 100 * np.mean(columns[c] <= rows[u][c]) for c in COLUMNS}
        cells = " | ".join(f"{rows[u][c]:.3g} ({percentiles[c]:.0f})" for c in COLUMNS)
        print(f"| {u} | {rounds[u]:g} | {cells} |")
    print()
    print(f"Spearman over {len(units)} units, each column against the median round:")
    for c in COLUMNS:
        print(f"- {c}: {spearman(list(columns[c]), [rounds[u] for u in units]):+.2f}")


if __name__ == "__main__":
    main()
