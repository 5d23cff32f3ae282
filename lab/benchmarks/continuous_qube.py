"""Episodes to completion of the PPO agent alone on the continuous QUBE task, next to the discrete one.

    python lab/benchmarks/continuous_qube.py [--seeds 0 1 2] [--rounds 400] [--preset standard]
        [--tasks continuous discrete] [--action-volts 3.0]

Each (task, seed) trains unit 0 of fleet 0 in-process, seeded like an individual run's worker 0, until the
criterion (WMA of the last 10 scores ≥ 2450) holds or ``--rounds`` rounds were played.
"""

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
from fleetrl.agent.action_space import ActionSpace
from fleetrl.agent.config import get_preset
from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.learner import Learner
from fleetrl.agent.ppo import PPOAgent
from fleetrl.envs.registration import QUBE_BALANCE_CONTINUOUS_ID, QUBE_BALANCE_ID
from fleetrl.runs.spec import derive_seed

TASKS = {"continuous": QUBE_BALANCE_CONTINUOUS_ID, "discrete": QUBE_BALANCE_ID}
THRESHOLD = 2450.0


def train(
    task: str, seed: int, rounds: int, preset: str, action_volts: float
) -> tuple[int | None, float, float]:
    """(rounds to completion or None, the last weighted moving average, seconds) of one task and seed."""
    kwargs = {"action_volts": action_volts} if task == "continuous" else {}
    env = gymnasium.make(TASKS[task], unit=0, fleet_seed=0, **kwargs)
    worker_seed = derive_seed(seed, 0)
    obs_dim = int(env.observation_space.shape[0])  # type: ignore[index]
    agent = PPOAgent(obs_dim, ActionSpace.of(env.action_space), get_preset(preset), worker_seed)
    learner = Learner(env, agent, CompletionCriterion(THRESHOLD), seed=worker_seed)
    started = time.perf_counter()
    for _ in range(rounds):
        result = learner.play_round()
        if result.completed:
            return result.round, result.wma, time.perf_counter() - started
    return None, learner.criterion.wma, time.perf_counter() - started


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--rounds", type=int, default=400, help="most rounds per seed")
    parser.add_argument("--preset", default="standard")
    parser.add_argument("--tasks", nargs="+", choices=sorted(TASKS), default=["continuous", "discrete"])
    parser.add_argument("--action-volts", type=float, default=3.0, help="the continuous task's box bound (V)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    print(f"# {portable.describe_host()}")
    print(
        f"# preset {args.preset}, at most {args.rounds} rounds, unit 0 of fleet 0, target WMA {THRESHOLD:g}"
    )
    for task in args.tasks:
        done: list[int] = []
        for seed in args.seeds:
            rounds, wma, seconds = train(task, seed, args.rounds, args.preset, args.action_volts)
            shown = f"{rounds} rounds" if rounds is not None else f"not within {args.rounds} rounds"
            print(f"{task:10s} seed {seed}: {shown} (last WMA {wma:.0f}; {seconds:.0f} s)", flush=True)
            if rounds is not None:
                done.append(rounds)
        median = f", median {statistics.median(done):g} rounds" if done else ""
        print(f"{task:10s}: completed on {len(done)} of {len(args.seeds)} seeds{median}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
