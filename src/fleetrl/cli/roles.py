"""The roles of a run spread over several machines (docs/deploy.md, docs/security.md): ``fleetrl broker``,
``chief``, ``worker``, ``aggregator`` (a site's edge aggregator) and ``secure-config`` (a mosquitto config
with logins, per-role ACLs, TLS and a fleet key)."""

import argparse
import json
import logging
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

from fleetrl.cli.settings_args import add_settings_arguments, settings_from_args
from fleetrl.cli.startup import collector_paused
from fleetrl.federation.chief.lease import chief_epoch, holder_fields, place_refusal
from fleetrl.federation.wire.topics import CHIEF_ID, status_topic
from fleetrl.runs.role_settings import ChiefSettings, WorkerSettings
from fleetrl.runs.setting_values import flat_values

log = logging.getLogger(__name__)


def register(sub: Any) -> None:
    """Add the role commands to the ``fleetrl`` sub-command parser."""
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

    from fleetrl.runs.aggregator_settings import AggregatorSettings

    for name, settings, handler, text in (
        ("chief", ChiefSettings, cmd_chief, "serve as the chief of a federated run (Algorithm 1)"),
        ("worker", WorkerSettings, cmd_worker, "serve as one worker of a federated run (Algorithm 2)"),
        (
            "aggregator",
            AggregatorSettings,
            cmd_aggregator,
            "serve a site's workers as one member of the root chief (an edge aggregator)",
        ),
    ):
        role = sub.add_parser(name, help=text)
        add_settings_arguments(role, settings, notes={"broker": "required"})
        role.set_defaults(handler=handler)


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
    from fleetrl.runs.secure import write_secure_config

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
    print(f"wrote {fleet.config}, passwd, acl, fleet.key, passwords/, credentials.json in {fleet.directory}")
    print(f"start the broker:  fleetrl broker --secure {fleet.directory}")
    extra = f" --ca-file {fleet.ca_file}" if fleet.ca_file else ""
    for user in fleet.passwords:  # no password on any command line: each role reads its own file
        role = "chief" if user == "chief" else f"worker --worker-id {user}"
        print(
            f"  {role}: --broker '{fleet.login_url(user)}' --broker-password-file {fleet.password_file(user)}"
            f"{extra} --fleet-key-file {fleet.key_file}"
        )
    return 0


def cmd_chief(args: argparse.Namespace) -> int:
    """Serve one run as its chief; print how it ended as JSON."""
    with collector_paused():
        from fleetrl.federation.chief.machine import EVERY_WORKER_DROPPED
        from fleetrl.federation.kinds import new_chief
        from fleetrl.runs.dirlock import DirectoryLock
        from fleetrl.runs.launch import chief_plan
        from fleetrl.runs.rundir import write_json_atomic

        settings = settings_from_args(ChiefSettings, args)
    plan, fleet = chief_plan(
        settings.learning, settings, run_id=settings.run_id, workers=settings.member_ids(),
        dropout_grace=settings.dropout_grace, open_fleet=not settings.closed_fleet,
    )  # fmt: skip
    chief = new_chief(plan, key=settings.fleet_key(), **fleet)
    # one chief per run directory, for its life, and one per run on the broker
    lock = None if settings.out is None else DirectoryLock(settings.out, "chief").acquire()
    try:
        retained = claim_place(settings, CHIEF_ID, lock)
        summary = _serve_chief(chief, settings, retained)
        result = {"run_id": settings.run_id, **summary.to_dict()}
        if settings.out is not None:
            write_json_atomic(settings.out / "chief.json", result)
    finally:
        if lock is not None:
            lock.release()
    print(json.dumps(result))
    if summary.end_reason == EVERY_WORKER_DROPPED:  # no fleet left to train: the run did not do its job
        print(f"fleetrl chief: error: run {settings.run_id!r}: {EVERY_WORKER_DROPPED}", file=sys.stderr)
        return 1
    return 0


def claim_place(settings: Any, node: str, lock: Any = None) -> Any:
    """The retained status of ``node``'s place in the run (``chief``, a worker's or a host's id), read
    before this process connects; RoleConflict (exit 1) if a live process holds it, ``lock`` abandoned."""
    from fleetrl.runs.dirlock import RoleConflict

    try:
        retained = settings.read_status(node)
        refusal = place_refusal(settings.run_id, node, retained, status_topic(settings.run_id, node))
        if refusal is not None:
            raise RoleConflict(refusal)
    except BaseException:
        if lock is not None:
            lock.abandon()
        raise
    return retained


def _forget_previous_session(settings: Any, retained: Any) -> None:
    """Remove the broker session of the chief this one replaces (nobody would read what is queued there)."""
    from fleetrl.federation.runner import chief_client_id

    if retained is None:
        return
    transport = settings.transport(clean_session=True)
    try:  # a clean-session connection under that id discards the stored session
        transport.connect(chief_client_id(settings.run_id, retained.number("epoch") or 0))
        transport.close()
    except ConnectionError as exc:
        log.info("could not remove the previous chief's broker session: %s", exc)


def _serve_chief(chief: Any, settings: Any, retained: Any) -> Any:
    """Run the chief; with ``settings.out``, with a checkpoint every round there (resumed with ``--resume``)
    and its events appended to chief.log. Its epoch follows the newest of ``retained``'s and the
    checkpoint's."""
    from fleetrl.federation.chief.checkpoint import replay_last_answer
    from fleetrl.federation.runner import run_chief
    from fleetrl.runs.checkpoints import ChiefCheckpoint, chief_checkpoint_dir

    lease: dict[str, Any] = {
        "read_lease": lambda: settings.read_status(CHIEF_ID),
        "status_fields": holder_fields(settings.keepalive),
    }
    out: Path | None = settings.out
    if out is None:
        chief.take_epoch(chief_epoch(checkpoint=None, retained=retained))
        _forget_previous_session(settings, retained)
        return run_chief(chief, settings.transport(), idle_timeout=settings.idle_timeout, **lease)
    store = ChiefCheckpoint(chief_checkpoint_dir(out))
    first = None
    saved = None
    if settings.resume:
        chief = store.load(key=chief.key, now=time.monotonic(), expect=chief)
        saved = chief.epoch
        first = replay_last_answer(chief)
    elif store.exists():
        raise FileExistsError(f"{out} holds a chief checkpoint: add --resume, or choose another --out")
    chief.take_epoch(chief_epoch(checkpoint=saved, retained=retained))  # checkpointed at the start
    _forget_previous_session(settings, retained)
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "chief.log", "a") as log_file:
        return run_chief(
            chief,
            settings.transport(),
            on_event=lambda e: print(e, file=log_file, flush=True),
            idle_timeout=settings.idle_timeout,
            checkpoint=store.save,
            first_step=first,
            **lease,
        )


def cmd_worker(args: argparse.Namespace) -> int:
    """Serve as one worker or unit host; its run directory gets the same files as a ``fleetrl train`` run."""
    with collector_paused():
        from fleetrl.runs.dirlock import DirectoryLock
        from fleetrl.runs.factory import make_learner
        from fleetrl.runs.host_settings import host_id

        settings = settings_from_args(WorkerSettings, args)
    config = worker_config(settings)
    ids = settings.unit_ids()
    if settings.units > 1:
        with DirectoryLock(settings.out, f"unit host {settings.worker_id}").acquire() as lock:
            claim_place(settings, host_id(ids), lock)
            first = settings.worker_spec()
            return _serve(settings, [replace(first, worker=k, unit=k) for k in ids], config)
    spec = settings.worker_spec()
    learner = make_learner(spec, settings.device_transport())  # a device bridge is reached before any file
    with DirectoryLock(settings.out, f"worker {settings.worker_id}").acquire() as lock:  # one per directory
        claim_place(settings, str(settings.worker_id), lock)  # one process per worker id on the broker
        return _serve(settings, [spec], config, learner)


def _serve(settings: Any, specs: list[Any], config: dict[str, Any], learner: Any = None) -> int:
    """Serve as the worker (one spec, its ``learner``) or unit host (several) of ``specs`` in the run
    directory this process has locked; a worker checkpoints every round."""
    from fleetrl.runs.checkpoints import WorkerCheckpoint, worker_checkpoint_dir
    from fleetrl.runs.fleet_summary import summarised
    from fleetrl.runs.roles import train_federated
    from fleetrl.runs.rundir import RunRecorder

    ids = settings.unit_ids()
    checkpoints, resume, resume_from = None, False, None
    if len(specs) == 1:
        checkpoints = worker_checkpoint_dir(settings.out, settings.worker_id)
        resume = settings.resume
        where = WorkerCheckpoint(checkpoints, specs[0], settings.run_id).where() if resume else None
        resume_from = {settings.worker_id: 1 if where is None else where.next_round} if resume else None
    summarise = summarised(len(ids), False)
    recorder = RunRecorder(settings.out, config, ids, resume_from=resume_from, summarise=summarise)
    return _recorded(
        recorder,
        lambda: train_federated(
            specs,
            settings.transport(),
            settings.run_id,
            recorder.add,
            learner=learner,
            reply_timeout=settings.reply_timeout,
            resend_interval=settings.resend_interval,
            key=settings.fleet_key(),
            checkpoint_dir=checkpoints,
            resume=resume,
            status_fields=holder_fields(settings.keepalive),
        ),
    )


def _recorded(recorder: Any, train: Callable[[], Any]) -> int:
    """Run a standalone worker's ``train`` into ``recorder`` (how it ended in summary.json, printed as JSON);
    the exit code."""
    try:
        outcome = train()
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


def cmd_aggregator(args: argparse.Namespace) -> int:
    """Serve a site as its edge aggregator until the root ends the run; print how it ended as JSON."""
    with collector_paused():
        from fleetrl.federation.edge.aggregator import EdgeAggregator
        from fleetrl.federation.edge.runner import run_edge
        from fleetrl.runs.aggregator_settings import AggregatorSettings
        from fleetrl.runs.launch import chief_plan

        settings = settings_from_args(AggregatorSettings, args)
    plan, fleet = chief_plan(
        settings.learning, settings, run_id=settings.site_run, workers=settings.member_ids,
        dropout_grace=settings.dropout_grace, open_fleet=not settings.closed_fleet,
    )  # fmt: skip
    edge = EdgeAggregator(
        plan, site_id=settings.site_id, root_run=settings.run_id, resend_interval=settings.resend_interval,
        key=settings.fleet_key(), **fleet,
    )  # fmt: skip
    summary = run_edge(
        edge, upstream=settings.transport(), downstream=settings.site_transport(),
        idle_timeout=settings.idle_timeout,
    )  # fmt: skip
    print(json.dumps({"run_id": settings.run_id, "site_run": settings.site_run, **asdict(summary)}))
    return 0


def worker_config(settings: Any) -> dict[str, Any]:
    """A standalone worker's config.json: its settings (no password) and the resolved PPO config."""
    config = {k: str(v) if isinstance(v, Path) else v for k, v in flat_values(settings).items()}
    return config | {
        "role": "worker",
        "mode": "federated",
        "units": settings.units,
        "broker": settings.public_broker,
        "unit": settings.device_unit,
        "ppo": asdict(settings.learning.ppo()),
    }
