"""One unit of a simulated fleet learning by itself: does it complete, and in how many rounds?

    python lab/benchmarks/unit_alone.py --env qube --unit 48 --seed 100 [--fleet-seed 0] [--fleet-profile P] \
        [--max-rounds 1000]

Prints one JSON line: the rounds played, whether it completed, and its last 20 scores.
"""

from __future__ import annotations

import argparse
import json
import logging

import torch

import fleetrl  # noqa: F401
from fleetrl.agent.config import get_preset
from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.learner import Learner
from fleetrl.envs.catalog import get_env_spec
from fleetrl.portable import describe_host
from fleetrl.runs.factory import agent_for


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env", default="qube")
    p.add_argument("--unit", type=int, required=True)
    p.add_argument("--seed", type=int, required=True)
    p.add_argument("--fleet-seed", type=int, default=0)
    p.add_argument("--fleet-profile", default=None)
    p.add_argument("--max-rounds", type=int, default=1000)
    a = p.parse_args()
    logging.disable(logging.WARNING)  # a hand reset's one-line warning per unit
    torch.set_num_threads(1)
    spec = get_env_spec(a.env)
    env, unit = spec.make(a.unit, a.fleet_seed, fleet_profile=a.fleet_profile)
    learner = Learner(
        env,
        agent_for(unit, get_preset("standard"), seed=a.seed),
        CompletionCriterion(spec.default_target(unit)),
        seed=a.seed,
    )
    scores: list[float] = []
    while len(scores) < a.max_rounds and not learner.completed:
        scores.append(learner.play_round().score)
    report = {"host": describe_host(), "env": a.env, "unit": a.unit, "fleet_seed": a.fleet_seed}
    report |= {"seed": a.seed, "rounds": len(scores), "completed": learner.completed, "last20": scores[-20:]}
    print(json.dumps(report))


if __name__ == "__main__":
    main()
