"""Per-step cost of the agent's acting path and the rollout rate of a worker (env + policy + memory).

    python lab/benchmarks/agent_speed.py [--steps 20000] [--repeats 5]

Medians over repeats of: act + remember (softmax head, Gaussian head on the numba path and through torch),
the rollout of each registered env (target ≥ 25k steps/s per worker), and one PPO update.
"""

import argparse
import statistics
import sys
import time

# isort: off
import fleetrl  # noqa: F401  (first: it applies FLEETRL_PORTABLE before numpy and torch load)
import gymnasium
import numpy as np
import torch

# isort: on
from fleetrl import portable
from fleetrl.agent.action_space import ActionSpace
from fleetrl.agent.config import get_preset
from fleetrl.agent.ppo import PPOAgent
from fleetrl.envs.registration import CARTPOLE_UNIT_ID, QUBE_BALANCE_CONTINUOUS_ID, QUBE_BALANCE_ID

BOX = ActionSpace.box([-3.0], [3.0])
"""the continuous QUBE task's action box"""


def act_and_remember(steps: int, actions: int | ActionSpace = 3) -> float:
    """Seconds per step of act + remember on a fixed observation."""
    agent = PPOAgent(4, actions, get_preset("standard"), seed=0)
    obs = np.zeros(4, dtype=np.float32)
    agent.act(obs)
    started = time.perf_counter()
    for _ in range(steps):
        agent.remember(obs, agent.act(obs), 1.0, obs, False, False)
    return (time.perf_counter() - started) / steps


def act_through_torch(steps: int) -> float:
    """Seconds per step of acting with the Gaussian head through torch (no fast path) + remember."""
    agent = PPOAgent(4, BOX, get_preset("standard"), seed=0)
    obs = np.zeros(4, dtype=np.float32)
    generator = torch.Generator().manual_seed(0)
    started = time.perf_counter()
    for _ in range(steps):
        with torch.no_grad():
            head, _ = agent.net(torch.from_numpy(obs)[None])
            mean, log_std = agent.net.gaussian(head)
            action = (mean + log_std.exp() * torch.randn(mean.shape, generator=generator))[0].numpy()
        agent.remember(obs, action, 1.0, obs, False, False)
    return (time.perf_counter() - started) / steps


def rollout(env_id: str, steps: int) -> float:
    """Steps per second of a worker's rollout (act, env step, remember), resets included."""
    env = gymnasium.make(env_id, unit=0, fleet_seed=0)
    agent = PPOAgent(4, ActionSpace.of(env.action_space), get_preset("standard"), seed=0)
    obs, _ = env.reset(seed=0)
    agent.act(obs)
    started = time.perf_counter()
    for _ in range(steps):
        action = agent.act(obs)
        next_obs, reward, terminated, truncated, _ = env.step(agent.env_action(action))
        agent.remember(obs, action, float(reward), next_obs, terminated, truncated)
        obs = env.reset()[0] if terminated or truncated else next_obs
    return steps / (time.perf_counter() - started)


def update_cost(repeats: int) -> float:
    """Seconds per PPO update (Algorithm 2 lines 11-25) of the standard preset on a full memory."""
    agent = PPOAgent(4, 3, get_preset("standard"), seed=0)
    rng = np.random.default_rng(0)
    for t in range(agent.config.memory_size):
        obs = rng.normal(size=4).astype(np.float32)
        agent.remember(obs, agent.act(obs), 1.0, obs, False, t % 200 == 199)
    agent.update()
    started = time.perf_counter()
    for _ in range(repeats):
        agent.update()
    return (time.perf_counter() - started) / repeats


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--steps", type=int, default=20_000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    torch.set_num_threads(1)
    print(f"# {portable.describe_host()}")
    act = statistics.median(act_and_remember(args.steps) for _ in range(args.repeats))
    print(f"act + remember: {act * 1e6:.1f} µs per step (median of {args.repeats})")
    box = statistics.median(act_and_remember(args.steps, BOX) for _ in range(args.repeats))
    print(f"act + remember, Gaussian head (numba): {box * 1e6:.1f} µs per step ({1 / box:,.0f} steps/s)")
    slow = statistics.median(act_through_torch(args.steps // 4) for _ in range(args.repeats))
    print(
        f"act + remember, Gaussian head through torch: {slow * 1e6:.1f} µs per step ({1 / slow:,.0f} steps/s)"
    )
    for env_id in (CARTPOLE_UNIT_ID, QUBE_BALANCE_ID, QUBE_BALANCE_CONTINUOUS_ID):
        rate = statistics.median(rollout(env_id, args.steps) for _ in range(args.repeats))
        print(f"rollout {env_id}: {rate:,.0f} steps/s (median of {args.repeats}; target ≥ 25,000)")
    update = statistics.median(update_cost(10) for _ in range(args.repeats))
    print(
        f"PPO update, standard preset (K 20, U 128, memory 1000): {update * 1e3:.1f} ms "
        f"(median of {args.repeats})"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
