"""A worker process for fault-injection tests: FederatedWorker + the fake learner over MQTT.

``python tests/federation/fake_worker_process.py URL RUN_ID WORKER_ID SEED MAX_ROUNDS PAUSE`` prints one line
``round <n> <event>`` per round (flushed), then ``summary <reason>``.
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from conftest import FakeLearner, worker_of

from fleetrl.federation.worker.runner import FederatedRound
from fleetrl.transport.mqtt import MqttTransport


def main(argv: list[str]) -> int:
    url, run_id, worker_id, seed, max_rounds, pause = argv
    logging.basicConfig(level=logging.INFO, format="%(name)s %(levelname)s %(message)s")

    def show(record: FederatedRound) -> None:
        print(f"round {record.round} {record.event}", flush=True)

    worker = worker_of(
        FakeLearner(int(seed), None, float(pause)),
        MqttTransport(url, reconnect_delay=(1, 2), clean_session=False),
        run_id=run_id,
        worker_id=worker_id,
        max_rounds=int(max_rounds),
        on_record=show,
        reply_timeout=60.0,
        resend_interval=1.0,
        scheme="paper",
    )
    summary = worker.run()
    print(f"summary {summary.reason}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
