"""Does the paper-code preset complete a task trained alone? Rounds and episodes to completion, per seed.

    python lab/benchmarks/paper_code_preset.py --env cartpole [--seeds 0-4] [--max-rounds 400]
    python lab/benchmarks/paper_code_preset.py --env qube --seeds 0-4 --max-rounds 1000 --json results.json

One learner per seed on unit 0 of fleet seed 0, one torch thread, the env's criterion. Prints per seed the
round and episode at which the criterion held (or the best WMA), episodes per round, the final entropy, CPU
seconds and how the episodes of the last 100 rounds ended; then how many seeds completed.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import statistics
import sys
import time
from collections import Counter, deque
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

# isort: off
import fleetrl  # noqa: F401  (first: it applies FLEETRL_PORTABLE before numpy and torch load)
import gymnasium
import torch

# isort: on
from wide_fleet import parse_pairs

from fleetrl import portable
from fleetrl.agent.config import get_preset
from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.learner import Learner
from fleetrl.envs.catalog import get_env_spec
from fleetrl.envs.qube_balance import ARM_LIMIT, PENDULUM_LIMIT
from fleetrl.runs.factory import agent_for

ENDINGS_WINDOW = 100
"""how many of the last rounds' episode endings are tallied"""


@dataclass
class SeedOutcome:
    """One seed's run."""

    seed: int
    completed_round: int | None
    completed_episode: int | None
    rounds: int
    episodes: int
    best_wma: float
    final_entropy: float
    cpu_seconds: float
    endings: dict[str, int] = field(default_factory=dict)
    """how the episodes of the last ENDINGS_WINDOW rounds ended"""


class EndingTally(gymnasium.Wrapper[Any, Any, Any, Any]):
    """Records why each episode ended: ``pendulum`` (|α| > 7.5°), ``arm`` (|θ| > π/2), ``cap``, ``other``."""

    def __init__(self, env: gymnasium.Env[Any, Any]) -> None:
        super().__init__(env)
        self.round_endings: deque[list[str]] = deque(maxlen=ENDINGS_WINDOW)
        self.current: list[str] = []

    def step(self, action: Any) -> Any:
        obs, reward, terminated, truncated, info = self.env.step(action)
        if terminated:
            alpha, theta = float(obs[0]), float(obs[2])
            self.current.append(
                "pendulum" if abs(alpha) > PENDULUM_LIMIT else "arm" if abs(theta) > ARM_LIMIT else "other"
            )
        elif truncated:
            self.current.append("cap")
        return obs, reward, terminated, truncated, info

    def end_round(self) -> None:
        self.round_endings.append(self.current)
        self.current = []

    def tally(self) -> dict[str, int]:
        return dict(Counter(e for endings in self.round_endings for e in endings))


def setting(text: str) -> tuple[str, Any]:
    """``KEY=VALUE`` with a JSON value (``gamma=0.99``, ``critic_loss="abs"``) for ``--set``."""
    key, _, value = text.partition("=")
    return key, json.loads(value)


def train(
    env_name: str, preset: str, seed: int, max_rounds: int, progress: int, overrides: dict[str, Any]
) -> SeedOutcome:
    spec = get_env_spec(env_name)
    unit_env, unit = spec.make(0, 0)
    env = EndingTally(unit_env)
    config = dataclasses.replace(get_preset(preset), **overrides)
    config.validate()
    agent = agent_for(unit, config, seed=seed)
    learner = Learner(env, agent, CompletionCriterion(spec.default_target(unit)), seed=seed)
    started = time.process_time()
    best_wma, entropy = 0.0, float("nan")
    for _ in range(max_rounds):
        result = learner.play_round()
        env.end_round()
        best_wma = max(best_wma, result.wma)
        entropy = entropy if math.isnan(result.entropy) else result.entropy
        if progress and result.round % progress == 0:
            print(
                f"  seed {seed} round {result.round}: episodes {learner.episodes}, score {result.score:.1f}, "
                f"wma {result.wma:.1f}, entropy {entropy:.3f}",
                flush=True,
            )
        if result.completed:
            break
    cpu = time.process_time() - started
    done = learner.completed
    return SeedOutcome(
        seed,
        learner.rounds if done else None,
        learner.episodes if done else None,
        learner.rounds,
        learner.episodes,
        round(best_wma, 1),
        round(entropy, 4),
        round(cpu, 1),
        env.tally(),
    )


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--env", choices=("cartpole", "qube"), default="cartpole")
    parser.add_argument("--preset", default="paper-code")
    parser.add_argument("--seeds", type=parse_pairs, default=parse_pairs("0-4"), help="e.g. 0-4 or 100-104")
    parser.add_argument("--max-rounds", type=int, default=400)
    parser.add_argument("--progress", type=int, default=0, help="print a line every N rounds (0: never)")
    parser.add_argument("--set", type=setting, action="append", default=[], help="override, e.g. gamma=0.99")
    parser.add_argument("--json", type=Path, default=None, help="also write the outcomes to this file")
    args = parser.parse_args()
    torch.set_num_threads(1)
    host = portable.describe_host()
    changed = "".join(f", {k}={v}" for k, v in args.set)
    print(
        f"# preset {args.preset}{changed}, {args.env} unit 0 alone, M {args.max_rounds}; {host}", flush=True
    )
    settings = {"env": args.env, "preset": args.preset, "set": dict(args.set)}
    settings |= {"max_rounds": args.max_rounds, "host": host}
    outcomes = []
    for seed in args.seeds:
        outcome = train(args.env, args.preset, seed, args.max_rounds, args.progress, dict(args.set))
        outcomes.append(outcome)
        where = (
            f"round {outcome.completed_round}, episode {outcome.completed_episode}"
            if outcome.completed_round is not None
            else f"- (best WMA {outcome.best_wma})"
        )
        print(
            f"seed {seed:4d}: {where}; {outcome.episodes / outcome.rounds:.1f} episodes per round, "
            f"entropy {outcome.final_entropy}, {outcome.cpu_seconds:.0f} s CPU; "
            f"endings of the last {ENDINGS_WINDOW} rounds {outcome.endings}",
            flush=True,
        )
        if args.json is not None:  # after every seed, so a long run leaves what finished
            seeds = [asdict(o) for o in outcomes]
            args.json.write_text(json.dumps({**settings, "seeds": seeds}, indent=1) + "\n")
    done = [o for o in outcomes if o.completed_round is not None]
    rounds = [o.completed_round for o in done if o.completed_round is not None]
    episodes = [o.completed_episode for o in done if o.completed_episode is not None]
    summary = f"completed {len(done)}/{len(outcomes)} within {args.max_rounds} rounds"
    if done:
        summary += (
            f"; rounds median {statistics.median(rounds)} (range {min(rounds)}-{max(rounds)}), "
            f"episodes median {statistics.median(episodes)} (range {min(episodes)}-{max(episodes)})"
        )
    print(summary)
    return 0


if __name__ == "__main__":
    sys.exit(main())
