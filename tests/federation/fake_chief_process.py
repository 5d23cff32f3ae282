"""A chief process for fault-injection tests: the fake learner's layout, checkpoints, optional resume.

``python tests/federation/fake_chief_process.py URL RUN_ID WORKERS MAX_ROUNDS CHECKPOINT_DIR [--resume]``
(WORKERS comma-separated) prints ``closed <round>`` per closed round (flushed) and ``summary <json>``.
"""

from __future__ import annotations

import json
import logging
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from conftest import FAKE_LAYOUT

from fleetrl.federation.chief.checkpoint import replay_last_answer
from fleetrl.federation.chief.machine import Chief, ChiefEvent
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.runner import run_chief
from fleetrl.runs.checkpoints import ChiefCheckpoint
from fleetrl.transport.mqtt import MqttTransport


def main(argv: list[str]) -> int:
    url, run_id, workers, max_rounds, directory = argv[:5]
    logging.basicConfig(level=logging.INFO, format="%(name)s %(levelname)s %(message)s")
    store = ChiefCheckpoint(Path(directory))
    chief = Chief(
        ChiefPlan(
            run_id=run_id,
            workers=workers.split(","),
            layout=FAKE_LAYOUT,
            max_rounds=int(max_rounds),
            scheme="paper",
        )
    )
    first = None
    if "--resume" in argv:
        chief = store.load(now=time.monotonic(), expect=chief)
        first = replay_last_answer(chief)

    def show(event: ChiefEvent) -> None:
        if event.kind in ("averaged", "transfer"):
            print(f"closed {event.round}", flush=True)

    transport = MqttTransport(url, reconnect_delay=(1, 2), clean_session=False)
    summary = run_chief(
        chief, transport, on_event=show, idle_timeout=60, checkpoint=store.save, first_step=first
    )
    print(f"summary {json.dumps(summary.to_dict())}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
