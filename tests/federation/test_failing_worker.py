"""A worker that dies of an error (not a kill: its connection closes cleanly, so no last will fires) says it
went offline, so a fleet that waits for every worker is not stalled by it: the chief drops it after its grace
and the others play on to M."""

from __future__ import annotations

import threading

from conftest import FakeLearner, FakeResult, worker_of

from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.runner import ChiefSummary, run_chief
from fleetrl.federation.schemes import resolve_scheme
from fleetrl.transport.local import LocalBus

ROUNDS = 5


class BrokenLearner(FakeLearner):
    """Plays two rounds, then its third raises (a bug, a full disk, a device gone)."""

    def play_round(self) -> FakeResult:
        if self.rounds == 2:
            raise RuntimeError("the unit's driver went away")
        return super().play_round()


def test_a_worker_that_fails_leaves_the_fleet_instead_of_stalling_it() -> None:
    learners = {"1": FakeLearner(11), "2": FakeLearner(12), "3": BrokenLearner(13)}
    bus = LocalBus()
    layout = resolve_scheme("paper").layout(learners["1"].agent)
    chief = Chief(
        ChiefPlan(
            run_id="r",
            workers=list(learners),
            layout=layout,
            max_rounds=ROUNDS,
            scheme="paper",
            dropout_grace=0.2,
        )
    )  # quorum 1 and no round deadline: every worker is waited for
    outcome: dict[str, ChiefSummary] = {}
    errors: dict[str, BaseException] = {}
    rounds: dict[str, int] = {}

    def chief_main() -> None:
        outcome["chief"] = run_chief(chief, bus.client(), idle_timeout=60.0)

    def worker_main(worker: str) -> None:
        try:
            summary = worker_of(
                learners[worker], bus.client(), run_id="r", worker_id=worker, max_rounds=ROUNDS,
                reply_timeout=60.0, scheme="paper",
            ).run()  # fmt: skip
            rounds[worker] = summary.rounds
        except RuntimeError as exc:
            errors[worker] = exc

    threads = [threading.Thread(target=chief_main)]
    threads += [threading.Thread(target=worker_main, args=(w,)) for w in learners]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(30.0)
    assert not any(t.is_alive() for t in threads), "the fleet stalled on the failed worker"
    assert list(errors) == ["3"] and "driver went away" in str(errors["3"])  # the error is not swallowed
    assert rounds == {"1": ROUNDS, "2": ROUNDS}
    assert chief.dropouts == [(3, "3", "went offline")]
    assert outcome["chief"].rounds == ROUNDS
