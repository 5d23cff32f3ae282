"""A digest of short seeded runs, to show that a refactoring of the learning code changed no number.

    python benchmarks/run_fingerprint.py [--rounds 30]

For each preset that exists in both versions compared (``paper``, ``standard``) and each env (CartPoleUnit,
QubeBalance; unit 0, fleet seed 0, seed 3), plays ``--rounds`` rounds alone and prints the SHA-256 of the
round scores and of the final network parameters. Run it before and after a change on the same machine
(``git stash`` or an exported copy of the old tree on PYTHONPATH): equal digests mean bit-identical runs.
"""

from __future__ import annotations

import argparse
import hashlib
import sys

# isort: off
import fleetrl  # noqa: F401  (first: it applies FLEETRL_PORTABLE before numpy and torch load)
import gymnasium
import numpy as np
import torch

# isort: on
from fleetrl import portable
from fleetrl.agent.config import get_preset
from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.learner import Learner
from fleetrl.agent.ppo import PPOAgent
from fleetrl.envs.registration import CARTPOLE_UNIT_ID, QUBE_BALANCE_ID

SEED = 3


def fingerprint(preset: str, env_id: str, rounds: int) -> tuple[str, str]:
    env = gymnasium.make(env_id, unit=0, fleet_seed=0)
    obs_dim = int(env.observation_space.shape[0])  # type: ignore[index]
    agent = PPOAgent(obs_dim, int(env.action_space.n), get_preset(preset), seed=SEED)  # type: ignore[attr-defined]
    learner = Learner(env, agent, CompletionCriterion(1e9), seed=SEED)
    scores = np.array([learner.play_round().score for _ in range(rounds)], dtype=np.float64)
    params = agent.model_parameters()
    return hashlib.sha256(scores.tobytes()).hexdigest()[:16], hashlib.sha256(params.tobytes()).hexdigest()[
        :16
    ]


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--rounds", type=int, default=30)
    args = parser.parse_args()
    torch.set_num_threads(1)
    print(f"# {args.rounds} rounds, seed {SEED}; {portable.describe_host()}")
    for env_id in (CARTPOLE_UNIT_ID, QUBE_BALANCE_ID):
        for preset in ("paper", "standard"):
            scores, params = fingerprint(preset, env_id, args.rounds)
            print(f"{env_id:26s} {preset:9s} scores {scores} parameters {params}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
