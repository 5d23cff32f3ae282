"""The worker's round events: one enum from the state machine to the metrics files, whose labels stay as they
were (metrics.csv's ``event`` column)."""

from __future__ import annotations

from fleetrl.agent.learner import RoundResult
from fleetrl.federation.events import RoundEvent, Sent, WorkerEvent
from fleetrl.federation.worker.actions import FederatedRound
from fleetrl.runs.roles import metrics_row

RESULT = RoundResult(2, 10.0, 10, 1, 9.0, False, 0.1, 0.2, 1.0, 0.5)
"""the learner's round 2, which the federation played as its round 4 (a resumed worker)"""


def record(event: RoundEvent, peer: str | None = None) -> FederatedRound:
    return FederatedRound("1", 4, RESULT, event, peer)


def test_the_metrics_row_is_the_learner_s_result_with_the_federation_s_round() -> None:
    fed = record(Sent("gradient"))
    row = metrics_row(1, fed.round, fed.result, 0.0, fed.label)
    figures = (row.round, row.score, row.wma, row.steps, row.actor_loss, row.critic_loss, row.entropy)
    assert figures == (4, 10.0, 9.0, 10, 0.1, 0.2, 1.0)
    assert (row.worker, row.event, row.episodes) == (1, "gradient", 1)


def test_metrics_labels_are_those_of_the_metrics_files() -> None:
    labels = {
        Sent("gradient"): "gradient",
        Sent("model"): "model",
        WorkerEvent.COMPLETED: "completed",
        WorkerEvent.LATE: "late",
        WorkerEvent.RUN_ENDED: "run_ended",
        WorkerEvent.TRANSFER_OUT: "completed+transfer_out",
    }
    assert {e: record(e).label for e in labels} == labels
    assert record(WorkerEvent.TRANSFER_IN, "2").label == "transfer_in:2"
    assert record(WorkerEvent.FINISHED, "0").label == "completed+finished:0"


def test_log_lines_name_the_peer_of_a_transfer() -> None:
    assert WorkerEvent.TRANSFER_IN.describe("2") == "transfer_in from 2"
    assert Sent("gradient").describe() == "gradient"
