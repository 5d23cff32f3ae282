"""The roles of a run spread over several machines: ``fleetrl broker``, ``fleetrl chief``, ``fleetrl worker``.

See docs/deploy.md. Start order does not matter: workers wait for the chief's retained ``online`` status.
"""

import argparse
import json
import logging
import time
from pathlib import Path
from typing import Any

from fleetrl.cli.parsing import parse_overrides

log = logging.getLogger(__name__)


def register(sub: Any) -> None:
    """Add the three role commands to the ``fleetrl`` sub-command parser."""
    broker = sub.add_parser("broker", help="run an embedded MQTT broker on 127.0.0.1 and print its URL")
    broker.add_argument("--prefer", default="auto", help="auto (mosquitto if installed), mosquitto or amqtt")
    broker.add_argument("--port", type=int, default=None, help="port (default: a free one)")
    broker.set_defaults(handler=cmd_broker)

    chief = sub.add_parser("chief", help="serve as the chief of a federated run (Algorithm 1)")
    add_run_arguments(chief)
    chief.add_argument("--workers", type=int, required=True, help="N: the workers are ids 0 … N-1")
    chief.add_argument("--out", type=Path, default=None, help="write chief.json and chief.log here")
    chief.add_argument(
        "--idle-timeout", type=float, default=600.0, help="give up after this many idle seconds"
    )
    chief.set_defaults(handler=cmd_chief)

    worker = sub.add_parser("worker", help="serve as one worker of a federated run (Algorithm 2)")
    add_run_arguments(worker)
    worker.add_argument("--worker-id", type=int, required=True, help="this worker's id (0 … N-1)")
    worker.add_argument("--unit", type=int, default=None, help="device unit to train on (default: worker id)")
    worker.add_argument("--seed", type=int, default=0, help="the run's learning seed")
    worker.add_argument("--fleet-seed", type=int, default=0, help="seed of the fleet's per-unit dynamics")
    worker.add_argument("--out", type=Path, required=True, help="this worker's run directory")
    worker.add_argument("--reply-timeout", type=float, default=600.0, help="seconds to wait for the chief")
    worker.set_defaults(handler=cmd_worker)


def add_run_arguments(p: argparse.ArgumentParser) -> None:
    """Options the chief and every worker must agree on."""
    p.add_argument("--broker", required=True, help="mqtt://[user:pass@]host:port or mqtts://…")
    p.add_argument("--ca-file", default=None, help="CA certificate for mqtts://")
    p.add_argument("--run-id", required=True, help="the run's id (a topic level shared by all roles)")
    p.add_argument("--env", default="qube", help="qube or cartpole")
    p.add_argument("--preset", default="paper", help="PPO preset: paper or standard")
    p.add_argument("--max-rounds", type=int, default=1000, help="the paper's M")
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override one PPO setting (all roles must agree)",
    )


def cmd_broker(args: argparse.Namespace) -> int:
    """Run the embedded broker until Ctrl-C."""
    from fleetrl.transport.broker import EmbeddedBroker

    with EmbeddedBroker(args.prefer, port=args.port) as broker:
        print(f"{broker.kind} broker listening: {broker.url}   (Ctrl-C stops it)", flush=True)
        try:
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            return 0


def _transport(args: argparse.Namespace) -> Any:
    from fleetrl.transport.mqtt import MqttTransport

    return MqttTransport(args.broker, ca_file=args.ca_file)


def cmd_chief(args: argparse.Namespace) -> int:
    """Serve one run as its chief; print how it ended as JSON."""
    from fleetrl.federation.chief import Chief
    from fleetrl.federation.runner import run_chief
    from fleetrl.runs.launch import actor_layout
    from fleetrl.runs.settings import RunSettings

    if args.workers < 1:
        raise ValueError(f"--workers must be at least 1, got {args.workers}")
    settings = RunSettings(
        "federated",
        args.env,
        args.workers,
        args.preset,
        0,
        args.max_rounds,
        Path("."),
        overrides=parse_overrides(args.overrides),
    )
    settings.validate()
    chief = Chief(
        run_id=args.run_id,
        workers=[str(k) for k in range(args.workers)],
        layout=actor_layout(settings),
        max_rounds=args.max_rounds,
    )
    events: list[str] = []
    summary = run_chief(
        chief, _transport(args), on_event=lambda e: events.append(str(e)), idle_timeout=args.idle_timeout
    )
    result = {
        "run_id": args.run_id,
        "rounds": summary.rounds,
        "end_reason": summary.end_reason,
        "transfers": [{"round": r, "from": o, "to": list(t)} for r, o, t in summary.transfers],
        "rejections": {str(k): v for k, v in summary.rejections.items()},
    }
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "chief.json").write_text(json.dumps(result, indent=2) + "\n")
        (args.out / "chief.log").write_text("\n".join(events) + "\n")
    print(json.dumps(result))
    return 0


def cmd_worker(args: argparse.Namespace) -> int:
    """Serve as one worker; its run directory gets the same files as a ``fleetrl train`` run."""
    from fleetrl.runs.roles import train_federated
    from fleetrl.runs.rundir import RunRecorder
    from fleetrl.runs.settings import RunSettings
    from fleetrl.runs.spec import WorkerSpec

    unit = args.worker_id if args.unit is None else args.unit
    settings = RunSettings(
        "federated",
        args.env,
        1,
        args.preset,
        args.seed,
        args.max_rounds,
        args.out,
        fleet_seed=args.fleet_seed,
        broker=args.broker,
        overrides=parse_overrides(args.overrides),
    )
    settings.validate()
    if args.worker_id < 0 or unit < 0:
        raise ValueError("--worker-id and --unit must be non-negative")
    spec = WorkerSpec(
        args.worker_id,
        unit,
        args.env,
        args.preset,
        args.seed,
        args.fleet_seed,
        args.max_rounds,
        str(args.out),
        settings.overrides,
    )
    config = settings.to_config() | {
        "role": "worker",
        "run_id": args.run_id,
        "worker_id": args.worker_id,
        "unit": unit,
    }
    recorder = RunRecorder(args.out, config, [args.worker_id])
    try:
        outcome = train_federated(
            spec, _transport(args), args.run_id, recorder.add, reply_timeout=args.reply_timeout
        )
        recorder.extra["worker"] = {
            "rounds": outcome.rounds,
            "finished": outcome.finished,
            "reason": outcome.reason,
        }
    except KeyboardInterrupt:
        recorder.interrupted = True
    finally:
        summary = recorder.finish()
    print(json.dumps(summary["workers"]))
    return 130 if recorder.interrupted else 0
