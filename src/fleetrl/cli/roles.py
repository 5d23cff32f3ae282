"""The roles of a run spread over several machines: ``fleetrl broker``, ``fleetrl chief``, ``fleetrl worker``,
and ``fleetrl secure-config`` (a mosquitto config with logins, per-role ACLs, TLS and a fleet key).

See docs/deploy.md and docs/security.md. Start order does not matter: workers wait for the chief's welcome.
"""

import argparse
import json
import logging
import time
from pathlib import Path
from typing import Any

from fleetrl.cli.parsing import parse_overrides

log = logging.getLogger(__name__)

CONNECT_TIMEOUT = 60.0
"""default seconds a standalone role retries the broker before it gives up"""


def register(sub: Any) -> None:
    """Add the three role commands to the ``fleetrl`` sub-command parser."""
    broker = sub.add_parser("broker", help="run an embedded MQTT broker on 127.0.0.1 and print its URL")
    broker.add_argument("--prefer", default="auto", help="auto (mosquitto if installed), mosquitto or amqtt")
    broker.add_argument("--port", type=int, default=None, help="port (default: a free one)")
    broker.add_argument(
        "--secure",
        type=Path,
        default=None,
        metavar="DIR",
        help="run mosquitto with DIR/mosquitto.conf written by `fleetrl secure-config` (login, ACLs, TLS)",
    )
    broker.set_defaults(handler=cmd_broker)

    secure = sub.add_parser(
        "secure-config", help="write a secure mosquitto config (passwords, per-role ACLs, TLS, fleet key)"
    )
    secure.add_argument(
        "dir", type=Path, help="directory to write mosquitto.conf, passwd, acl, fleet.key into"
    )
    secure.add_argument("--workers", type=int, required=True, help="N: MQTT users for worker ids 0 … N-1")
    secure.add_argument("--port", type=int, default=8883, help="listener port (default 8883)")
    secure.add_argument("--host", default="127.0.0.1", help="the broker's address as clients use it")
    secure.add_argument("--bind", default=None, help="address to listen on (default: --host)")
    secure.add_argument("--no-tls", action="store_true", help="plain MQTT (logins travel in clear text)")
    secure.set_defaults(handler=cmd_secure_config)

    chief = sub.add_parser("chief", help="serve as the chief of a federated run (Algorithm 1)")
    add_run_arguments(chief)
    chief.add_argument("--workers", type=int, required=True, help="N: the workers are ids 0 … N-1")
    chief.add_argument(
        "--out",
        type=Path,
        default=None,
        help="write chief.json, chief.log and a checkpoint every round (checkpoints/chief/) here",
    )
    chief.add_argument(
        "--resume",
        action="store_true",
        help="continue the run from the checkpoint in --out (after a crash; same settings)",
    )
    chief.add_argument(
        "--idle-timeout", type=float, default=600.0, help="give up after this many idle seconds"
    )
    chief.add_argument(
        "--quorum",
        type=float,
        default=1.0,
        help="at the round deadline, close the round if this fraction of W answered (needs --round-timeout)",
    )
    chief.add_argument(
        "--round-timeout",
        type=float,
        default=None,
        help="round deadline in seconds (default: none, the paper's fully synchronous rule)",
    )
    chief.add_argument(
        "--aggregation",
        default="mean",
        help="mean (the paper's), median, trimmed_mean[:β], clipped_mean[:C]",
    )
    chief.add_argument(
        "--dropout-grace",
        type=float,
        default=3.0,
        help="seconds a worker that went offline has to come back before it leaves W",
    )
    chief.set_defaults(handler=cmd_chief)

    worker = sub.add_parser("worker", help="serve as one worker of a federated run (Algorithm 2)")
    add_run_arguments(worker)
    worker.add_argument("--worker-id", type=int, required=True, help="this worker's id (0 … N-1)")
    worker.add_argument("--unit", type=int, default=None, help="device unit to train on (default: worker id)")
    worker.add_argument("--seed", type=int, default=0, help="the run's learning seed")
    worker.add_argument("--fleet-seed", type=int, default=0, help="seed of the fleet's per-unit dynamics")
    worker.add_argument(
        "--out",
        type=Path,
        required=True,
        help="this worker's run directory (metrics, model, a checkpoint every round in checkpoints/)",
    )
    worker.add_argument(
        "--resume",
        action="store_true",
        help="continue from the checkpoint in --out at its round (after a crash; same settings)",
    )
    worker.add_argument("--reply-timeout", type=float, default=600.0, help="seconds to wait for the chief")
    worker.add_argument(
        "--resend-interval",
        type=float,
        default=5.0,
        help="re-send the round's message after this many seconds without an answer",
    )
    worker.set_defaults(handler=cmd_worker)


def add_run_arguments(p: argparse.ArgumentParser) -> None:
    """Options the chief and every worker must agree on."""
    p.add_argument("--broker", required=True, help="mqtt://[user:pass@]host:port or mqtts://…")
    p.add_argument("--scheme", default="paper", help="federation scheme: paper (default) or fedavg")
    p.add_argument("--ca-file", default=None, help="CA certificate for mqtts://")
    p.add_argument("--client-cert", default=None, help="client certificate for mqtts:// (optional)")
    p.add_argument("--client-key", default=None, help="the client certificate's private key")
    p.add_argument(
        "--fleet-key-file",
        type=Path,
        default=None,
        help="sign and verify every federation message with this key (HMAC-SHA256; all roles share it)",
    )
    p.add_argument("--run-id", required=True, help="the run's id (a topic level shared by all roles)")
    add_connect_timeout(p)
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


def add_connect_timeout(p: argparse.ArgumentParser) -> None:
    """``--connect-timeout``: how long a standalone role retries an unreachable broker (start order does not
    matter) before it exits 1."""
    p.add_argument(
        "--connect-timeout",
        type=float,
        default=CONNECT_TIMEOUT,
        help=f"seconds to keep retrying an unreachable broker, with backoff (default {CONNECT_TIMEOUT:g})",
    )


def cmd_broker(args: argparse.Namespace) -> int:
    """Run the embedded broker (or mosquitto with a secure config) until Ctrl-C."""
    from fleetrl.transport.broker import EmbeddedBroker

    config = None
    if args.secure is not None:
        config = (args.secure / "mosquitto.conf").resolve()
        if not config.is_file():
            raise FileNotFoundError(f"{config} not found: run `fleetrl secure-config {args.secure}` first")
        args.port = _listener_port(config)
    with EmbeddedBroker("mosquitto" if config else args.prefer, port=args.port, config=config) as broker:
        where = f"{config} on port {broker.port}" if config else broker.url
        print(f"{broker.kind} broker listening: {where}   (Ctrl-C stops it)", flush=True)
        try:
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            return 0


def _listener_port(config: Path) -> int:
    for line in config.read_text().splitlines():
        if line.startswith("listener "):
            return int(line.split()[1])
    raise ValueError(f"{config} has no listener line")


def cmd_secure_config(args: argparse.Namespace) -> int:
    """Write the secure config and print each role's broker URL (with its password) once."""
    from fleetrl.transport.secure import write_secure_config

    if args.workers < 1:
        raise ValueError(f"--workers must be at least 1, got {args.workers}")
    fleet = write_secure_config(
        args.dir,
        workers=[str(k) for k in range(args.workers)],
        port=args.port,
        host=args.host,
        bind=args.bind,
        self_signed_tls=not args.no_tls,
    )
    print(f"wrote {fleet.config}, passwd, acl, fleet.key, credentials.json in {fleet.directory}")
    print(f"start the broker:  fleetrl broker --secure {fleet.directory}")
    extra = f" --ca-file {fleet.ca_file}" if fleet.ca_file else ""
    for user in fleet.passwords:
        role = "chief" if user == "chief" else f"worker --worker-id {user}"
        print(f"  {role}: --broker '{fleet.url(user)}'{extra} --fleet-key-file {fleet.key_file}")
    return 0


def _transport(args: argparse.Namespace) -> Any:
    from fleetrl.transport.mqtt import MqttTransport

    return MqttTransport(
        args.broker,
        ca_file=args.ca_file,
        cert_file=args.client_cert,
        key_file=args.client_key,
        clean_session=False,  # persistent session under the role's fixed client id
        connect_timeout=args.connect_timeout,
    )


def _key(args: argparse.Namespace) -> Any:
    from fleetrl.federation.signing import FleetKey

    return None if args.fleet_key_file is None else FleetKey.from_file(args.fleet_key_file)


def cmd_chief(args: argparse.Namespace) -> int:
    """Serve one run as its chief; print how it ended as JSON."""
    from fleetrl.federation.chief import Chief
    from fleetrl.federation.runner import run_chief
    from fleetrl.runs.launch import shared_layout
    from fleetrl.runs.rundir import write_json_atomic
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
        scheme=args.scheme,
        overrides=parse_overrides(args.overrides),
    )
    settings.validate()
    chief = Chief(
        run_id=args.run_id,
        workers=[str(k) for k in range(args.workers)],
        layout=shared_layout(settings),
        scheme=args.scheme,
        max_rounds=args.max_rounds,
        aggregator=args.aggregation,
        quorum=args.quorum,
        round_timeout=args.round_timeout,
        dropout_grace=args.dropout_grace,
        key=_key(args),
    )
    if args.out is None:
        if args.resume:
            raise ValueError("--resume needs --out: the run directory holding the chief's checkpoint")
        summary = run_chief(chief, _transport(args), idle_timeout=args.idle_timeout)
    else:
        summary = _serve_with_checkpoints(chief, args)
    result = {"run_id": args.run_id, **summary.to_dict()}
    if args.out is not None:
        write_json_atomic(args.out / "chief.json", result)
    print(json.dumps(result))
    return 0


def _serve_with_checkpoints(chief: Any, args: argparse.Namespace) -> Any:
    """Run the chief with a checkpoint every round in ``args.out`` (resuming from it with ``--resume``)
    and its events appended to chief.log as they happen."""
    from fleetrl.federation.chief_state import replay_last_answer
    from fleetrl.federation.runner import run_chief
    from fleetrl.runs.checkpoints import ChiefCheckpoint, chief_checkpoint_dir

    args.out.mkdir(parents=True, exist_ok=True)
    store = ChiefCheckpoint(chief_checkpoint_dir(args.out))
    first = None
    if args.resume:
        chief = store.load(key=chief.key, now=time.monotonic(), expect=chief)
        first = replay_last_answer(chief)
    elif store.exists():
        raise FileExistsError(f"{args.out} holds a chief checkpoint: add --resume, or choose another --out")
    with open(args.out / "chief.log", "a") as log_file:
        return run_chief(
            chief,
            _transport(args),
            on_event=lambda e: print(e, file=log_file, flush=True),
            idle_timeout=args.idle_timeout,
            checkpoint=store.save,
            first_step=first,
        )


def cmd_worker(args: argparse.Namespace) -> int:
    """Serve as one worker; its run directory gets the same files as a ``fleetrl train`` run."""
    from fleetrl.runs.checkpoints import WorkerCheckpoint, worker_checkpoint_dir
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
        scheme=args.scheme,
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
        scheme=args.scheme,
    )
    config = settings.to_config() | {
        "role": "worker",
        "run_id": args.run_id,
        "worker_id": args.worker_id,
        "unit": unit,
    }
    checkpoints = worker_checkpoint_dir(args.out, args.worker_id)
    where = WorkerCheckpoint(checkpoints, spec, args.run_id).where() if args.resume else None
    resume_from = {args.worker_id: 1 if where is None else where.next_round} if args.resume else None
    recorder = RunRecorder(args.out, config, [args.worker_id], resume_from=resume_from)
    try:
        outcome = train_federated(
            spec,
            _transport(args),
            args.run_id,
            recorder.add,
            reply_timeout=args.reply_timeout,
            resend_interval=args.resend_interval,
            key=_key(args),
            checkpoint_dir=checkpoints,
            resume=args.resume,
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
