"""How a fleet's last units fared round by round: their WMA and π_θ's entropy on their states, beside how many
units had completed, how many held the target then and the fleet's median entropy, from one run directory's
metrics.csv and config.json.

    python lab/benchmarks/trailer_course.py RUN_DIR [--last 3] [--every 10]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from fleetrl.runs.records import read_metrics
from fleetrl_lab.trailer_course import read_course


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path, help="a run directory (its metrics.csv is read)")
    p.add_argument("--last", type=int, default=3, help="how many of the last units to follow")
    p.add_argument("--every", type=int, default=10, help="print a row every this many rounds")
    a = p.parse_args()
    metrics, config = a.run / "metrics.csv", a.run / "config.json"
    for needed in (metrics, config):
        if not needed.is_file():
            raise SystemExit(f"{needed}: no such file (a run directory of `fleetrl train` has one)")
    target = json.loads(config.read_text()).get("target_score")
    if target is None:
        raise SystemExit(
            f"{config}: no target_score (written by a fleetrl older than the run directories read here)"
        )
    course = read_course(read_metrics(metrics))
    rounds = course.rounds
    units = course.last_units(a.last)
    done = ", ".join(f"unit {u}: {course.completed_at.get(u, 'not completed')}" for u in units)
    print(f"{a.run}: {len(course.units)} units, {len(rounds)} rounds; the last units complete at: {done}")
    print()
    heads = ["round", "units completed", f"units at WMA ≥ {target:g}", "fleet's median entropy"]
    heads += [f"unit {u}: WMA (entropy)" for u in units]
    print("| " + " | ".join(heads) + " |")
    print("|---" * len(heads) + "|")
    for r in [r for r in rounds if r % a.every == 0 or r == rounds[-1]]:
        cells = [str(r), str(course.completed_by(r)), str(course.holding(r, target))]
        cells.append(f"{course.median_entropy(r):.2f}")
        for u in units:
            cells.append(
                f"{course.wma[r][u]:.0f} ({course.entropy[r][u]:.2f})" if u in course.wma[r] else "—"
            )
        print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
