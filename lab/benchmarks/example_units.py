"""Figures of the DC-motor example (examples/dc-motor, ``fleet_dc_motor``): what a random policy and an
untrained agent score, how many held-out seeds a federated fleet over mosquitto brings to the target and in
how many rounds, and what the trained policies score (``fleetrl evaluate``) on their own and unseen units.

    python lab/benchmarks/example_units.py [--seeds 100-104] [--units 3] [--target -10] [--episodes 10]
        [--max-rounds 300] [--out runs/example-units] [--broker mqtt://127.0.0.1:PORT]

A seed whose run directory already has a summary.json is reused; one seed takes minutes on 2 cores.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "examples" / "dc-motor"
sys.path.insert(0, str(EXAMPLE))

# isort: off
import fleetrl  # noqa: E402, F401  (first: it applies FLEETRL_PORTABLE before torch loads)
import torch  # noqa: E402
from fleet_dc_motor.units import factory  # noqa: E402

# isort: on
from wide_fleet import parse_pairs  # noqa: E402

from fleetrl import portable  # noqa: E402
from fleetrl.agent.action_space import ActionSpace  # noqa: E402
from fleetrl.agent.config import get_preset  # noqa: E402
from fleetrl.agent.ppo import PPOAgent  # noqa: E402
from fleetrl.control.policies import greedy_scores  # noqa: E402
from fleetrl.transport.broker import EmbeddedBroker  # noqa: E402

FACTORY = "fleet_dc_motor.units:factory"
PRESET = "standard"
Policy = Callable[[np.ndarray], np.ndarray]


def mean_score(policy: Callable[[object], Policy], units: range, episodes: int) -> float:
    """The mean score of ``episodes`` episodes (reset seeds 0, 1, …) on each unit of fleet 0;
    ``policy(space)`` makes the policy for a unit's action space."""
    scores = []
    for unit in units:
        env = factory(unit, 0)
        scores += greedy_scores(env, policy(env.action_space), episodes)  # type: ignore[arg-type]
        env.close()
    return float(np.mean(scores))


def random_policy(space: object) -> Policy:
    """Uniform duty cycles from the action space (its own seeded generator)."""
    space.seed(0)  # type: ignore[attr-defined]
    return lambda obs: space.sample()  # type: ignore[attr-defined,no-any-return]


def untrained(seed: int, greedy: bool) -> Callable[[object], Policy]:
    """A fresh agent of the run's preset, as seed ``seed`` starts the fleet (its mean, or its samples)."""

    def make(space: object) -> Policy:
        agent = PPOAgent(3, ActionSpace.of(space), get_preset(PRESET), seed=seed)  # type: ignore[arg-type]
        if greedy:
            return agent.act_greedy  # type: ignore[no-any-return]
        return lambda obs: agent.env_action(agent.act(obs))  # type: ignore[no-any-return]

    return make


def fleetrl_command(*argv: str) -> subprocess.CompletedProcess[str]:
    """``fleetrl ARGV`` from the repository root, the example on PYTHONPATH; its output as text."""
    env = dict(
        os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(EXAMPLE), os.environ.get("PYTHONPATH")]))
    )
    done = subprocess.run(
        [sys.executable, "-m", "fleetrl.cli.main", *argv], cwd=REPO, env=env, capture_output=True, text=True
    )
    if done.returncode != 0:
        sys.exit(f"fleetrl {' '.join(argv)} failed ({done.returncode}): {done.stderr.strip()[-400:]}")
    return done


def train_argv(seed: int, args: argparse.Namespace, broker: str, out: Path) -> list[str]:
    """The command line of one seed's federated run."""
    return [
        "train", "--env", FACTORY, "--units", str(args.units), "--mode", "federated", "--preset", PRESET,
        "--target-score", f"{args.target:g}", "--seed", str(seed), "--max-rounds", str(args.max_rounds),
        "--broker", broker, "--no-live", "--out", str(out),
    ]  # fmt: skip


def fleet_rounds(run: Path, units: int) -> int | None:
    """The round at which the last unit completed, or None if one did not."""
    completed = json.loads((run / "summary.json").read_text())["chief"]["completed"]
    return max(completed.values()) if len(completed) == units else None


def evaluate(model: Path, unit: int, episodes: int) -> float:
    """``fleetrl evaluate``'s mean greedy score of ``model`` on ``unit`` of fleet 0."""
    done = fleetrl_command("evaluate", str(model), "--env", FACTORY, "--unit", str(unit), "--episodes",
                           str(episodes))  # fmt: skip
    return float(np.mean(json.loads(done.stdout)["scores"]))


def run_seeds(args: argparse.Namespace, url: str, units: range, unseen: range) -> None:
    """Train (or reuse) each seed's run on the broker at ``url``, evaluate it, print its line and the sum."""
    rounds: dict[int, int | None] = {}
    own: list[float] = []
    others: list[float] = []
    for seed in args.seeds:
        run = args.out / f"seed-{seed}"
        argv = train_argv(seed, args, url, run)
        if not (run / "summary.json").is_file():
            print("$ fleetrl " + " ".join(argv), flush=True)
            fleetrl_command(*argv)
        rounds[seed] = fleet_rounds(run, args.units)
        models = run / "models"
        own.append(
            statistics.mean(evaluate(models / f"worker-{u}.safetensors", u, args.episodes) for u in units)
        )
        others.append(
            statistics.mean(evaluate(models / "worker-0.safetensors", u, args.episodes) for u in unseen)
        )
        shown = "not reached" if rounds[seed] is None else f"{rounds[seed]} rounds"
        print(
            f"seed {seed}: {shown}; trained greedy score {own[-1]:.1f} on its units, {others[-1]:.1f} "
            f"(worker 0's policy) on unseen units {unseen.start}-{unseen.stop - 1}",
            flush=True,
        )
    reached = [r for r in rounds.values() if r is not None]
    median = f"{statistics.median(reached):g}" if reached else "-"
    print(
        f"{len(reached)} of {len(rounds)} seeds reached the target {args.target:g} within {args.max_rounds} "
        f"rounds; median {median} rounds (the last unit's); trained greedy score "
        f"{statistics.mean(own):.1f} on their units, {statistics.mean(others):.1f} on unseen units"
    )


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seeds", type=parse_pairs, default=parse_pairs("100-104"), help="e.g. 100-104")
    parser.add_argument("--units", type=int, default=3)
    parser.add_argument("--target", type=float, default=-10.0, help="the target score")
    parser.add_argument("--episodes", type=int, default=10, help="episodes per unit for every mean score")
    parser.add_argument("--max-rounds", type=int, default=300)
    parser.add_argument("--out", type=Path, default=Path("runs/example-units"))
    parser.add_argument("--broker", help="mqtt://host:port of a running broker (default: start mosquitto)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    units, unseen = range(args.units), range(args.units, args.units + 5)
    n = args.episodes
    print(f"# {portable.describe_host()}")
    print(f"# {FACTORY}, fleet seed 0, {n} episodes per unit (reset seeds 0-{n - 1})")
    print(f"random policy on units {units.start}-{units.stop - 1}: {mean_score(random_policy, units, n):.1f}")
    greedy = statistics.mean(mean_score(untrained(s, True), units, n) for s in args.seeds)
    sampled = statistics.mean(mean_score(untrained(s, False), units, n) for s in args.seeds)
    seeds = f"{args.seeds[0]}-{args.seeds[-1]}"
    print(f"untrained agent (seeds {seeds}): greedy {greedy:.1f}, sampled {sampled:.1f}")
    if args.broker is not None:
        run_seeds(args, args.broker, units, unseen)
    else:
        with EmbeddedBroker("mosquitto") as broker:
            run_seeds(args, broker.url, units, unseen)
    return 0


if __name__ == "__main__":
    sys.exit(main())
