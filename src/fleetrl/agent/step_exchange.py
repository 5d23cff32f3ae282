"""An update driven one step at a time from outside, as flat vectors (a scheme that combines the fleet's
step gradients): ``PPOAgent.begin_update`` … ``end_update``."""

from __future__ import annotations

from collections.abc import Callable, Generator

import numpy as np

from fleetrl.agent.optimisers import Named, flatten_tensors, split
from fleetrl.agent.update import Gradient, UpdateStats


class StepExchange:
    """The update ``steps`` under way: :meth:`gradient_of` hands out a step's gradient, :meth:`apply` applies
    what the fleet sends back and computes the next.

    :param parts: the parts step k moves, in its gradient's order: each part's shared parameters (what the
        flat vector holds) and how many of the unit's own offsets follow them (their gradient stays here)
    """

    def __init__(
        self,
        steps: Generator[Gradient, Gradient, UpdateStats],
        parts: Callable[[int], list[tuple[Named, int]]],
        count: int,
    ) -> None:
        self._steps, self._parts, self.count = steps, parts, count
        self.step = 0  # the index of the step whose gradient is :attr:`gradient`
        self.taken = False  # the step's gradient was handed out and awaits :meth:`apply`
        self.stats: UpdateStats | None = None
        self.gradient: Gradient | None = None
        self._advance(lambda: next(steps))

    def gradient_of(self, k: int) -> np.ndarray:
        """Step ``k``'s gradient, flat float32; RuntimeError if it is not the step next."""
        if self.taken:
            raise RuntimeError(f"step {self.step}'s gradient is not applied yet: call apply_step()")
        if self.gradient is None or k != self.step:
            raise RuntimeError(f"step {k} requested, but step {self.step} of {self.count} is next")
        self.taken = True
        return flatten_tensors([g for shared, _ in self._pieces(self.gradient) for g in shared])

    def apply(self, flat: np.ndarray) -> None:
        """Apply ``flat`` for the step handed out and compute the next step's gradient (or finish)."""
        if not self.taken:
            raise RuntimeError("no step gradient to apply: call step_gradients(k) first")
        named = [item for shared, _ in self._parts(self.step) for item in shared]
        fleet = iter(split(flat, named, "step gradient"))
        assert self.gradient is not None
        applied = [
            g for shared, own in self._pieces(self.gradient) for g in [next(fleet) for _ in shared] + own
        ]
        self._advance(lambda: self._steps.send(applied))
        self.step += 1

    def finished(self) -> UpdateStats:
        """The update's statistics; RuntimeError if a step was not applied."""
        if self.stats is None:
            raise RuntimeError(f"end_update() after {self.step} of {self.count} steps")
        return self.stats

    def abandon(self) -> None:
        """Stop the update before its last step: the steps applied stay, nothing after them runs."""
        self._steps.close()
        self.gradient, self.taken = None, False

    def _pieces(self, gradient: Gradient) -> list[tuple[Gradient, Gradient]]:
        pieces, at = [], 0
        for shared, own in self._parts(self.step):
            pieces.append(
                (gradient[at : at + len(shared)], gradient[at + len(shared) : at + len(shared) + own])
            )
            at += len(shared) + own
        return pieces

    def _advance(self, resume: Callable[[], Gradient]) -> None:
        self.taken = False
        try:
            self.gradient = resume()
        except StopIteration as done:
            self.gradient, self.stats = None, done.value
