"""The run's end: a worker started after it learns from the chief's retained ``ended`` status and gives up
with a clear error instead of waiting for a welcome that never comes (the reply timeout, 600 s by default);
a chief that keeps the fleet's model sends it with ``done``, so every worker ends with it."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pytest
from conftest import StepAgent, worker_of

from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.chief.state import FleetModel
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.schemes.pergrad import PerStepGradientScheme
from fleetrl.federation.wire.messages import Message, decode, encode
from fleetrl.federation.wire.topics import status_topic
from fleetrl.federation.worker.actions import RunEndedError
from fleetrl.transport.local import LocalBus

RUN = "ended-run"


@pytest.mark.timeout(60)
def test_a_worker_started_after_the_run_ended_gives_up_after_the_grace(
    fleet_runner: Any, fake_fleet: Any, fake_learner: Any
) -> None:
    bus = LocalBus()
    result = fleet_runner(bus.client, fake_fleet(), run_id=RUN, max_rounds=5)
    assert result.chief.end_reason == "reached M=5 rounds"
    watcher = bus.client()
    watcher.connect("watcher")
    watcher.subscribe(status_topic(RUN, "chief"))
    retained = watcher.receive(1.0)
    assert retained is not None and retained.retained and retained.payload.startswith(b"ended ")
    late = worker_of(
        fake_learner(14, None),
        bus.client(),
        run_id=RUN,
        worker_id="3",
        max_rounds=5,
        scheme="paper",
        reply_timeout=30.0,
        ended_grace=0.5,
    )
    started = time.monotonic()
    with pytest.raises(RunEndedError, match="had ended before this worker was welcomed"):
        late.run()
    assert 0.5 <= time.monotonic() - started < 10.0


def test_a_chief_that_keeps_the_fleet_model_ends_the_run_with_it_and_one_that_does_not_without() -> None:
    model = FleetModel(PerStepGradientScheme(), StepAgent())  # type: ignore[arg-type]
    keeper = Chief(
        ChiefPlan(
            run_id=RUN,
            workers=("1",),
            layout=[("g", (3,))],
            welcome_layout=model.layout,
            max_rounds=1,
            scheme="pergrad",
            steps_per_round=1,
        ),
        fleet_model=model,
    )
    model.load(np.array([1.0, 2.0, 0.0], np.float32))
    step = keeper.receive(
        Message("step_gradient", RUN, "1", 1, flat=np.array([0.5, 0.5, 9], np.float32)), now=0
    )
    (done,) = [m for m in step.outgoing if m.type == "done"]
    assert done.flat is not None and done.flat.tolist() == [0.5, 1.5, 1.0]  # one fleet step: the final model
    decoded = decode(encode(done, layout=keeper.layout_of("done")), run_id=RUN, known_senders=("chief",),
                     layout=[("g", (3,))], layouts={"done": model.layout})  # fmt: skip
    assert decoded.flat is not None and decoded.flat.tolist() == done.flat.tolist()
    plain = Chief(ChiefPlan(run_id=RUN, workers=("1",), layout=[("g", (3,))], max_rounds=1, scheme="paper"))
    step = plain.receive(Message("gradient", RUN, "1", 1, flat=np.ones(3, np.float32)), now=0)
    assert [m.flat for m in step.outgoing if m.type == "done"] == [None]
