"""A whole federated run with devices behind MQTT device bridges vs in-process devices: episodes/s, wall
time, and whether the run completes.

    python lab/benchmarks/device_link_run.py [--env qube] [--units 3] [--max-rounds 1000] [--seed 0]

Both runs use the in-process federation bus, so the difference is the device link alone; with the same
seed they play the same episodes (lockstep bridges are exact), which the script checks.
"""

import argparse
import json
import sys
import tempfile
from pathlib import Path

from fleetrl.cli.main import main as fleetrl
from fleetrl.runs.records import read_metrics


def run(out: Path, args: argparse.Namespace, link: str) -> dict:
    argv = [
        "train", "--env", args.env, "--units", str(args.units), "--mode", "federated", "--transport", "local",
        "--preset", "standard", "--seed", str(args.seed), "--max-rounds", str(args.max_rounds),
        "--device-link", link, "--out", str(out), "--no-live",
    ]  # fmt: skip
    if fleetrl(argv) != 0:
        raise SystemExit(f"run failed: {' '.join(argv)}")
    summary = json.loads((out / "summary.json").read_text())
    records = read_metrics(out / "metrics.csv")
    return {
        "link": link,
        "episodes": len(records),
        "steps": sum(r.steps for r in records),
        "wall_seconds": summary["wall_seconds"],
        "episodes_per_second": len(records) / summary["wall_seconds"],
        "steps_per_second": sum(r.steps for r in records) / summary["wall_seconds"],
        "completed": all(w["completed_at_round"] is not None for w in summary["workers"].values()),
        "scores": sorted((r.worker, r.round, r.score) for r in records),
    }


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--env", default="qube")
    parser.add_argument("--units", type=int, default=3)
    parser.add_argument("--max-rounds", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        results = [run(Path(tmp) / link, args, link) for link in ("inprocess", "mqtt")]
    print("| device link | episodes | steps | wall s | episodes/s | steps/s | all units completed |")
    print("|---|---|---|---|---|---|---|")
    for r in results:
        print(
            f"| {r['link']} | {r['episodes']} | {r['steps']} | {r['wall_seconds']:.1f} | "
            f"{r['episodes_per_second']:.1f} | {r['steps_per_second']:.0f} | {r['completed']} |"
        )
    same = results[0]["scores"] == results[1]["scores"]
    print(
        f"\nsame episodes over both links: {same}; MQTT / in-process wall time: "
        f"{results[1]['wall_seconds'] / results[0]['wall_seconds']:.1f}×"
    )
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
