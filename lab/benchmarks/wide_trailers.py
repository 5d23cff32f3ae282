"""Which units trail in a fleet: each unit's rounds beside its dynamics, from wide_fleet.py's records.

    python lab/benchmarks/wide_trailers.py --profile wide --units 3 --pairs 100-109 [--arm shared]

Prints each unit's rounds and dynamics, then each column's Spearman correlation with the rounds.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from wide_fleet import parse_pairs, records_dir

from fleetrl.devices.qube.params import NOMINAL, fleet_profile, qube_unit_params
from fleetrl.runs.rig_time import reset_seconds

COLUMNS = ("authority", "dead zone V", "cable N·m/rad", "pendulum m·L", "swing-up s")


def spearman(x: list[float], y: list[float]) -> float:
    """Spearman's rank correlation (ranks by argsort; no ties expected among floats)."""
    rx = np.argsort(np.argsort(x)).astype(float)
    ry = np.argsort(np.argsort(y)).astype(float)
    return float(np.corrcoef(rx, ry)[0, 1])


def unit_row(profile: str, fleet_seed: int, unit: int) -> dict[str, float]:
    """One unit's dynamics, as the columns name them."""
    p = qube_unit_params(fleet_seed, unit, fleet_profile(profile).variation)
    return {
        "authority": (p.km / p.Rm) / (NOMINAL.km / NOMINAL.Rm),
        "dead zone V": p.deadband_volts,
        "cable N·m/rad": p.cable_stiffness,
        "pendulum m·L": (p.mp * p.Lp) / (NOMINAL.mp * NOMINAL.Lp),
        "swing-up s": reset_seconds("qube", unit, fleet_seed, profile),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--profile", default="wide")
    p.add_argument("--units", type=int, default=3)
    p.add_argument("--pairs", default="100-109")
    p.add_argument("--arm", default="shared")
    p.add_argument("--records", type=Path, default=Path("lab/records/wide-fleet"))
    a = p.parse_args()
    base = records_dir(a.records, a.profile, a.units)
    rows = []
    for pair in parse_pairs(a.pairs):
        alone = json.loads((base / "alone" / f"pair-{pair}.json").read_text())["rounds"]
        fleet = json.loads((base / a.arm / f"pair-{pair}.json").read_text())["rounds"]
        for unit in range(a.units):
            rows.append({"pair": pair, "unit": unit, "alone": alone[unit], "fleet": fleet[unit],
                         "last": fleet[unit] == max(fleet), **unit_row(a.profile, pair, unit)})  # fmt: skip
    print(f"| pair | unit | alone | {a.arm} | " + " | ".join(COLUMNS) + " |")
    print("|---" * (4 + len(COLUMNS)) + "|")
    for r in rows:
        mark = " (last)" if r["last"] else ""
        cells = " | ".join(f"{r[c]:.3g}" for c in COLUMNS)
        print(f"| {r['pair']} | {r['unit']} | {r['alone']} | {r['fleet']}{mark} | {cells} |")
    print()
    print(f"Spearman over {len(rows)} units | rounds in {a.arm} | rounds alone |")
    print("|---|---|---|")
    for c in (*COLUMNS, "alone"):
        column = [float(r[c]) for r in rows]
        in_fleet = spearman(column, [float(r["fleet"]) for r in rows])
        alone_rho = spearman(column, [float(r["alone"]) for r in rows]) if c != "alone" else 1.0
        print(f"| {c} | {in_fleet:+.2f} | {alone_rho:+.2f} |")
    lasts = [r for r in rows if r["last"]]
    print()
    print(f"The last unit of each pair against the median of all {len(rows)} units:")
    for c in COLUMNS:
        last_median, all_median = np.median([r[c] for r in lasts]), np.median([r[c] for r in rows])
        print(f"- {c}: last units {last_median:.3g}, all {all_median:.3g}")


if __name__ == "__main__":
    main()
