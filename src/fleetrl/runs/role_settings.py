"""The settings of ``fleetrl chief`` and ``fleetrl worker`` (docs/deploy.md): what both must agree on
(:class:`RoleSettings`) and what each adds."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from fleetrl.envs.catalog import check_takes_link, get_env_spec
from fleetrl.federation.chief.lease import DEFAULT_KEEPALIVE
from fleetrl.federation.wire.messages import MessageRejected
from fleetrl.federation.wire.signing import FleetKey, Status, parse_status
from fleetrl.federation.wire.topics import status_topic, validate_id
from fleetrl.runs.host_settings import host_setting_problem, member_ids
from fleetrl.runs.learning_resolution import positive
from fleetrl.runs.setting_values import SettingError, check_readable_file, check_writable_dir, label
from fleetrl.runs.settings import (
    DEVICE_LINKS,
    BrokerLogin,
    FleetShape,
    LearningSettings,
    RoundRules,
    as_setting_error,
    choose,
    path_text,
    resolve_and_probe,
)
from fleetrl.runs.spec import WorkerSpec
from fleetrl.runs.uneven import UnevenFleet


@dataclass(frozen=True, kw_only=True)
class RoleSettings(BrokerLogin):
    """What the chief and every worker of a run must agree on, and how each reaches the broker."""

    learning: LearningSettings = field(default_factory=LearningSettings)
    """what every worker learns with (the shared part is checked when a worker joins)"""
    run_id: str
    """the run's id (a topic level shared by all roles)"""
    ca_file: Path | None = None
    """CA certificate for ``mqtts://``"""
    client_cert: Path | None = None
    """client certificate for ``mqtts://`` (optional)"""
    client_key: Path | None = None
    """the client certificate's private key"""
    fleet_key_file: Path | None = None
    """sign and verify every federation message with this key (HMAC-SHA256; all roles share it)"""
    connect_timeout: float = 60.0
    """seconds to keep retrying an unreachable broker, with backoff, before exiting 1 (start order does not
    matter)"""
    keepalive: int = DEFAULT_KEEPALIVE
    """MQTT keep-alive in seconds (1–3600): the broker fires the last will of a role silent for 1.5 × this
    (its lease: how long the place of a stopped or cut-off chief or worker stays held)"""

    def resolved_learning(self) -> tuple[LearningSettings, FleetShape]:
        """The learning settings resolved (and the fleet's shape), then the broker, the run id and every file
        the role will read checked."""
        learning, shape = resolve_and_probe(self.learning)
        if self.broker is None:
            raise SettingError(f"missing setting: {label('broker')} (mqtt://[user@]host:port or mqtts://…)")
        self.validate_broker()
        as_setting_error("run_id", validate_id, self.run_id, "run id")
        for name in ("ca_file", "client_cert", "client_key", "fleet_key_file"):
            check_readable_file(name, getattr(self, name))
        self.fleet_key()
        positive("connect_timeout", self.connect_timeout)
        if (
            isinstance(self.keepalive, bool)
            or not isinstance(self.keepalive, int)
            or not 1 <= self.keepalive <= 3600
        ):
            raise SettingError(
                f"{label('keepalive')} = {self.keepalive!r}: must be a whole number of seconds, 1 to 3600"
            )
        return learning, shape

    def fleet_key(self) -> FleetKey | None:
        """The fleet key (None: messages are not signed)."""
        if self.fleet_key_file is None:
            return None
        return as_setting_error("fleet_key_file", FleetKey.from_file, self.fleet_key_file)

    def transport(self, *, clean_session: bool = False) -> Any:
        """An unconnected MQTT transport to the broker with the role's login."""
        from fleetrl.transport.mqtt import MqttTransport

        assert self.broker is not None, "resolution requires a broker"
        return MqttTransport(
            self.broker,
            clean_session=clean_session,
            connect_timeout=self.connect_timeout,
            keepalive=self.keepalive,
            **self._login(),
        )

    def _login(self) -> dict[str, Any]:
        return {
            "ca_file": path_text(self.ca_file),
            "cert_file": path_text(self.client_cert),
            "key_file": path_text(self.client_key),
            "password": self.broker_password,
        }

    def read_status(self, node: str) -> Status | None:
        """The retained status of ``node`` (``chief`` or a worker id) of this run, over a connection of its
        own; None if there is none, or it is not a status (ConnectionError: no broker in time)."""
        from fleetrl.transport.mqtt import read_retained

        assert self.broker is not None, "resolution requires a broker"
        payload = read_retained(
            self.broker,
            status_topic(self.run_id, node),
            client_id=f"fleetrl-{self.run_id}-probe-{os.getpid()}-{time.monotonic_ns() % 10**9}",
            timeout=self.connect_timeout,
            **self._login(),
        )
        if payload is None:
            return None
        try:
            return parse_status(payload, run_id=self.run_id, node=node, key=self.fleet_key())
        except MessageRejected:
            return None


@dataclass(frozen=True, kw_only=True)
class ChiefSettings(RoleSettings, RoundRules):
    """``fleetrl chief``: serve one run as its chief (Algorithm 1)."""

    workers: int
    """N: the workers are ids 0 … N-1 (the units, with --units-per-host)"""
    units_per_host: int = 1
    """the N units are in unit hosts of this many (``fleetrl worker --units``, the last host what is left):
    the members are host-0, host-U, …; 1: a worker per unit"""
    out: Path | None = None
    """write chief.json, chief.log and a checkpoint every round (checkpoints/chief/) here"""
    resume: bool = False
    """continue the run from the checkpoint in ``out`` (after a crash; same settings)"""
    idle_timeout: float = 600.0
    """give up (exit 1) after this many seconds without any worker message"""
    dropout_grace: float = 3.0
    """seconds a worker that went offline has to come back before it leaves W"""
    closed_fleet: bool = False
    """take only workers 0 … N-1 (by default a worker with another id joins the running fleet: a new unit)"""

    def resolved(self) -> ChiefSettings:
        """A new value with every default filled in; SettingError naming the first that cannot work."""
        learning, shape = self.resolved_learning()
        quorum = self.resolved_quorum(learning, shape)
        if self.workers < 1:
            raise SettingError(f"{label('workers')} = {self.workers}: must be at least 1")
        hosts = host_setting_problem(self.units_per_host, learning)
        if hosts is not None:
            raise SettingError(f"{label('units_per_host')} = {self.units_per_host}: {hosts}")
        positive("idle_timeout", self.idle_timeout)
        positive("dropout_grace", self.dropout_grace, allow_zero=True)
        if self.out is None:
            if self.resume:
                raise SettingError(f"--resume needs {label('out')}: the directory holding the checkpoint")
        else:
            check_writable_dir("out", self.out)
        return replace(self, learning=learning, quorum=quorum)

    def member_ids(self) -> list[str]:
        """W at the start: the worker ids 0 … N-1, or each host's id."""
        return member_ids(self.workers, self.units_per_host)


@dataclass(frozen=True, kw_only=True)
class WorkerSettings(RoleSettings):
    """``fleetrl worker``: serve as one worker of a run (Algorithm 2)."""

    worker_id: int
    """this worker's id (0 … N-1; another id joins a running fleet as a new unit, unless its chief runs
    with --closed-fleet)"""
    out: Path
    """this worker's run directory (metrics, model, a checkpoint every round in checkpoints/)"""
    units: int = 1
    """more than 1: this process is a unit host of the simulated units worker_id … worker_id+units-1, one
    member (host-<worker_id>) of a chief run with --units-per-host; it keeps no checkpoints"""
    unit: int | None = None
    """device unit to train on (unset: the worker id)"""
    resume: bool = False
    """continue from the checkpoint in ``out`` at its round (after a crash; same settings)"""
    reply_timeout: float = 600.0
    """give up (exit 1) after this many seconds without the chief's answer"""
    resend_interval: float = 5.0
    """re-send the round's message after this many seconds without an answer"""
    device_link: str = "inprocess"
    """``inprocess``: the unit is simulated in this process; ``mqtt``: the unit is driven through its device
    bridge (``fleetrl device --run-id RUN --unit K``) on the same broker, with this worker's login"""
    uneven: UnevenFleet = field(default_factory=UnevenFleet)
    """how this simulated unit is uneven (``--pace``, ``--slow wK=F``, ``--link-delay wK=S``, ``--absent``,
    ``--absent-rounds``; a table's entries for other workers are not this one's)"""

    def resolved(self) -> WorkerSettings:
        """A new value with every default filled in; SettingError naming the first that cannot work."""
        learning, _ = self.resolved_learning()  # the env's spaces fit the agent, the scheme the preset
        choose("device_link", self.device_link, DEVICE_LINKS)
        if self.device_link == "mqtt":
            as_setting_error("device_link", check_takes_link, get_env_spec(learning.env))
        if self.worker_id < 0 or (self.unit is not None and self.unit < 0):
            raise SettingError(f"{label('worker_id')} and {label('unit')}: must be non-negative")
        positive("reply_timeout", self.reply_timeout)
        positive("resend_interval", self.resend_interval)
        uneven = self.uneven.resolved_uneven(get_env_spec(learning.env).control_period, None)
        self._check_host(learning)
        check_writable_dir("out", self.out)
        return replace(self, learning=learning, uneven=uneven)

    def _check_host(self, learning: LearningSettings) -> None:
        if self.units == 1:
            return
        problem = host_setting_problem(self.units, learning)
        if problem is None and self.resume:
            problem = "a unit host keeps no checkpoints, so it cannot --resume (restart it without)"
        if problem is None and self.unit is not None:
            problem = "a unit host's units are its ids from --worker-id on: leave --unit unset"
        if problem is None and self.device_link != "inprocess":
            problem = "a standalone unit host runs simulated units (a unit behind its bridge: --units 1)"
        if problem is not None:
            raise SettingError(f"{label('units')} = {self.units}: {problem}")

    def unit_ids(self) -> list[int]:
        """The units this worker trains: its own id, or a host's ids from it on."""
        return list(range(self.worker_id, self.worker_id + self.units))

    @property
    def device_unit(self) -> int:
        return self.worker_id if self.unit is None else self.unit

    def worker_spec(self) -> WorkerSpec:
        """The spec this worker trains with."""
        return WorkerSpec(
            worker=self.worker_id,
            unit=self.device_unit,
            learning=self.learning,
            out=str(self.out),
            device_url=self.public_broker if self.device_link == "mqtt" else None,
            device_run_id=self.run_id,
            uneven=self.uneven.for_worker(self.worker_id, get_env_spec(self.learning.env).control_period),
        )

    def device_transport(self) -> Any:
        """With ``device_link = "mqtt"``: an unconnected transport for the device link (a clean session);
        None without."""
        return self.transport(clean_session=True) if self.device_link == "mqtt" else None
