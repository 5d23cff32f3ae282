"""Rounds until a PPO preset completes fleetrl/CartPoleUnit-v0 (unit 0, fleet seed 0) alone, per seed.

    python lab/benchmarks/preset_rounds.py [--preset standard] [--seeds 0-9] [--max-rounds 400]

One learner per seed, one torch thread, criterion WMA ≥ 475; prints each seed's rounds ("-": none) and the
median.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

# isort: off
import fleetrl  # noqa: F401  (first: it applies FLEETRL_PORTABLE before numpy and torch load)
import gymnasium
import torch

# isort: on
from fleetrl import portable
from fleetrl.agent.config import get_preset
from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.learner import Learner
from fleetrl.agent.ppo import PPOAgent
from fleetrl.envs.registration import CARTPOLE_UNIT_ID


def seed_range(text: str) -> list[int]:
    first, _, last = text.partition("-")
    return list(range(int(first), int(last or first) + 1))


def rounds_to_completion(preset: str, seed: int, max_rounds: int) -> int | None:
    env = gymnasium.make(CARTPOLE_UNIT_ID, unit=0, fleet_seed=0)
    agent = PPOAgent(4, 2, get_preset(preset), seed=seed)
    learner = Learner(env, agent, CompletionCriterion(475.0), seed=seed)
    for _ in range(max_rounds):
        result = learner.play_round()
        if result.completed:
            return result.round
    return None


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--preset", default="standard")
    parser.add_argument("--seeds", type=seed_range, default=seed_range("0-9"), help="e.g. 0-9 or 100-104")
    parser.add_argument("--max-rounds", type=int, default=400)
    args = parser.parse_args()
    torch.set_num_threads(1)
    print(f"# preset {args.preset}, CartPoleUnit unit 0; {portable.describe_host()}")
    found: list[int] = []
    started = time.process_time()
    for seed in args.seeds:
        rounds = rounds_to_completion(args.preset, seed, args.max_rounds)
        print(f"seed {seed:4d}: {rounds if rounds is not None else '-'}", flush=True)
        if rounds is not None:
            found.append(rounds)
    median = statistics.median(found) if found else float("nan")
    print(
        f"completed {len(found)}/{len(args.seeds)} within {args.max_rounds} rounds; median {median}, "
        f"range {min(found, default=0)}-{max(found, default=0)}; {time.process_time() - started:.0f} s of CPU"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
