"""Rounds (episodes) to completion of the PPO agent alone, both presets, CartPole and QUBE, next to
Stable-Baselines3 PPO (defaults) on the same registered envs and criterion.

    python lab/benchmarks/learning.py [--seeds 5] [--out runs/experiments] [--quick]

Runs `fleetrl experiment learning` and `fleetrl experiment peers` (runs already in --out are reused) and
prints their report sections; the figures in docs/benchmarks.md come from this command.
"""

import argparse
import sys
from pathlib import Path

from fleetrl_lab.runner import run_experiment


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--out", type=Path, default=Path("runs/experiments"))
    parser.add_argument("--quick", action="store_true", help="tiny budgets (pipeline check only)")
    args = parser.parse_args()
    seeds = list(range(args.seeds))
    for name in ("learning", "peers"):
        run_experiment(name, args.out, seeds, args.quick)
        print((args.out / name / "section.md").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
