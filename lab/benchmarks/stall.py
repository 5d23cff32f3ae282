"""The stalling-unit table (issue 42, item 6): a 3-unit CartPole fleet trained by ``fleetrl train`` with the
defaults, even, with worker 2 computing 4× slower (``--slow w2=4``) and with worker 2 paused whole 0.75 s of
every second (``--stall w2=0.75``: its computing and its link), over some learning seeds.

    python lab/benchmarks/stall.py --seeds 300 301 302 303 304 --out /tmp/stall

Prints per run and per arm the healthy units' rounds and seconds to completion and worker 2's completion; a
figure with ``>`` is a lower bound. A run dir holding a summary.json is read, not run again.
"""

from __future__ import annotations

import argparse
import os
import statistics
from dataclasses import dataclass
from pathlib import Path

from uneven_fleet import completions
from uneven_fleet import run as train_run

UNEVEN_UNIT = 2
HEALTHY = (0, 1)
ARMS = {"even": [], "slow": ["--slow", f"w{UNEVEN_UNIT}=4"], "stall": ["--stall", f"w{UNEVEN_UNIT}=0.75"]}


@dataclass(frozen=True)
class Row:
    """One run's figures."""

    rounds: int  # rounds until the last healthy unit completed
    seconds: float  # wall seconds until the last healthy unit completed
    complete: bool  # the healthy units completed (else the figures are lower bounds)
    uneven_round: int | None  # the round in which worker 2 completed (None: never)

    @property
    def per_round(self) -> float:
        return self.seconds / self.rounds


def read_row(out: Path) -> Row:
    """The figures of the finished run in ``out``."""
    units = completions(out)
    healthy = [units[worker] for worker in HEALTHY]
    _, uneven, uneven_completed = units[UNEVEN_UNIT]
    return Row(
        max(rnd for _, rnd, _ in healthy),
        max(seconds for seconds, _, _ in healthy),
        all(completed for _, _, completed in healthy),
        uneven if uneven_completed else None,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[300], help="learning seeds (report: ≥ 100)")
    parser.add_argument("--out", type=Path, default=Path("/tmp/stall"), help="where the runs go")
    parser.add_argument("--transport", default="mqtt", help="mqtt (processes, embedded broker) or local")
    parser.add_argument("--max-rounds", type=int, default=400, help="M of every run")
    parser.add_argument("--arms", nargs="+", default=list(ARMS), choices=list(ARMS), help="which arms to run")
    parser.add_argument("--extra", default="", help="more fleetrl train flags for every arm, quoted")
    parser.add_argument("--fresh", action="store_true", help="rerun runs already in --out")
    args = parser.parse_args()
    args.pace = None
    load = os.getloadavg()[0]
    print(f"load average at start: {load:.2f}", flush=True)
    results: dict[str, list[Row]] = {}
    for seed in args.seeds:  # seed by seed: the arms of one seed run at the same load
        for arm in args.arms:
            out = args.out / arm / f"seed-{seed}"
            took = train_run(out, "pergrad", seed, ARMS[arm], args)
            row = read_row(out)
            results.setdefault(arm, []).append(row)
            mark = "" if row.complete else ">"
            unit = "never" if row.uneven_round is None else f"round {row.uneven_round}"
            print(
                f"{arm:>5} seed {seed}: healthy units {mark}{row.rounds} rounds, {mark}{row.seconds:.1f} s, "
                f"{row.per_round:.2f} s/round; w{UNEVEN_UNIT} completed {unit}"
                + (f"  (run {took:.0f} s, load {os.getloadavg()[0]:.1f})" if took else "  (read)"),
                flush=True,
            )
    print(f"\nload average at end: {os.getloadavg()[0]:.2f}")
    print(f"\n| fleet | seeds | rounds | s/round | healthy time | vs even | w{UNEVEN_UNIT} completed |")
    print("|---|---|---|---|---|---|---|")
    even = statistics.median(r.seconds for r in results["even"]) if "even" in results else None
    for arm, runs in results.items():
        seconds = statistics.median(r.seconds for r in runs)
        rounds = statistics.median(r.rounds for r in runs)
        per_round = statistics.median(r.per_round for r in runs)
        ratio = f"{seconds / even:.2f}×" if even else "–"
        done = sum(r.uneven_round is not None for r in runs)
        lower = "" if all(r.complete for r in runs) else " (some lower bounds)"
        seeds = f"{args.seeds[0]}–{args.seeds[-1]}" if len(args.seeds) > 1 else str(args.seeds[0])
        print(
            f"| {arm} {' '.join(ARMS[arm])} | {seeds} | {rounds:g} | {per_round:.2f} | {seconds:.1f} s{lower}"
            f" | {ratio} | {done} of {len(runs)} |"
        )
        print(
            "|  per seed | | "
            + " ".join(str(r.rounds) for r in runs)
            + " | "
            + " ".join(f"{r.per_round:.2f}" for r in runs)
            + " | "
            + " ".join(f"{r.seconds:.1f}" for r in runs)
            + " | | "
            + " ".join("–" if r.uneven_round is None else str(r.uneven_round) for r in runs)
            + " |"
        )


if __name__ == "__main__":
    main()
