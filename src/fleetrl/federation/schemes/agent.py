"""What a scheme needs of the agent (:class:`FederatedAgent`, and :class:`LocalTraining` for a scheme that
adds to its loss): flat float32 vectors in named layouts, so federation never imports torch."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol, TypeAlias, runtime_checkable

import numpy as np

if TYPE_CHECKING:  # torch is the agent's: not imported to read a scheme
    import torch


class FederatedAgent(Protocol):
    """What schemes need from the agent (``fleetrl.agent.ppo.PPOAgent`` provides it)."""

    def actor_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        """Names and shapes of the actor's parameters, in flat order."""

    def actor_gradient(self) -> np.ndarray:
        """The actor's last gradient of the round, flat float32."""

    def apply_actor_gradient(self, flat: np.ndarray) -> None:
        """Update the actor with ``flat`` through its optimiser."""

    def actor_parameters(self) -> np.ndarray:
        """The actor's parameters, flat float32."""

    def set_actor_parameters(self, flat: np.ndarray) -> None:
        """Replace the actor's parameters."""

    def model_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        """Names and shapes of the whole actor-critic's parameters, in flat order."""

    def model_parameters(self) -> np.ndarray:
        """The whole actor-critic's parameters, flat float32."""

    def set_model_parameters(self, flat: np.ndarray) -> None:
        """Replace the whole actor-critic's parameters."""

    def optimiser_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        """Names and shapes of the optimisers' state as one flat vector."""

    def optimiser_parameters(self) -> np.ndarray:
        """The optimisers' state, flat float32."""

    def set_optimiser_parameters(self, flat: np.ndarray) -> None:
        """Replace the optimisers' state."""

    def step_layout(self, k: int) -> list[tuple[str, tuple[int, ...]]]:
        """Names and shapes of optimisation step ``k``'s flat gradient."""

    def update_step_count(self) -> int:
        """How many optimisation steps each update takes."""

    def begin_update(self) -> int:
        """Start the round's update; the number of optimisation steps it takes."""

    def step_gradients(self, k: int) -> np.ndarray:
        """Step ``k``'s gradient, flat float32 in :meth:`step_layout` order, nothing stepped."""

    def apply_step(self, flat_grad: np.ndarray) -> None:
        """Step the optimiser(s) with a gradient for the step last computed."""

    def apply_fleet_step(self, k: int, flat_grad: np.ndarray) -> None:
        """Step the optimiser(s) with the fleet's gradient of step ``k``, no update under way."""

    def end_update(self) -> Any:
        """Finish the update (every step applied); its statistics."""

    def abandon_update(self) -> None:
        """Drop the round's update, under way or not begun (the fleet went on past it)."""


ExtraLoss: TypeAlias = "Callable[[torch.nn.Module], torch.Tensor]"
"""A term added to the loss of every optimisation step of local training (FedProx's μ/2‖θ − θ_global‖²)."""


@runtime_checkable
class LocalTraining(Protocol):
    """The worker-side hook into the agent's local training (``fleetrl.agent.ppo.PPOAgent`` provides it)."""

    def set_extra_loss(self, fn: ExtraLoss | None) -> None:
        """Add ``fn(model)`` to the loss of every optimisation step from now on (None: nothing added)."""
