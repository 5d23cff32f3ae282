"""A unit joining a learning fleet: a 3-unit QUBE fleet (``fleetrl chief --workers 3`` and three
``fleetrl worker`` processes on an embedded broker); once the chief has closed round ``--at``, a fourth unit,
id 3, joins from the fleet's model. The figure: its own episodes until its completion criterion holds
(target: a median ≤ 20; the criterion's floor is 10).

    python lab/benchmarks/late_join.py --seeds 100 101 102 103 104 105 106 107 108 109 --out runs/late-join

Each seed's run goes to OUT/seed-S and its record to RECORDS/seed-S.json (default
lab/benchmarks/results/late-join, committed); a seed whose record exists is read, not run again.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

from fleetrl.transport.broker import EmbeddedBroker

RECORDS = Path(__file__).parent / "results" / "late-join"
"""the committed records, one per seed"""
TIMEOUT = 1800.0
"""seconds a run may take before it is stopped (its record then says so)"""


def closed_round(chief_log: Path) -> int:
    """The last round the chief closed, from its log (an ``answered`` line names its round)."""
    if not chief_log.exists():
        return 0
    rounds = [
        int(line.split()[1].rstrip(":"))
        for line in chief_log.read_text().splitlines()
        if ": answered " in line and line.startswith("round ")
    ]
    return max(rounds, default=0)


def run_seed(seed: int, at: int, out: Path, extra: list[str]) -> dict[str, object]:
    """One fleet with a unit joining after round ``at``; its record."""
    out.mkdir(parents=True, exist_ok=True)
    run_id = f"late-{seed}"
    with EmbeddedBroker() as broker:
        common = ["--broker", broker.url, "--run-id", run_id, "--env", "qube", "--fleet-seed", "1", *extra]
        procs: dict[str, subprocess.Popen[bytes]] = {}

        def start(role: str, argv: list[str]) -> None:
            log = (out / f"{role}.log").open("ab")
            procs[role] = subprocess.Popen(
                [sys.executable, "-m", "fleetrl.cli.main", *argv, *common],
                stdout=log,
                stderr=subprocess.STDOUT,
            )
            log.close()

        def worker(k: int) -> None:
            start(
                f"w{k}", ["worker", "--worker-id", str(k), "--seed", str(seed), "--out", str(out / f"w{k}")]
            )

        started = time.monotonic()
        start("chief", ["chief", "--workers", "3", "--out", str(out / "chief"), "--idle-timeout", "300"])
        for k in range(3):
            worker(k)
        joined_after = None
        try:
            while time.monotonic() - started < TIMEOUT and procs["chief"].poll() is None:
                if joined_after is None and closed_round(out / "chief" / "chief.log") >= at:
                    joined_after = closed_round(out / "chief" / "chief.log")
                    worker(3)
                time.sleep(0.2)
            codes = {role: proc.wait(timeout=120) for role, proc in procs.items()}
        finally:
            for proc in procs.values():
                if proc.poll() is None:
                    proc.kill()
    summary_path = out / "w3" / "summary.json"
    unit = json.loads(summary_path.read_text())["workers"]["3"] if summary_path.exists() else {}
    chief_path = out / "chief" / "chief.json"
    chief = json.loads(chief_path.read_text()) if chief_path.exists() else {}
    admitted = [
        int(line.split()[1].rstrip(":"))
        for line in (out / "chief" / "chief.log").read_text().splitlines()
        if "worker 3 admitted" in line
    ]
    return {
        "seed": seed,
        "started_after_round": joined_after,
        "admitted_at_round": admitted[0] if admitted else None,
        "episodes_to_complete": unit.get("completed_at_episode"),
        "completed_at_round": unit.get("completed_at_round"),
        "fleet_rounds": chief.get("rounds"),
        "end_reason": chief.get("end_reason"),
        "exit_codes": codes,
        "wall_s": round(time.monotonic() - started, 1),
    }


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seeds", type=int, nargs="+", default=list(range(100, 110)))
    parser.add_argument("--at", type=int, default=40, help="the round after which the new unit joins (40)")
    parser.add_argument("--out", type=Path, required=True, help="where the runs go")
    parser.add_argument("--records", type=Path, default=RECORDS, help=f"the records (default {RECORDS})")
    parser.add_argument("--extra", default="", help="more flags for every role, quoted")
    args = parser.parse_args()
    records = []
    for seed in args.seeds:
        path = args.records / f"seed-{seed}.json"
        if path.exists():
            record = json.loads(path.read_text())
        else:
            record = run_seed(seed, args.at, args.out / f"seed-{seed}", args.extra.split())
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(record, indent=1) + "\n")
        records.append(record)
        print(json.dumps(record), flush=True)
    done = [int(r["episodes_to_complete"]) for r in records if r["episodes_to_complete"] is not None]
    print(
        f"seeds {args.seeds[0]}–{args.seeds[-1]} (fleet seed 1), the new unit joining after round {args.at}:"
    )
    print(
        f"  completed {len(done)} of {len(records)}; its own episodes until its criterion held:", sorted(done)
    )
    if done:
        print(f"  median {statistics.median(done):g} (target ≤ 20; the criterion's floor is 10)")
    return 0 if len(done) == len(records) else 1


if __name__ == "__main__":
    sys.exit(main())
