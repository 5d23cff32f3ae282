"""An uneven fleet against the even one (issue 23's targets): a 3-unit CartPole fleet trained by
``fleetrl train`` as it is (even), with its last unit at a quarter of the others' speed (``--slow w2=4``), and
with every unit absent for a random 20 % of rounds (``--absent 0.2``), for one scheme and some seeds.

    python lab/benchmarks/uneven_fleet.py --scheme pergrad --seeds 100 101 102 --out /tmp/uneven
    python lab/benchmarks/uneven_fleet.py --scheme fedavg --seeds 100 --extra "--quorum 0.6 --round-timeout 1"

Prints per run and per arm the wall time until every unit and the healthy units completed and the rounds; a
figure with ``>`` is a lower bound. A run dir holding a summary.json is read, not run again.
"""

from __future__ import annotations

import argparse
import csv
import json
import shlex
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

UNITS = 3
SLOW_UNIT = UNITS - 1
FIGURES = ("every_unit", "healthy", "rounds")


@dataclass(frozen=True)
class Figures:
    """One run's completion, in wall seconds and rounds."""

    every_unit: float  # seconds until the last unit completed
    healthy: float  # seconds until the last healthy unit completed
    rounds: int  # rounds until the last unit completed
    complete: bool  # every unit completed (else the figures are lower bounds)


def run(out: Path, scheme: str, seed: int, flags: list[str], args: argparse.Namespace) -> float:
    """``fleetrl train`` of one arm and seed into ``out``; its wall seconds (0 if it was already there)."""
    if (out / "summary.json").is_file() and not args.fresh:
        return 0.0
    if out.exists():
        subprocess.run(["rm", "-rf", str(out)], check=True)
    command = [
        sys.executable, "-m", "fleetrl.cli.main", "train", "--env", "cartpole", "--units", str(UNITS),
        "--scheme", scheme, "--seed", str(seed), "--max-rounds", str(args.max_rounds),
        "--transport", args.transport, "--no-live", "--out", str(out), *flags, *shlex.split(args.extra),
    ]  # fmt: skip
    if args.pace is not None:
        command += ["--pace", str(args.pace)]
    started = time.monotonic()
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed:\n{done.stderr[-2000:]}")
    return time.monotonic() - started


def completions(out: Path) -> dict[int, tuple[float, int, bool]]:
    """Per worker of the finished run in ``out``: the wall seconds and round at which it completed (else its
    last round's), and whether it completed."""
    summary = json.loads((out / "summary.json").read_text())
    with (out / "metrics.csv").open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    result = {}
    for worker, info in summary["workers"].items():
        mine = [r for r in rows if int(r["worker"]) == int(worker)]
        at = info["completed_at_round"]
        completed = at is not None
        if not completed:
            at = max(int(r["round"]) for r in mine)
        row = next(r for r in mine if int(r["round"]) == at)
        result[int(worker)] = (float(row["wall_time"]), int(at), completed)
    return result


def figures(out: Path, slow_unit: int | None) -> Figures:
    """The completion figures of the finished run in ``out``."""
    units = completions(out)
    healthy = [seconds for w, (seconds, _, _) in units.items() if w != slow_unit]
    every_unit = max(seconds for seconds, _, _ in units.values())
    complete = all(completed for _, _, completed in units.values())
    return Figures(every_unit, max(healthy), max(rnd for _, rnd, _ in units.values()), complete)


def asynchronous(scheme: str) -> bool:
    """Whether ``scheme`` (a name) has no round barrier: its units count their own rounds."""
    from fleetrl.federation.schemes import AsyncScheme, scheme_class

    return issubclass(scheme_class(scheme), AsyncScheme)


def show(value: float, complete: bool, unit: str = "s") -> str:
    return ("" if complete else ">") + (f"{value:.1f}{unit}" if unit == "s" else f"{value:g}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scheme", default="pergrad", help="the federation scheme (default: pergrad)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[100], help="learning seeds (from 100 on)")
    parser.add_argument("--out", type=Path, default=Path("/tmp/uneven-fleet"), help="where the runs go")
    parser.add_argument("--transport", default="mqtt", help="mqtt (processes, embedded broker) or local")
    parser.add_argument("--max-rounds", type=int, default=400, help="M of every run")
    parser.add_argument("--factor", type=float, default=4.0, help="the slow unit's slowdown (default: 4)")
    parser.add_argument("--absent", type=float, default=0.2, help="the absent arm's share of rounds absent")
    parser.add_argument("--pace", type=float, default=None, help="--pace of every arm (default: none)")
    parser.add_argument("--arms", nargs="+", default=["even", "slow", "absent"], help="which arms to run")
    parser.add_argument("--extra", default="", help="more fleetrl train flags for every arm, quoted")
    parser.add_argument("--fresh", action="store_true", help="rerun runs already in --out")
    args = parser.parse_args()
    flags = {
        "even": [],
        "slow": ["--slow", f"w{SLOW_UNIT}={args.factor:g}"],
        "absent": ["--absent", f"{args.absent:g}"],
    }
    results: dict[str, list[Figures]] = {}
    for arm in args.arms:
        for seed in args.seeds:
            out = args.out / args.scheme / arm / f"seed-{seed}"
            took = run(out, args.scheme, seed, flags[arm], args)
            result = figures(out, SLOW_UNIT if arm == "slow" else None)
            results.setdefault(arm, []).append(result)
            print(
                f"{arm:>6} seed {seed}: every unit {show(result.every_unit, result.complete)}, healthy units "
                f"{show(result.healthy, result.complete)}, rounds {show(result.rounds, result.complete, '')}"
                + (f"  (run {took:.0f} s)" if took else "  (read)"),
                flush=True,
            )
    even = results.get("even")
    rounds = "rounds per unit" if asynchronous(args.scheme) else "rounds"
    print(f"\nscheme {args.scheme}, {len(args.seeds)} seed(s), medians (ratio to the even fleet):")
    for arm, runs in results.items():
        medians = [statistics.median(getattr(r, name) for r in runs) for name in FIGURES]
        ratios = ""
        if even and arm != "even":
            base = [statistics.median(getattr(r, name) for r in even) for name in FIGURES]
            ratios = " (" + ", ".join(f"{m / b:.2f}×" for m, b in zip(medians, base, strict=True)) + ")"
        lower = "" if all(r.complete for r in runs) else "  [some unit never completed: lower bounds]"
        every, healthy, count = medians
        print(
            f"  {arm:>6}: every unit {every:.1f} s, healthy units {healthy:.1f} s, {rounds} {count:g}"
            f"{ratios}{lower}"
        )


if __name__ == "__main__":
    main()
