"""``pergrad``: the workers' whole actor-critic gradients averaged at every optimisation step (DD-PPO style,
through the chief). The fleet is one policy with one optimiser state, kept by the chief and handed to every
joining worker; a completed worker stays; the run ends in the round every member of W has completed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from fleetrl.federation.schemes.agent import FederatedAgent
from fleetrl.federation.schemes.base import RoundAnswer, RoundContext, StepScheme, average_until_all_completed
from fleetrl.federation.wire.messages import Layout, Message


class PerStepGradientScheme(StepScheme):
    """Synchronous per-step gradient averaging (Wijmans et al.'s DD-PPO, with the chief as the all-reduce)."""

    name = "pergrad"
    summary = "average the workers' minibatch gradients at every optimisation step; mature workers stay"
    round_message = "step_gradient"
    stays_after_completion = True
    shared_start = True
    one_policy_per_step = True

    def layout(self, agent: FederatedAgent) -> Layout:
        """One step's gradient: the whole actor-critic (every step moves the same parameters)."""
        return agent.step_layout(0)

    def welcome_layout(self, agent: FederatedAgent) -> Layout:
        """The fleet's model: the whole actor-critic's parameters, then its optimisers' state."""
        return agent.model_layout() + agent.optimiser_layout()

    def start_parameters(self, agent: FederatedAgent) -> np.ndarray:
        """``agent``'s network and optimisers' state, in :meth:`welcome_layout` order."""
        return np.concatenate([agent.model_parameters(), agent.optimiser_parameters()])

    def take_parameters(self, agent: FederatedAgent, flat: np.ndarray) -> None:
        """Take the fleet's model (the welcome's): its network and its optimisers' state."""
        size = sum(math.prod(shape) for _, shape in agent.model_layout())
        agent.set_model_parameters(flat[:size])
        agent.set_optimiser_parameters(flat[size:])

    def exchanges_per_round(self, agent: FederatedAgent) -> int:
        """The steps of one update; every step must move the same parameters (one layout on the wire)."""
        steps = agent.update_step_count()
        first = agent.step_layout(0)
        if any(agent.step_layout(k) != first for k in range(1, steps)):
            raise ValueError(
                "scheme pergrad averages one whole actor-critic gradient per step: it needs the PPO setting "
                "optimisers = 'per_model' (this preset steps the critic and the actor in turn): choose "
                "another scheme (--scheme fedavg or paper) or --set optimisers=per_model"
            )
        return steps

    def apply_step_answer(self, agent: FederatedAgent, flat: np.ndarray) -> None:
        """Step the optimiser with the fleet's gradient of this step."""
        agent.apply_step(flat)

    def combine(self, answers: Mapping[str, Message], context: RoundContext) -> RoundAnswer:
        """The step's gradients aggregated; at the last step of the round in which the last member of W
        completed, every member is listed in ``finished`` and the run ends."""
        return average_until_all_completed(answers, context, fleet_model=False)
