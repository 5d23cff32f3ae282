"""Launching ``fleetrl train``: individual (a worker process per unit) or federated (the chief a thread of
this process; workers, or unit hosts, processes on a broker or threads on the in-process bus). This process
owns the run directory and the live view; worker processes are forked before the chief's thread starts."""

import logging
import threading
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any

import numpy as np

from fleetrl.envs.catalog import ENV_SPECS, describe_env, get_env_spec
from fleetrl.federation.kinds import new_chief
from fleetrl.federation.runner import ChiefSummary, run_chief
from fleetrl.link.fleet import start_bridges
from fleetrl.runs.factory import chief_plan, make_learner, probe_agent
from fleetrl.runs.fleet import Fleet, ThreadFleet, follow
from fleetrl.runs.fleet_summary import summarised
from fleetrl.runs.host_settings import host_groups, member_ids
from fleetrl.runs.live import LiveView
from fleetrl.runs.processes import ProcessFleet, fork_available
from fleetrl.runs.roles import Emit, train_federated
from fleetrl.runs.rundir import RunDirectoryError, RunRecorder, write_json_atomic
from fleetrl.runs.settings import LearningSettings, RunSettings
from fleetrl.runs.spec import WorkerSpec
from fleetrl.transport.base import Transport
from fleetrl.transport.broker import EmbeddedBroker
from fleetrl.transport.local import LocalBus
from fleetrl.transport.login import password_in_environment
from fleetrl.transport.mqtt import MqttTransport, probe_broker

log = logging.getLogger(__name__)

CHIEF_IDLE_TIMEOUT = 600.0
TRAIN_CONNECT_WINDOW = 10.0
"""seconds ``fleetrl train`` retries a broker given with ``--broker`` before it gives up"""


def demo_settings(out: Path, seed: int = 0) -> RunSettings:
    """The main job: every setting its default (a simulated 3-unit QUBE fleet, federated, embedded broker)."""
    return RunSettings(learning=LearningSettings(seed=seed), out=out)


def worker_specs(settings: RunSettings, device_url: str | None, run_id: str) -> dict[int, WorkerSpec]:
    """One spec per worker; worker K trains unit K of the fleet."""
    period = get_env_spec(settings.learning.env).control_period
    return {
        k: WorkerSpec(
            worker=k,
            unit=k,
            learning=settings.learning,
            out=str(settings.out),
            device_url=device_url,
            device_run_id=run_id,
            uneven=settings.uneven.for_worker(k, period),
        )
        for k in range(settings.units)
    }


def train(settings: RunSettings) -> dict[str, Any]:
    """Run the training of resolved ``settings`` and return summary.json's content."""
    password = settings.broker_password if settings.broker else None
    with password_in_environment(password):  # children inherit it; no argv or file holds it
        if settings.needs_broker and settings.broker:  # fatal now, before the run directory exists
            try:
                probe_broker(settings.broker, timeout=TRAIN_CONNECT_WINDOW, password=password)
            except ConnectionError as err:
                raise ConnectionError(f"{err} (fleetrl train retries its --broker for that long)") from None
        return _train(settings)


def _train(settings: RunSettings) -> dict[str, Any]:
    run_id = f"run-{uuid.uuid4().hex[:8]}"
    summarise = summarised(settings.units, settings.per_unit_detail)
    recorder = RunRecorder(
        Path(settings.out), settings.to_config(), list(range(settings.units)), summarise=summarise
    )
    (recorder.out / "config.toml").write_text(settings.to_toml())
    recorder.extra["run_id"] = run_id
    log.debug("run directory %s ready", recorder.out)
    learning = settings.learning
    title = f"fleetrl {settings.mode} · {learning.env} × {settings.units} · preset {learning.preset}"
    threshold = learning.target_score
    assert threshold is not None, "validation fills in the target score"
    members = host_groups(settings.units, settings.per_host)  # the units each member of the run carries
    try:
        with (
            run_logging(recorder.out / "logs" / "run.log", quiet=settings.live),
            broker_url(settings) as url,
            device_bridges(settings, url, run_id),
            LiveView(title, threshold, enabled=settings.live, summarise=summarise, members=members) as view,
        ):
            device_url = url if settings.device_link == "mqtt" else None
            specs = worker_specs(settings, device_url, run_id)
            if url is not None:
                recorder.extra["broker"] = url
            if settings.mode == "individual":
                commands = {k: [s.to_json()] for k, s in specs.items()}
                follow(process_fleet(settings, commands), recorder, view)
            else:
                fed_url = url if settings.transport == "mqtt" else None
                train_fleet(settings, specs, run_id, fed_url, recorder, view)
    except RunDirectoryError:
        with suppress(OSError):  # the summary and plot too, if there is room; the error says what happened
            recorder.finish()
        raise
    finally:
        if not recorder.finished:
            summary = recorder.finish()
    return summary


@contextmanager
def device_bridges(settings: RunSettings, url: str | None, run_id: str) -> Iterator[None]:
    """One device bridge thread per unit when workers reach their devices over MQTT."""
    if settings.device_link != "mqtt":
        yield
        return
    assert url is not None, "a device link over MQTT needs a broker"
    units = range(settings.units)
    driver = settings.bridge_driver()  # a built-in's device type, or the user's driver function
    learning = settings.learning
    profile = learning.fleet_profile if isinstance(driver, str) else None
    with start_bridges(url, run_id, driver, units, learning.fleet_seed, fleet_profile=profile):
        yield


@contextmanager
def run_logging(path: Path, quiet: bool) -> Iterator[None]:
    """Log everything of this process to ``path``; with ``quiet``, only warnings reach the terminal."""
    path.parent.mkdir(parents=True, exist_ok=True)
    root = logging.getLogger()
    handler = logging.FileHandler(path)
    handler.setFormatter(logging.Formatter("%(asctime)s %(threadName)s %(name)s %(levelname)s %(message)s"))
    handler.setLevel(logging.INFO)
    saved = [(h, h.level) for h in root.handlers]
    if quiet:
        for console, _ in saved:
            console.setLevel(max(console.level, logging.WARNING))
    previous_level = root.level
    root.setLevel(min(root.level or logging.INFO, logging.INFO))
    root.addHandler(handler)
    try:
        yield
    finally:
        root.removeHandler(handler)
        with suppress(OSError):  # a full disk: the run's own error says so
            handler.close()
        root.setLevel(previous_level)
        for console, level in saved:
            console.setLevel(level)


def process_fleet(
    settings: RunSettings, commands: dict[int, list[str]], units: dict[int, list[int]] | None = None
) -> ProcessFleet:
    """The run's worker processes; forked ones start with the kernels loaded."""
    if fork_available():
        load_kernels(settings)
    return ProcessFleet(commands, Path(settings.out) / "logs", units)


def load_kernels(settings: RunSettings) -> None:
    """Load the numba kernels of a step once, for the forked workers: the agent's acting and, for a built-in
    unit type on an in-process link, the unit's physics and reset."""
    learning = settings.learning
    config = learning.ppo()
    agent = probe_agent(learning.env, config)
    description = describe_env(learning.env, config.last_step)
    if learning.env not in ENV_SPECS or settings.device_link != "inprocess":
        agent.act(np.zeros(description.obs_dim, dtype=np.float32))
        return
    built = ENV_SPECS[learning.env].make(
        0, learning.fleet_seed, fleet_profile=learning.fleet_profile, last_step=config.last_step
    )
    try:
        obs, _ = built.env.reset(seed=0)
        action = agent.act(obs)
        built.env.step(action if agent.action_space.is_discrete else agent.env_action(action))
    finally:
        built.env.close()


def host_args(units: list[int]) -> list[str]:
    """The arguments that make a worker process (:mod:`fleetrl.runs.worker_main`, after its spec JSON) the
    unit host of ``units`` (none for one unit)."""
    return [] if len(units) == 1 else ["--host-units", str(len(units))]


def train_fleet(
    settings: RunSettings,
    specs: dict[int, WorkerSpec],
    run_id: str,
    url: str | None,
    recorder: RunRecorder,
    view: LiveView,
) -> None:
    """Chief in a thread of this process; workers as processes (MQTT at ``url``) or threads (local bus)."""
    workers = member_ids(settings.units, settings.per_host)
    plan, kept = chief_plan(settings.learning, settings, run_id=run_id, workers=workers)
    chief = new_chief(plan, **kept)
    make_transport, fleet_for = transports(settings, url, specs, run_id)
    outcome: dict[str, ChiefSummary | BaseException] = {}
    with open(recorder.out / "logs" / "chief.log", "w") as log_file:

        def chief_body() -> None:
            try:
                outcome["chief"] = run_chief(
                    chief,
                    make_transport(),
                    on_event=lambda event: print(event, file=log_file, flush=True),
                    idle_timeout=CHIEF_IDLE_TIMEOUT,
                )
            except BaseException as err:  # reported in summary.json, never lost in a thread
                log.error("chief failed: %s", err)
                outcome["chief"] = err

        chief_thread = threading.Thread(target=chief_body, name="chief", daemon=True)
        fleet = fleet_for()  # worker processes are forked before the chief's thread exists (runs.processes)
        chief_thread.start()
        follow(fleet, recorder, view)
        chief_thread.join(timeout=10)
    result = outcome.get("chief")
    if isinstance(result, ChiefSummary):
        recorder.extra["chief"] = result.to_dict()
    else:
        recorder.extra["chief"] = {"error": str(result) if result else "did not finish"}
    write_json_atomic(recorder.out / "chief.json", recorder.extra["chief"])


@contextmanager
def broker_url(settings: RunSettings) -> Iterator[str | None]:
    """The broker to use: the given one, an embedded one for the run's lifetime, or none."""
    if not settings.needs_broker:
        yield None
    elif settings.broker:
        yield settings.public_broker  # the password is in the environment (password_in_environment)
    else:
        with EmbeddedBroker() as broker:
            log.info("embedded %s broker at %s", broker.kind, broker.url)
            yield broker.url


def transports(
    settings: RunSettings, url: str | None, specs: dict[int, WorkerSpec], run_id: str
) -> tuple[Callable[[], Transport], Callable[[], Fleet]]:
    """(a factory of the chief's transport, a starter of the workers) for the run's transport."""
    groups = {units[0]: units for units in host_groups(settings.units, settings.per_host)}
    if url is None:
        bus = LocalBus()
        bodies = {
            k: member_thread([specs[u] for u in units], bus.client, run_id) for k, units in groups.items()
        }
        return bus.client, lambda: ThreadFleet(bodies, units=groups)

    def federated_fleet() -> Fleet:
        commands = {
            k: [specs[k].to_json(), "--broker", url, "--run-id", run_id, *host_args(units)]
            for k, units in groups.items()
        }
        return process_fleet(settings, commands, units=groups)

    return (lambda: MqttTransport(url, clean_session=False)), federated_fleet


def member_thread(
    specs: list[WorkerSpec], make_transport: Callable[[], Transport], run_id: str
) -> Callable[[Emit], None]:
    """The body of a worker's, or a unit host's, thread on the in-process bus."""

    def body(emit: Emit) -> None:
        learner = None
        if len(specs) == 1:
            learner = make_learner(specs[0])
            log.info("worker %d: learner ready", specs[0].worker)
        train_federated(
            specs, make_transport(), run_id, emit, reply_timeout=CHIEF_IDLE_TIMEOUT, learner=learner
        )

    return body
