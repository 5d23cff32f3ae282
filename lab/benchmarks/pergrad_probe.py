"""Tuning probe for per-step gradient averaging (the ``pergrad`` rule) without the chief: N agents in one
process average their step gradients at every optimisation step; ``--arm alone`` trains each unit by itself.
Prints one JSON line: rounds until the last unit completes and per unit, per seed (tuning seeds 0-9 only).

    python lab/benchmarks/pergrad_probe.py --env cartpole --units 3 --seeds 0-4 --arm pergrad [--k-scale 3]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time

import numpy as np
import torch

import fleetrl  # noqa: F401
from fleetrl.agent.config import get_preset
from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.learner import Learner
from fleetrl.envs.catalog import get_env_spec
from fleetrl.portable import describe_host
from fleetrl.runs.factory import agent_for
from fleetrl.runs.rig_time import NO_BARRIER, Waits, rig_time, run_units
from fleetrl.runs.spec import derive_seed


def seeds_arg(text: str) -> list[int]:
    a, _, b = text.partition("-")
    return list(range(int(a), int(b or a) + 1))


def run(args: argparse.Namespace, seed: int) -> dict:
    """One seed's run of the parsed command line ``args``."""
    torch.set_num_threads(1)
    units, arm, m, fleet_seed = args.units, args.arm, args.max_rounds, args.fleet_seed
    spec = get_env_spec(args.env)
    base = dataclasses.replace(get_preset(args.preset), **dict(args.set))
    base.validate()
    config = dataclasses.replace(
        base,
        actor_lr=base.actor_lr * args.lr_scale,
        critic_lr=base.critic_lr * args.lr_scale,
        n_optimisations=max(1, round(base.n_optimisations * args.k_scale)),
        batch_size=max(1, round(base.batch_size * args.b_scale)),
        memory_size=max(base.memory_size, round(base.batch_size * args.b_scale)),
    )
    learners = []
    for k in range(units):
        env, unit = spec.make(k, fleet_seed)
        agent = agent_for(unit, config, seed=derive_seed(seed, k))
        criterion = CompletionCriterion(spec.default_target(unit))
        learners.append(
            Learner(env, agent, criterion, seed=derive_seed(seed, k), keep_learning=arm != "alone")
        )
    if arm != "alone":
        start = learners[0].agent.model_parameters()
        for learner in learners[1:]:
            learner.agent.set_model_parameters(start)
    done_at: list[int | None] = [None] * units
    steps: list[list[int]] = [[] for _ in range(units)]
    started = time.monotonic()
    for rnd in range(1, m + 1):
        active = [i for i in range(units) if arm != "alone" or done_at[i] is None]
        for i in active:
            (played,) = learners[i].play_episodes()
            steps[i].append(int(sum(played.steps)))
            if done_at[i] is None and learners[i].criterion.done:
                done_at[i] = rnd
        if all(d is not None for d in done_at):
            break
        if arm == "alone":
            for i in active:
                if done_at[i] is None:
                    learners[i].agent.update()
            continue
        agents = [learners[i].agent for i in active]
        (n_steps,) = {a.begin_update() for a in agents}  # every agent begins; all take the same K
        for step in range(n_steps):
            grads = np.stack([a.step_gradients(step) for a in agents])
            mean = grads.mean(axis=0).astype(np.float32)
            for a in agents:
                a.apply_step(mean)
        for a in agents:
            a.end_update()
    rounds = [m if d is None else d for d in done_at]
    rig_minutes = None  # a unit type whose control period is not known has no time on the rigs
    if spec.control_period is not None:
        waits = NO_BARRIER if arm == "alone" else Waits(barrier=True)
        played = {str(i): steps[i] for i in range(units)}
        settings = {"env": args.env, "fleet_seed": fleet_seed}
        plays = run_units(played, {str(i): d for i, d in enumerate(done_at)}, settings)
        rig = rig_time(plays, spec.control_period, waits)
        rig_minutes = round(rig.fleet / 60, 2)
    return {
        "rig_fleet_min": rig_minutes,
        "seed": seed,
        "fleet": max(rounds),
        "units": rounds,
        "complete": all(d is not None for d in done_at),
        "wall": round(time.monotonic() - started, 1),
    }


def override_arg(text: str) -> tuple[str, object]:
    key, _, value = text.partition("=")
    try:
        return key, json.loads(value)
    except json.JSONDecodeError:
        return key, value


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--env", default="cartpole")
    p.add_argument("--units", type=int, default=3)
    p.add_argument("--seeds", type=seeds_arg, default=seeds_arg("0-4"))
    p.add_argument("--arm", default="pergrad", choices=("alone", "pergrad"))
    p.add_argument("--lr-scale", type=float, default=1.0)
    p.add_argument("--k-scale", type=float, default=1.0)
    p.add_argument("--b-scale", type=float, default=1.0)
    p.add_argument("--max-rounds", type=int, default=400)
    p.add_argument("--preset", default="standard")
    p.add_argument("--fleet-seed", type=int, default=0)
    p.add_argument("--set", type=override_arg, action="append", default=[], metavar="KEY=VALUE")
    a = p.parse_args()
    results = [run(a, s) for s in a.seeds]
    fleet = [r["fleet"] for r in results]
    per_unit = [u for r in results for u in r["units"]]
    print(describe_host(), file=sys.stderr)
    medians = {"fleet_median": float(np.median(fleet)), "unit_median": float(np.median(per_unit))}
    print(json.dumps({"args": vars(a) | {"seeds": a.seeds}, **medians, "runs": results}))


if __name__ == "__main__":
    main()
