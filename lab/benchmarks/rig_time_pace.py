"""Cross-check of the time on the rigs (``fleetrl.runs.rig_time``) against runs stepped in real time.

    python lab/benchmarks/rig_time_pace.py --env cartpole --rounds 25 --pace 1 --out /tmp/rig-pace

Each case (pergrad, fedasync; even and uneven) is trained paced (``--pace S``) and unpaced; the accounting
from the paced run's records is compared with its wall time less the unpaced twin's. Prints a table and
exits 1 if a case is off by more than ``--tolerance``.
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

from fleetrl.envs.catalog import get_env_spec
from fleetrl.runs.rig_time import rig_time, run_units, waits_of

UNEVEN = ("--slow", "w2=4", "--absent", "0.2")
CASES = {
    "pergrad even": ("pergrad", ()),
    "pergrad uneven": ("pergrad", UNEVEN),
    "fedasync even": ("fedasync", ()),
    "fedasync uneven": ("fedasync", UNEVEN),
}


def train(out: Path, env: str, scheme: str, extra: tuple[str, ...], rounds: int, seed: int) -> dict:
    """Run ``fleetrl train`` into ``out`` (kept if it already holds a finished run); its summary."""
    if not (out / "summary.json").is_file():
        fleetrl = str(Path(sys.executable).parent / "fleetrl")
        command = [
            fleetrl, "train", "--env", env, "--mode", "federated", "--scheme", scheme, "--units", "3",
            "--max-rounds", str(rounds), "--seed", str(seed), "--out", str(out), *extra,
        ]  # fmt: skip
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    return dict(json.loads((out / "summary.json").read_text()))


def accounted(run: Path, summary: dict, scale: float) -> float:
    """The fleet's time on the rigs of the paced run in ``run``, its period scaled by ``scale``."""
    config = json.loads((run / "config.json").read_text())
    steps: dict[str, dict[int, int]] = {}
    episodes: dict[str, dict[int, int]] = {}
    with (run / "metrics.csv").open(newline="") as f:
        for row in csv.DictReader(f):
            steps.setdefault(row["worker"], {})[int(row["round"])] = int(row["steps"])
            episodes.setdefault(row["worker"], {})[int(row["round"])] = int(row.get("episodes") or 1)
    completed = {w: summary["workers"][w]["completed_at_round"] for w in steps}
    measured = run_units(steps, completed, config, episodes=episodes)
    units = {w: replace(u, reset=u.reset * scale) for w, u in measured.items()}  # paced, as its steps
    period = get_env_spec(config["env"]).control_period
    assert period is not None
    waits = waits_of(config.get("mode"), config.get("scheme"), config.get("quorum"))
    return rig_time(units, period * scale, waits).fleet


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="cartpole")
    parser.add_argument("--rounds", type=int, default=25)
    parser.add_argument("--pace", type=float, default=1.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--tolerance", type=float, default=0.10)
    parser.add_argument("--out", type=Path, default=Path("runs/rig-time-pace"))
    parser.add_argument("--only", action="append", choices=sorted(CASES), help="run only these cases")
    args = parser.parse_args()
    rows, off = [], []
    for name, (scheme, extra) in CASES.items():
        if args.only and name not in args.only:
            continue
        key = name.replace(" ", "-")
        paced = args.out / f"{key}-paced"
        fast = train(args.out / f"{key}-unpaced", args.env, scheme, extra, args.rounds, args.seed)
        slow = train(paced, args.env, scheme, (*extra, "--pace", str(args.pace)), args.rounds, args.seed)
        rig = accounted(paced, slow, args.pace)
        wall, compute = float(slow["wall_seconds"]), float(fast["wall_seconds"])
        ratio = rig / (wall - compute)
        rows.append(
            f"| {name} | {rig:.1f} | {wall:.1f} | {compute:.1f} | {wall - compute:.1f} | {ratio:.3f} |"
        )
        if abs(ratio - 1) > args.tolerance:
            off.append(name)
        print(rows[-1], flush=True)
    print(f"\n{args.env}, {args.rounds} rounds, --pace {args.pace:g}, seed {args.seed}\n")
    print("| run | accounted s | wall s | compute s | wall − compute | ratio |\n|---|---|---|---|---|---|")
    print("\n".join(rows))
    if off:
        print(f"\noff by more than {args.tolerance:.0%}: {', '.join(off)}")
        return 1
    print(f"\nevery run within {args.tolerance:.0%}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
