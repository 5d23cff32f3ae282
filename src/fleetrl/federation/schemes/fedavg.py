"""``fedavg``: whole actor-critic models averaged every round (McMahan et al.); a worker whose criterion holds
says so (``parameters``), is averaged like the others and stays. The run ends after the round in which every
member of W has completed at least once. docs/algorithm.md ("Federation schemes").
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from fleetrl.federation.schemes.agent import FederatedAgent
from fleetrl.federation.schemes.base import (
    COMPLETED,
    RoundAnswer,
    RoundContext,
    RoundScheme,
    average_until_all_completed,
)
from fleetrl.federation.wire.messages import Layout, Message


class FedAvgScheme(RoundScheme):
    """Federated averaging of whole models, one average per round."""

    name = "fedavg"
    summary = "average whole actor-critic models every round; mature workers stay until every unit completes"
    round_message = "model"
    stays_after_completion = True

    def layout(self, agent: FederatedAgent) -> Layout:
        """The whole actor-critic's parameters."""
        return agent.model_layout()

    def outgoing(self, agent: FederatedAgent, *, completed: bool) -> tuple[str, np.ndarray]:
        """The model after the round's update; typed :data:`COMPLETED` when the criterion holds."""
        return (COMPLETED if completed else self.round_message), agent.model_parameters()

    def take_parameters(self, agent: FederatedAgent, flat: np.ndarray) -> None:
        """Replace the whole model."""
        agent.set_model_parameters(flat)

    def apply_average(
        self, agent: FederatedAgent, flat: np.ndarray, *, completed: bool, contributed: bool
    ) -> None:
        """Continue from the fleet's average model, whether or not this worker's model is in it."""
        agent.set_model_parameters(flat)

    def combine(self, answers: Mapping[str, Message], context: RoundContext) -> RoundAnswer:
        """The aggregate of the models; every member ``finished`` in the round the last one completes."""
        return average_until_all_completed(answers, context, fleet_model=True)
