"""``pergrad`` with a straggler (docs/protocol.md, "Stragglers"): three real CartPole learners over the
in-process bus, one of them much slower to play its rounds. Under the default quorum the fleet does not wait
for it round after round; it applies every answer it missed and contributes what it played, stale; and the
fleet stays one policy."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from fleetrl.agent.learner import Learner
from fleetrl.federation.chief import Chief
from fleetrl.runs.factory import make_learner
from fleetrl.runs.launch import fleet_start
from fleetrl.runs.settings import LearningSettings, fleet_shape, resolve_learning
from fleetrl.runs.spec import WorkerSpec
from fleetrl.transport.local import LocalBus

ROUNDS = 6


class SlowLearner:
    """A learner whose rounds take ``pause`` seconds more to play (a slow unit)."""

    def __init__(self, learner: Learner, pause: float) -> None:
        self.inner, self.pause = learner, pause

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    def begin_round(self) -> Any:
        time.sleep(self.pause)
        return self.inner.begin_round()


@pytest.mark.slow  # a 3-worker CartPole run with a slow unit
def test_a_slow_unit_does_not_hold_the_fleet_back_and_the_fleet_stays_one_policy(
    fleet_runner: Callable[..., Any],
) -> None:
    learning = resolve_learning(
        LearningSettings(env="cartpole", preset="standard", scheme="pergrad", max_rounds=ROUNDS)
    )
    learners: dict[str, Any] = {
        w: make_learner(WorkerSpec(worker=int(w), unit=int(w), learning=learning, out="/nonexistent"))
        for w in ("0", "1", "2")
    }
    plain = {w: learner for w, learner in learners.items()}
    learners["2"] = SlowLearner(learners["2"], pause=1.0)
    chief_kwargs = {
        "scheme": "pergrad", "steps_per_round": fleet_shape(learning).exchanges_per_round,
        "start": fleet_start(learning), "quorum": 0.6,
    }  # fmt: skip
    chiefs: list[Chief] = []
    result = fleet_runner(
        LocalBus().client, learners, max_rounds=ROUNDS, chief_kwargs=chief_kwargs,
        worker_kwargs={"scheme": "pergrad"}, timeout=120, on_chief=chiefs.append,
    )  # fmt: skip
    (chief,) = chiefs
    assert chief.end_reason == f"reached M={ROUNDS} rounds" and not chief.dropouts
    assert len(result.records["0"]) == len(result.records["1"]) == ROUNDS
    slow_rounds = [r.round for r in result.records["2"]]
    assert 1 <= len(slow_rounds) < ROUNDS, slow_rounds  # it took part in some rounds, stale, not in all
    assert chief.state.pace.late["2"] >= ROUNDS - len(slow_rounds) and not chief.state.pace.late["0"]
    models = {w: learner.agent.model_parameters() for w, learner in plain.items()}
    assert all(np.array_equal(models["0"], m) for m in models.values())  # every answer applied, in order


@pytest.fixture(autouse=True)
def _one_thread() -> None:
    import torch

    torch.set_num_threads(1)
