"""Rounds to completion of finished ``fleetrl train`` runs, one arm per directory: prints, per arm, each
seed's "rounds until the last unit completes" and the medians of that and of "rounds per unit".

    python lab/benchmarks/run_table.py /tmp/tune/q/alone /tmp/tune/q/pergrad   # each holds seed-<n>/ run dirs

A unit that never completed counts as the run's M and the figure gets ">" (a lower bound).
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path


def completion(run: Path) -> tuple[int, list[int], bool]:
    """(fleet rounds, per-unit rounds, all completed) of one finished run directory."""
    summary = json.loads((run / "summary.json").read_text())
    config = json.loads((run / "config.json").read_text())
    cap = int(config["max_rounds"])
    rounds = [
        info["completed_at_round"]
        for _, info in sorted(summary["workers"].items(), key=lambda kv: int(kv[0]))
    ]
    per_unit = [cap if r is None else int(r) for r in rounds]
    return max(per_unit), per_unit, all(r is not None for r in rounds)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("arms", nargs="+", type=Path, help="directories of seed-<n> run directories")
    args = parser.parse_args()
    for arm in args.arms:
        runs = sorted(
            (p for p in arm.glob("seed-*") if (p / "summary.json").is_file()),
            key=lambda p: int(p.name.split("-")[1]),
        )
        if not runs:
            print(f"{arm}: no finished run")
            continue
        fleets, units, cells = [], [], []
        for run in runs:
            fleet, per_unit, complete = completion(run)
            fleets.append(fleet)
            units += per_unit
            cells.append(
                f"{run.name.split('-')[1]}: {'' if complete else '>'}{fleet} ({'/'.join(map(str, per_unit))})"
            )
        print(
            f"{arm.name}: median fleet {statistics.median(fleets):g}, "
            f"median per unit {statistics.median(units):g} over {len(runs)} seeds | " + "; ".join(cells)
        )


if __name__ == "__main__":
    main()
