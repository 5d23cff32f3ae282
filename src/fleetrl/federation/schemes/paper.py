"""``paper``: the paper's scheme (Algorithms 1 and 2). Each worker sends its actor's last gradient of the
round (line 25), the chief averages them (lines 11–13) and every worker applies the average (line 31). The
first worker whose criterion holds sends its θ instead (line 8): the chief forwards it (lines 6–9; the lowest
id if several), that round's gradients are discarded, the senders leave W and the others take θ (line 29).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from fleetrl.federation.schemes.agent import FederatedAgent
from fleetrl.federation.schemes.base import COMPLETED, RoundAnswer, RoundContext, RoundScheme, aggregate
from fleetrl.federation.wire.messages import Layout, Message


class PaperScheme(RoundScheme):
    """Gradient sharing with model transfer (the paper's Algorithms 1 and 2)."""

    name = "paper"
    summary = "average actor gradients every round; transfer θ of the first mature worker, which leaves"
    round_message = "gradient"
    stays_after_completion = False

    def layout(self, agent: FederatedAgent) -> Layout:
        """The actor's parameters (the critic stays with each worker)."""
        return agent.actor_layout()

    def outgoing(self, agent: FederatedAgent, *, completed: bool) -> tuple[str, np.ndarray]:
        """θ once the criterion holds (line 8), else the actor's last gradient of the round (line 25)."""
        if completed:
            return COMPLETED, agent.actor_parameters()
        return self.round_message, agent.actor_gradient()

    def take_parameters(self, agent: FederatedAgent, flat: np.ndarray) -> None:
        """Replace the actor's parameters (line 29)."""
        agent.set_actor_parameters(flat)

    def start_parameters(self, agent: FederatedAgent) -> np.ndarray:
        """The actor's parameters (what a transfer carries)."""
        return agent.actor_parameters()

    def apply_average(
        self, agent: FederatedAgent, flat: np.ndarray, *, completed: bool, contributed: bool
    ) -> None:
        """Apply the averaged gradient through the actor's optimiser (line 31) — unless this worker sent its
        θ: then it keeps its mature policy (and if the chief averaged its θ as a gradient: a protocol bug)."""
        if completed and contributed:
            raise RuntimeError("the chief answered a worker's parameters with an average")
        if not completed:
            agent.apply_actor_gradient(flat)

    def combine(self, answers: Mapping[str, Message], context: RoundContext) -> RoundAnswer:
        """A transfer of the lowest completed worker's θ if any completed, else the gradients' aggregate."""
        completed = tuple(w for w, m in answers.items() if m.type == COMPLETED)
        if completed:
            origin = completed[0]
            flat = answers[origin].flat
            assert flat is not None, "decode guarantees tensors for parameters"
            return RoundAnswer(
                "transfer", flat, origin=origin, finished=completed, leave_w=completed, fleet_model=True
            )
        return RoundAnswer("average", aggregate(answers, context), contributors=tuple(answers))
