"""A unit fitted in a few episodes: the fleet's policy, its shared part held, its own part learned on the unit
(a unit that joins, or one the fleet never saw). ``fleetrl adapt``."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from fleetrl.agent.config import OWN_PART_NAMES, PPOConfig
from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.learner import Learner
from fleetrl.agent.ppo import PPOAgent, UpdateStats
from fleetrl.control.policies import greedy_scores
from fleetrl.runs.evaluate import load_policy
from fleetrl.runs.rig_time import reset_seconds

DEFAULT_ADAPT_PART = "biases"
"""the own part fitted when the fleet's model has none"""


@dataclass(frozen=True)
class Adapted:
    """What adapting one unit did: the scores and steps of the episodes it played to adapt, their time on a
    rig (None: unknown), the greedy check episodes before and after, the env's episode cap, and whether the
    model file holds the fit (:func:`keep_fit`)."""

    scores: list[float]
    steps: int
    rig_seconds: float | None
    before: list[float]
    after: list[float]
    cap: int | None
    kept_fit: bool


def keep_fit(before: list[float], after: list[float]) -> bool:
    """Whether to keep a fit whose greedy check episodes scored ``after`` against the fleet policy's
    ``before``: unless it scored less on average."""
    return not before or not after or float(np.mean(after)) >= float(np.mean(before))


def with_own_part(agent: PPOAgent, own_part: str, seed: int) -> PPOAgent:
    """A new agent of ``agent``'s shared weights and settings with the own part ``own_part``, its offsets
    zero."""
    if own_part not in OWN_PART_NAMES or own_part == "none":
        parts = ", ".join(p for p in OWN_PART_NAMES if p != "none")
        raise ValueError(f"--own-part must be one of {parts}, got {own_part!r}")
    config = PPOConfig.from_dict(agent.config.to_dict() | {"own_part": own_part})
    fresh = PPOAgent(agent.obs_dim, agent.action_space, config, seed)
    state = fresh.net.state_dict()
    tensors = {k: v.detach().numpy() for k, v in agent.net.state_dict().items() if not k.startswith("own.")}
    tensors |= {k: torch.zeros_like(v).numpy() for k, v in state.items() if k.startswith("own.")}
    fresh.load_weights(tensors, "the fleet's policy")
    return fresh


def update_own_part(agent: PPOAgent) -> UpdateStats:
    """One round's update with the shared part held: every step's shared gradient is zeros (a fresh Adam
    leaves the shared weights where they are); only the own offsets move."""
    count = agent.begin_update()
    for k in range(count):
        agent.apply_step(np.zeros_like(agent.step_gradients(k)))
    return agent.end_update()


def adapt_model(
    model: Path,
    env: str,
    unit: int,
    *,
    fleet_seed: int = 0,
    fleet_profile: str | None = None,
    episodes: int = 5,
    check: int = 10,
    seed: int = 0,
    own_part: str | None = None,
    out: Path | None = None,
) -> Adapted:
    """Fit the fleet's policy in ``model`` to ``unit`` in ``episodes`` episodes (one update after each) and
    write the unit's model file to ``out``; ``check`` greedy episodes before and after say what it gained
    (:func:`keep_fit`). Raises as :func:`~fleetrl.runs.evaluate.load_policy` does."""
    if episodes < 1 or check < 0:
        raise ValueError(f"need --episodes >= 1 and --check >= 0, got {episodes} and {check}")
    spec, loaded, description = load_policy(model, env)
    last_step = loaded.config.last_step
    part = own_part or (loaded.config.own_part if loaded.config.own_part != "none" else DEFAULT_ADAPT_PART)
    agent = with_own_part(loaded, part, seed)
    gym_env, spec_unit = spec.make(unit, fleet_seed, fleet_profile=fleet_profile, last_step=last_step)
    try:
        before = greedy_scores(gym_env, agent.act_greedy, check, seed=10_000 + seed)
        learner = Learner(gym_env, agent, CompletionCriterion(spec.default_target(spec_unit)), seed=seed)
        scores: list[float] = []
        steps = 0
        while len(scores) < episodes:
            played = learner.begin_round()
            result = learner.end_round(played, update_own_part(agent))
            scores.append(result.score)
            steps += result.steps
        after = greedy_scores(gym_env, agent.act_greedy, check, seed=10_000 + seed)
    finally:
        gym_env.close()
    kept = keep_fit(before, after)
    if out is not None:
        (agent if kept else with_own_part(loaded, part, seed)).save(out)
    period = spec.control_period
    rig = (
        None
        if period is None
        else steps * period + episodes * reset_seconds(env, unit, fleet_seed, fleet_profile)
    )
    return Adapted(scores, steps, rig, before, after, description.episode_cap, kept)
