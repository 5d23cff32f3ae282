"""A federation scheme from a user's own code, outside the fleetrl package: named on the command line as
``--scheme my_scheme:SampleWeightedAverage`` (with this directory on the path, or the current one)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from fleetrl.federation.schemes import COMPLETED, RoundAnswer, RoundContext, RoundScheme
from fleetrl.federation.schemes.agent import FederatedAgent
from fleetrl.federation.schemes.base import aggregate
from fleetrl.federation.wire.messages import Layout, Message


class SampleWeightedAverage(RoundScheme):
    """Whole models averaged, each weighted by the transitions its worker played in the round (Flower's
    FedAvg weighting); mature workers stay until the round's end, which comes at M."""

    name = "sample_weighted"
    summary = "whole models averaged, weighted by the transitions each worker played"
    round_message = "weighted_model"
    stays_after_completion = True

    def layout(self, agent: FederatedAgent) -> Layout:
        return agent.model_layout()

    def take_parameters(self, agent: FederatedAgent, flat: np.ndarray) -> None:
        agent.set_model_parameters(flat)

    def outgoing(self, agent: FederatedAgent, *, completed: bool) -> tuple[str, np.ndarray]:
        return (COMPLETED if completed else self.round_message), agent.model_parameters()

    def apply_average(
        self, agent: FederatedAgent, flat: np.ndarray, *, completed: bool, contributed: bool
    ) -> None:
        agent.set_model_parameters(flat)

    def combine(self, answers: Mapping[str, Message], context: RoundContext) -> RoundAnswer:
        flat = aggregate(answers, context, by="samples")
        return RoundAnswer("average", flat, contributors=tuple(answers), fleet_model=True)


class NotAScheme:
    """Anything else a user might name by mistake."""
