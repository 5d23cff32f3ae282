"""Drawing a large fleet's scores plot: the summarised plot (one fleet panel) of a synthetic fleet, and for
comparison the per-unit plot (one panel per unit) of a smaller one.

    python lab/benchmarks/fleet_plot.py [--units 1000] [--rounds 200] [--per-unit-units 32]

Prints the wall seconds to build the rows, compute the fleet's quantiles per round, and draw each PNG.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from fleetrl.runs.fleet_summary import fleet_rounds
from fleetrl.runs.plots import plot_run
from fleetrl.runs.records import MetricsRow


def synthetic_fleet(units: int, rounds: int) -> list[MetricsRow]:
    """One row per unit per round, unit u completing at round 20 + u % 300."""
    rows = []
    for u in range(units):
        done = 20 + u % 300
        for r in range(1, rounds + 1):
            wma = min(500.0, 500.0 * r / done)
            rows.append(MetricsRow(r, u, wma, wma, event="completed" if r == done else "gradient"))
    return rows


def timed(what: str, action: Callable[[], object]) -> None:
    """Run ``action`` and print its wall seconds."""
    started = time.perf_counter()
    action()
    print(f"{what}: {time.perf_counter() - started:.2f} s", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--units", type=int, default=1000)
    parser.add_argument("--rounds", type=int, default=200)
    parser.add_argument("--per-unit-units", type=int, default=32)
    args = parser.parse_args()
    print(f"load {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    started = time.perf_counter()
    rows = synthetic_fleet(args.units, args.rounds)
    print(f"{len(rows)} rows built: {time.perf_counter() - started:.2f} s")
    with tempfile.TemporaryDirectory() as tmp:
        timed(
            f"fleet quantiles per round, {args.units} units x {args.rounds} rounds",
            lambda: fleet_rounds(rows),
        )
        timed(
            f"summarised scores.png, {args.units} units x {args.rounds} rounds",
            lambda: plot_run(rows, Path(tmp) / "fleet.png", "fleet", summarise=True, target=475.0),
        )
        few = [r for r in rows if r.worker < args.per_unit_units]
        timed(
            f"per-unit scores.png, {args.per_unit_units} units x {args.rounds} rounds",
            lambda: plot_run(few, Path(tmp) / "units.png", "units"),
        )
    print(f"load {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
