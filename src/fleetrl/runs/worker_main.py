"""Entry point of one worker process of ``fleetrl train``: ``python -m fleetrl.runs.worker_main SPEC_JSON``
trains alone; with ``--broker URL --run-id R`` it joins a federated run (with ``--host-units U`` as the unit
host of the spec's unit and the U − 1 after it). One JSON round record per line on stdout; SIGINT stops it
after saving its model."""

import argparse
import logging
import signal
import sys
from dataclasses import replace

from fleetrl.runs.factory import make_learner
from fleetrl.runs.records import MetricsRow
from fleetrl.runs.roles import train_alone, train_federated
from fleetrl.runs.spec import WorkerSpec
from fleetrl.transport.mqtt import MqttTransport


def print_record(record: MetricsRow) -> None:
    """Hand a round to the launcher: one JSON line on stdout."""
    print(record.to_json(), flush=True)


def main(argv: list[str] | None = None) -> int:
    """Run one worker; returns the process exit code."""
    parser = argparse.ArgumentParser(prog="python -m fleetrl.runs.worker_main")
    parser.add_argument("spec", help="the worker's WorkerSpec as JSON")
    parser.add_argument("--broker", default=None, help="federated mode: the broker URL")
    parser.add_argument("--run-id", default=None, help="federated mode: the run id")
    parser.add_argument(
        "--host-units", type=int, default=1, help="federated: host the spec's unit and the next ones"
    )
    args = parser.parse_args(argv)
    if args.host_units < 1:
        parser.error(f"--host-units {args.host_units}: must be at least 1")
    if args.host_units > 1 and args.broker is None:
        parser.error("--host-units: a unit host joins a federated run (--broker)")
    # the launcher stops workers with SIGINT; re-arm it in case this process inherited it ignored
    signal.signal(signal.SIGINT, signal.default_int_handler)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(levelname)s %(message)s")
    spec = WorkerSpec.from_json(args.spec)
    log = logging.getLogger(__name__)
    log.info("worker %d: process up", spec.worker)
    try:
        specs, learner = [spec], None
        if args.host_units > 1:  # the unit host of the spec's unit and the U - 1 after it
            specs = [
                replace(spec, worker=k, unit=k) for k in range(spec.worker, spec.worker + args.host_units)
            ]
        else:
            learner = make_learner(spec)
            log.info("worker %d: learner ready", spec.worker)
        if args.broker is None:
            train_alone(spec, print_record, learner)
        else:
            transport = MqttTransport(args.broker, clean_session=False)
            train_federated(specs, transport, args.run_id, print_record, learner=learner)
    except KeyboardInterrupt:
        log.info("interrupted; the model was saved")
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
