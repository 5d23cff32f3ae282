"""The fleet's one policy, kept by the chief of a per-step scheme (a parameter server): its copy of the agent
steps with every answer as each worker's does, so it is, after every exchange, the model (network and
optimiser state) every worker holds; a joining worker's welcome and the chief's checkpoint carry it.
"""

from __future__ import annotations

import numpy as np

from fleetrl.federation.schemes.agent import FederatedAgent
from fleetrl.federation.schemes.base import FleetStart, StepScheme
from fleetrl.federation.wire.messages import Layout, Message
from fleetrl.federation.wire.topics import CHIEF_ID


class FleetModel:
    """The chief's copy of the fleet's model under ``scheme``, starting as ``agent`` is (the fleet's start).

    :param scheme: a per-step scheme whose fleet is one policy.
    :param agent: the chief's agent, built as every worker's is and set to the fleet's start.
    """

    def __init__(self, scheme: StepScheme, agent: FederatedAgent) -> None:
        """Keep ``agent`` as the fleet's model."""
        if not scheme.shared_start:
            raise ValueError(f"scheme {scheme.name!r}'s fleet is not one policy: the chief keeps no model")
        self.scheme = scheme
        self.agent = agent
        self.layout: Layout = list(scheme.welcome_layout(agent))
        """what a ``welcome`` carries"""

    def apply(self, answer: Message) -> None:
        """Apply one of the chief's step answers (every one, in order, as the workers do)."""
        if answer.flat is None:
            raise ValueError(f"a {answer.type} without tensors cannot move the fleet's model")
        self.scheme.catch_up_step(self.agent, answer.step, answer.flat)

    def snapshot(self) -> np.ndarray:
        """The model a joining worker takes: network and optimiser state, flat in :attr:`layout` order."""
        return np.asarray(self.scheme.start_parameters(self.agent), dtype=np.float32)

    def start(self) -> FleetStart:
        """The fleet's start a welcome carries until the fleet's first answer: the model as it is."""
        return FleetStart(self.layout, self.snapshot())

    def welcome(self, run_id: str, rnd: int, step: int) -> Message:
        """The welcome a worker joining at exchange (``rnd``, ``step``) takes: the model as it now is."""
        return Message("welcome", run_id, CHIEF_ID, rnd, step=step, origin=CHIEF_ID, flat=self.snapshot())

    def load(self, flat: np.ndarray) -> None:
        """Make the copy ``flat`` (a checkpoint's :meth:`snapshot`)."""
        self.scheme.take_parameters(self.agent, flat)
