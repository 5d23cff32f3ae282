"""Unseen units fitted in a few episodes: the share of greedy episodes held to the cap before and after.

    python lab/benchmarks/adapt_unseen.py RUN/models/worker-0.safetensors --fleet-profile wide \
        --fleet-seed 1 --units 3-22 [--episodes 0,1,3,5] [--check 10] [--own-part biases] [--seed 0] \
        [--record FILE]
    python lab/benchmarks/adapt_unseen.py --pool lab/records/adapt-unseen/wide-u3/shared

For each unit (none of them trained in the fleet) and each budget E of ``--episodes``: ``fleetrl adapt``'s
fit (:func:`fleetrl.runs.adapt.adapt_model`) of E episodes from the fleet's policy, then ``--check`` greedy
episodes; E = 0 is the fleet's policy as it is. Prints, per budget, the share of check episodes held to the
cap over every unit, the units that held every one, and the median time on the rig the fit took.
"""

from __future__ import annotations

import argparse
import json
import shlex
import statistics
import sys
from pathlib import Path

from wide_fleet import parse_pairs

from fleetrl.portable import describe_host
from fleetrl.runs.adapt import adapt_model


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("model", type=Path, nargs="?")
    p.add_argument("--env", default="qube")
    p.add_argument("--fleet-profile", default=None)
    p.add_argument("--fleet-seed", type=int, default=0)
    p.add_argument("--units", default="3-22")
    p.add_argument("--episodes", default="0,1,3,5")
    p.add_argument("--check", type=int, default=10)
    p.add_argument("--own-part", default=None)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--record", type=Path, default=None, help="write the budgets' rows here as a JSON record")
    p.add_argument("--pool", type=Path, default=None, help="print the table pooled over a folder of records")
    a = p.parse_args()
    if a.pool is not None:
        print_pooled(a.pool)
        return
    if a.model is None:
        p.error("name a model file, or --pool a folder of records")
    units, budgets = parse_pairs(a.units), parse_pairs(a.episodes)
    rows = []
    for budget in budgets:
        held = episodes = every = 0
        rig: list[float] = []
        for unit in units:
            done = adapt_model(
                a.model, a.env, unit, fleet_seed=a.fleet_seed, fleet_profile=a.fleet_profile,
                episodes=max(budget, 1), check=a.check, seed=a.seed, own_part=a.own_part,
            )  # fmt: skip
            scores = done.before if budget == 0 else done.after
            count = sum(s >= (done.cap or float("inf")) for s in scores)
            held, episodes, every = held + count, episodes + len(scores), every + (count == len(scores))
            rig.append(0.0 if budget == 0 else done.rig_seconds or 0.0)
        row = {"episodes": budget, "held": held / episodes, "units_all_held": every, "units": len(units)}
        rows.append(row | {"rig_seconds_median": statistics.median(rig)})
        print(json.dumps(rows[-1]), flush=True)
    print(f"{a.model}; {a.env} {a.fleet_profile or 'default'} fleet seed {a.fleet_seed}, units {a.units}, "
          f"{a.check} check episodes each (seed {a.seed}); {describe_host()}")  # fmt: skip
    print("| episodes of its own | episodes held to the cap | units holding all | time on the rig, median |")
    print("|---|---|---|---|")
    for row in rows:
        print(f"| {row['episodes']} | {100 * row['held']:.0f} % | {row['units_all_held']}/{row['units']} "
              f"| {row['rig_seconds_median']:.0f} s |")  # fmt: skip
    if a.record is not None:
        command, host = shlex.join(sys.argv), describe_host()
        record = {"format": 1, "model": str(a.model), "command": command, "host": host}
        a.record.write_text(json.dumps(record | {"budgets": rows}, indent=1) + "\n")


def print_pooled(folder: Path) -> None:
    """The budgets' rows pooled over every record in ``folder`` (fleets of as many units and checks each):
    the mean share held, the units holding every check, the median of the fleets' median rig times."""
    records = [json.loads(f.read_text()) for f in sorted(folder.glob("*.json"))]
    if not records:
        raise SystemExit(f"no records in {folder}")
    print(f"{folder}: {len(records)} fleets")
    print("| episodes of its own | episodes held to the cap | units holding all | time on the rig, median |")
    print("|---|---|---|---|")
    for k, row in enumerate(records[0]["budgets"]):
        rows = [rec["budgets"][k] for rec in records]
        held = statistics.mean(r["held"] for r in rows)
        every, units = sum(r["units_all_held"] for r in rows), sum(r["units"] for r in rows)
        rig = statistics.median(r["rig_seconds_median"] for r in rows)
        print(f"| {row['episodes']} | {100 * held:.1f} % | {every}/{units} | {rig:.0f} s |")


if __name__ == "__main__":
    main()
