"""Learning at scale: a CartPole (or QUBE) fleet of N units under the default scheme, until every unit
completes.

    python lab/benchmarks/scale_learning.py --units 1000 --seeds 100 101 102 103 104 [--per-host 500]
        [--env cartpole|qube] [--transport local|mqtt] [--set batch_size=16 ...] [--max-rounds 60]
        [--out DIR] [--records lab/benchmarks/results/scale]

Each (arm, seed) runs ``fleetrl train`` once and leaves a JSON record in ``--records`` (a recorded run is
not run again); prints each run's figures and the medians over the seeds.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from run_memory import peak_pss

FLEETRL = Path(sys.executable).with_name("fleetrl")
FULL_LENGTH = {"cartpole": 500, "qube": 2500}
"""each unit type's step cap: a round in which every unit reached it is a full-length round"""


def arm_name(
    env: str, units: int, per_host: int, overrides: list[str], max_rounds: int, transport: str
) -> str:
    """The arm's record name (a transport other than local ends it)."""
    extra = "".join(f"-{o.replace('=', '')}" for o in sorted(overrides))
    where = "" if transport == "local" else f"-{transport}"
    return f"{env}-n{units}-u{per_host}-m{max_rounds}{extra}{where}"


def figures(run: Path, full_length: int) -> dict[str, object]:
    """What a finished run's metrics.csv says: completions, rounds and full-length rounds' wall time."""
    with (run / "metrics.csv").open() as f:
        rows = list(csv.DictReader(f))
    units = {r["worker"] for r in rows}
    first: dict[str, int] = {}
    ends: dict[int, float] = defaultdict(float)
    short: set[int] = set()
    for r in rows:
        rnd = int(r["round"])
        ends[rnd] = max(ends[rnd], float(r["wall_time"]))
        if int(r["steps"]) < full_length:
            short.add(rnd)
        if r["event"] == "completed":
            first.setdefault(r["worker"], rnd)
    rounds = sorted(ends)
    full = [ends[n] - ends[n - 1] for n in rounds if n > 1 and n not in short and n - 1 in ends]
    return {
        "units": len(units),
        "completed": len(first),
        "fleet_rounds": max(first.values()) if len(first) == len(units) else None,
        "per_unit_median": statistics.median(first.values()) if first else None,
        "rounds_played": rounds[-1],
        "full_length_rounds": len(full),
        "full_length_round_s_median": round(statistics.median(full), 2) if full else None,
    }


def commit() -> str:
    """The checkout's commit (and '+' if it has uncommitted changes)."""
    here = Path(__file__).parent
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=here, capture_output=True, text=True)
    dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=here,
                           capture_output=True, text=True)  # fmt: skip
    return head.stdout.strip() + ("+" if dirty.stdout.strip() else "")


def run_one(argv: list[str], out: Path, record: Path, full_length: int) -> dict[str, object]:
    """Run the command, read its figures, write and return the record."""
    if out.exists():
        shutil.rmtree(out)
    load_before = os.getloadavg()[0]
    started = time.perf_counter()
    with tempfile.TemporaryFile("w+") as errors:  # a file, not a pipe: a full pipe would stop the run
        command = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=errors, text=True)
        peak = peak_pss(command, 2.0)
        wall = time.perf_counter() - started
        if command.returncode != 0:
            errors.seek(0)
            raise SystemExit(f"{' '.join(argv)} exited {command.returncode}: {errors.read()[-500:]}")
    data: dict[str, object] = {
        "command": " ".join(["fleetrl", *argv[1:]]),
        **figures(out, full_length),
        "wall_s": round(wall, 1),
        "peak_tree_pss_mb": round(peak / 2**20),
        "load_before": round(load_before, 1),
        "load_after": round(os.getloadavg()[0], 1),
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
        "commit": commit(),
    }
    record.parent.mkdir(parents=True, exist_ok=True)
    record.write_text(json.dumps(data, indent=1) + "\n")
    return data


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--units", type=int, default=1000)
    parser.add_argument("--env", choices=sorted(FULL_LENGTH), default="cartpole")
    parser.add_argument("--per-host", type=int, default=500)
    parser.add_argument("--transport", choices=("local", "mqtt"), default="local")
    parser.add_argument("--seeds", type=int, nargs="+", required=True)
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--max-rounds", type=int, default=60)
    parser.add_argument("--out", type=Path, default=Path("/tmp/fleetrl-scale"))
    parser.add_argument("--records", type=Path, default=Path(__file__).parent / "results" / "scale")
    args = parser.parse_args()
    arm = arm_name(args.env, args.units, args.per_host, args.overrides, args.max_rounds, args.transport)
    results = []
    for seed in args.seeds:
        record = args.records / arm / f"seed-{seed}.json"
        if record.exists():
            data = json.loads(record.read_text())
        else:
            out = args.out / f"{arm}-seed-{seed}"
            argv = [str(FLEETRL), "train", "--env", args.env, "--units", str(args.units), "--mode",
                    "federated", "--transport", args.transport, "--units-per-host", str(args.per_host),
                    "--seed", str(seed), "--max-rounds", str(args.max_rounds), "--no-live",
                    "--out", str(out)]  # fmt: skip
            argv += [a for o in args.overrides for a in ("--set", o)]
            data = run_one(argv, out, record, FULL_LENGTH[args.env])
        results.append(data)
        print(f"{arm} seed {seed}: {data['completed']}/{data['units']} completed, "
              f"fleet {data['fleet_rounds']}, per unit {data['per_unit_median']}, "
              f"full-length round {data['full_length_round_s_median']} s, wall {data['wall_s']} s, "
              f"peak {data.get('peak_tree_pss_mb', '?')} MB "
              f"(load {data['load_before']} -> {data['load_after']})", flush=True)  # fmt: skip
    fleets = [r["fleet_rounds"] for r in results]
    per_unit = [r["per_unit_median"] for r in results if r["per_unit_median"] is not None]
    fleet_text = statistics.median(fleets) if None not in fleets else f"n/a ({fleets.count(None)} incomplete)"
    print(
        f"{arm}, seeds {' '.join(map(str, args.seeds))}: fleet rounds median {fleet_text}, "
        f"per unit median {statistics.median(per_unit) if per_unit else 'n/a'}"
    )


if __name__ == "__main__":
    main()
