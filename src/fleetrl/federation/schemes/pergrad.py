"""``pergrad``: the workers' gradients averaged at every optimisation step (DD-PPO style, synchronous, through
the chief).

Every worker starts from the same parameters (drawn from the run's seed) and plays its round. Then, for each
of the round's K optimisation steps, it computes the gradient of its minibatch (the whole actor-critic's loss,
Eqs. 3 and 6, nothing stepped: ``PPOAgent.step_gradients``), sends it keyed (round, step), and applies the
chief's average through its own Adam (``PPOAgent.apply_step``). Every worker applies the same averages to the
same parameters with optimisers in the same state, so the fleet stays one policy, and each step sees the N
workers' minibatches: an N× larger batch per step, with the units' differences in it. A worker whose
criterion holds says so (its step messages are typed ``parameters``) and stays; the run ends after the round
in which every member of W has completed, as with ``fedavg``.

Per step the chief combines with the run's aggregation rule (mean by default; a robust rule also works).
With ``focus`` F > 0 (``--scheme-param focus=0.8``) the mean weighs each unit by its need, 1 − F·p where p
is its progress towards its criterion (WMA / target, clipped to [0, 1]), computed on the worker after the
round's episodes: the units furthest from their criterion steer the step, a unit holding its target counts
1 − F as much as one at zero, and everyone still applies the same step (docs/tuning.md, "The units furthest
from their criterion steer the step"). A unit host weighs each unit's minibatch gradient so inside its one
backward pass and says the sum as its message's ``weight``; an edge aggregator adds the weights up. With
``mature_weight`` ε < 1 (``--scheme-param mature_weight=0.05``) a unit that has completed counts ε as much
as one still learning: in a large fleet whose majority has completed, the last units steer the step. No
straggler stalls the fleet: an exchange closes once a quorum answered and the others' grace ran out; a
straggler applies the answers it missed and contributes to the next round (docs/protocol.md, "Stragglers").
The fleet starts from one network whatever each worker's own seed, and the chief keeps the fleet's model —
the network and the Adam states every worker holds — applying each step's answer as the workers do: its
``welcome`` hands it to every joining worker (at the start, late, or after a restart without its
checkpoint), which then steps on exactly as the fleet does.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from fleetrl.federation.messages import Layout, Message
from fleetrl.federation.schemes.base import (
    FederatedAgent,
    RoundAnswer,
    RoundContext,
    StepScheme,
    average_until_all_completed,
)

WEIGHT_GRID = 2.0**-12
"""a unit's weight by need or maturity is a multiple of this (≥ one step): 12 bits, whose products with a
float32 gradient are exact in float64"""


class PerStepGradientScheme(StepScheme):
    """Synchronous per-step gradient averaging (Wijmans et al.'s DD-PPO, with the chief as the all-reduce).

    :param focus: F in [0, 1): each unit weighs 1 − F·(its progress towards its criterion) in the mean
        (0, the default: every unit the same).
    :param mature_weight: in (0, 1]: what a unit that has completed weighs against one still learning (1,
        the default: the same), times its weight by ``focus``.
    :raises ValueError: a parameter out of range.
    """

    name = "pergrad"
    summary = "average the workers' minibatch gradients at every optimisation step; mature workers stay"
    round_message = "step_gradient"
    stays_after_completion = True
    shared_start = True

    def __init__(self, *, focus: float = 0.0, mature_weight: float = 1.0) -> None:
        if not (math.isfinite(focus) and 0.0 <= focus < 1.0):
            raise ValueError(f"focus = {focus!r}: must be in [0, 1) (a unit at its target must still count)")
        if not (math.isfinite(mature_weight) and 0.0 < mature_weight <= 1.0):
            raise ValueError(
                f"mature_weight = {mature_weight!r}: must be in (0, 1] (a mature unit still counts)"
            )
        self.focus = float(focus)
        self.mature_weight = float(mature_weight)

    def params(self) -> dict[str, Any]:
        """F and the mature units' weight, each only where it is not its default: the plain mean has no
        parameters, so its runs' records, welcomes and checkpoints are those made before either existed."""
        params: dict[str, Any] = {}
        if self.focus != 0.0:
            params["focus"] = self.focus
        if self.mature_weight != 1.0:
            params["mature_weight"] = self.mature_weight
        return params

    def unit_weights(self, progress: Sequence[float], completed: Sequence[bool]) -> list[float] | None:
        """(1 − F·p) per unit, times ``mature_weight`` for a unit that has completed, rounded to a multiple
        of :data:`WEIGHT_GRID` (None with F = 0 and mature units weighing 1: every unit counts once)."""
        if self.focus == 0.0 and self.mature_weight == 1.0:
            return None
        weights = 1.0 - self.focus * np.clip(np.asarray(progress, dtype=np.float64), 0.0, 1.0)
        weights = np.where(np.asarray(completed, dtype=bool), weights * self.mature_weight, weights)
        # On a grid of WEIGHT_GRID (at least one step): w·g is then exact in float64 for a float32 g, so an
        # edge aggregator's partial sums add up to the flat fleet's sum, as integer weights do
        # (fleetrl.federation.aggregation, "decomposes").
        steps = np.maximum(np.round(weights / WEIGHT_GRID), 1.0)
        return [float(w) for w in steps * WEIGHT_GRID]

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
        """Take the fleet's model (the welcome's; no transfer happens in this scheme): its network and its
        optimisers' state."""
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
