"""``fleetrl train``'s settings (:class:`RunSettings`) and the parts every command shares
(:class:`RoundRules`, :class:`BrokerLogin`): frozen, each field a setting (its docstring the flag's help),
resolved once before anything starts."""

from __future__ import annotations

import dataclasses
import json
import logging
import platform
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

from fleetrl.envs.catalog import describe_env, get_env_spec
from fleetrl.federation.aggregation import get_aggregator
from fleetrl.federation.schemes import DEFAULT_SCHEME
from fleetrl.federation.schemes.paper import PaperScheme
from fleetrl.federation.shared_settings import LearningSettings
from fleetrl.runs.host_settings import (
    AUTO,
    auto_units_per_host,
    host_setting_problem,
    hosts_possible,
    usable_cores,
)
from fleetrl.runs.learning_resolution import (
    FleetShape,
    as_setting_error,
    choose,
    fleet_shape,
    resolve_and_probe,
    resolve_learning,
    with_large_fleet_update,
)
from fleetrl.runs.memory_fit import run_memory_problem
from fleetrl.runs.setting_values import (
    SettingError,
    check_readable_file,
    check_writable_dir,
    flat_values,
    label,
    toml_text,
)
from fleetrl.runs.uneven import UnevenFleet
from fleetrl.transport.login import broker_password, password_in_url, without_password

log = logging.getLogger(__name__)

__all__ = [
    "BrokerLogin",
    "LearningSettings",
    "RoundRules",
    "RunSettings",
    "fleet_shape",
    "resolve_and_probe",
    "resolve_learning",
]

MODES = ("individual", "federated")
TRANSPORTS = ("mqtt", "local")
DEVICE_LINKS = ("inprocess", "mqtt")
NOT_RESULT_SETTINGS = ("out", "live", "per_unit_detail", "broker", "broker_password_file")
"""settings that cannot change what a run learns"""
ALONE_SCHEME = PaperScheme.name
"""the scheme of a run whose units learn alone (``--mode individual``): its learners stop at completion"""


@dataclass(frozen=True, kw_only=True)
class RoundRules:
    """How the chief closes a round."""

    aggregation: str = "mean"
    """how the chief aggregates: mean (the paper's), median, trimmed_mean[:β], clipped_mean[:C]"""
    quorum: float | None = None
    """a once-per-round scheme: at the round deadline, close the round if this fraction of W answered (1:
    fully synchronous; < 1 needs ``round_timeout``); a per-step scheme: once this fraction of the workers
    waited for answered an exchange, the others get a grace of a quarter of that time (docs/protocol.md,
    "Stragglers"). Unset: the scheme's own (1 once per round, 0.6 per step)"""
    round_timeout: float | None = None
    """round deadline in seconds (unset: wait for every worker, the paper's fully synchronous rule)"""
    max_staleness: int | None = None
    """a per-step scheme: rounds a straggler's contribution may lag the fleet and still be averaged (unset:
    no bound)"""

    @property
    def chief_quorum(self) -> float:
        assert self.quorum is not None, "resolved() fills in the quorum"
        return self.quorum

    def resolved_quorum(self, learning: LearningSettings, shape: FleetShape) -> float:
        """The quorum (the scheme's own unless given), with the aggregation and the round rules checked."""
        from fleetrl.federation.chief.answer import check_round_rules

        as_setting_error("aggregation", get_aggregator, self.aggregation)
        scheme = learning.federation_scheme()
        quorum = scheme.default_quorum if self.quorum is None else self.quorum
        try:
            check_round_rules(
                scheme, learning.max_rounds, quorum, self.round_timeout, shape.exchanges_per_round,
                self.max_staleness, self.aggregation,
            )  # fmt: skip
        except ValueError as err:
            raise SettingError(str(err)) from None
        return quorum


@dataclass(frozen=True, kw_only=True)
class BrokerLogin:
    """Where the broker is and how to log in (the password never travels in a URL a run writes)."""

    broker: str | None = None
    """``mqtt://[user@]host:port`` or ``mqtts://…``"""
    broker_password_file: Path | None = None
    """the broker password's file (else ``$FLEETRL_BROKER_PASSWORD``; never put it in the URL)"""

    def validate_broker(self) -> None:
        if self.broker is None:
            return
        from fleetrl.transport.mqtt import BrokerAddress  # paho: not needed to build the flags

        as_setting_error("broker", BrokerAddress.parse, self.broker)
        check_readable_file("broker_password_file", self.broker_password_file)
        if password_in_url(self.broker):
            log.warning(
                "the broker URL carries a password: every local user sees it in `ps` and it stays in shell "
                "history; use --broker-password-file FILE or FLEETRL_BROKER_PASSWORD instead"
            )

    @property
    def broker_password(self) -> str | None:
        """From the file, else the URL, else the environment (None: no login)."""
        return broker_password(self.broker_password_file, self.broker)

    @property
    def public_broker(self) -> str | None:
        """The broker URL without its password."""
        return None if self.broker is None else without_password(self.broker)


@dataclass(frozen=True, kw_only=True)
class RunSettings(RoundRules, BrokerLogin):
    """One training run of a simulated fleet (``fleetrl train``)."""

    learning: LearningSettings = field(default_factory=LearningSettings)
    """what every worker learns with (its fields are settings of their own: ``--env``, ``--preset``, …)"""
    out: Path
    """the run directory to create (must not hold a run)"""
    mode: str = "federated"
    """``individual`` (each unit alone, the paper's Fig. 5a) or ``federated`` (Algorithms 1 and 2)"""
    units: int = 3
    """units in the fleet, one worker each"""
    units_per_host: int | Literal["auto"] = AUTO
    """units each worker carries (a unit host: their envs stepped together, one policy acting for all of
    them in one pass, one gradient per exchange; federated, pergrad); 1: one worker per unit; ``auto`` (the
    default): about one host per core above 16 units where the run can have hosts, else 1"""
    transport: str = "mqtt"
    """federated: ``mqtt`` (a real broker, workers or unit hosts in processes) or ``local`` (in-process
    bus, threads)"""
    device_link: str = "inprocess"
    """how workers reach their devices: ``inprocess`` or ``mqtt`` (one device bridge per unit, over the
    broker)"""
    device_driver: str | None = None
    """with ``device_link = "mqtt"``: the device side the bridges serve, ``package.module:function`` with
    ``driver(unit, fleet_seed, *, realtime) -> DeviceDriver`` (needed for a unit factory; a built-in's
    bridges serve its simulated units)"""
    live: bool = True
    """show the live terminal view"""
    per_unit_detail: bool = False
    """show every unit however large the fleet: one plot panel, one live-view row and one TensorBoard
    series per unit (by default a fleet of more than 16 units is summarised: units completed, WMA
    quantiles, the slowest units)"""
    uneven: UnevenFleet = field(default_factory=UnevenFleet)
    """how the simulated fleet is made uneven (its fields are settings of their own: ``--pace``, ``--slow``,
    ``--link-delay``, ``--absent``, ``--absent-rounds``); not a learning setting, never shared at join"""

    def resolved(self) -> RunSettings:
        """A new value with every default filled in and every setting checked (SettingError naming the first
        that cannot work); nothing is created."""
        learning = self.learning
        if self.mode == "federated":
            learning = with_large_fleet_update(learning, self.units)
        learning, shape = resolve_and_probe(learning, default_scheme=self.default_scheme)
        choose("mode", self.mode, MODES)
        choose("transport", self.transport, TRANSPORTS)
        choose("device_link", self.device_link, DEVICE_LINKS)
        if self.mode == "individual" and (learning.scheme != ALONE_SCHEME or self.learning.scheme_params):
            raise SettingError(
                f"--scheme {learning.scheme} is a federation scheme: it needs --mode federated"
            )
        quorum = self.resolved_quorum(learning, shape)
        self.validate_broker()
        if self.units < 1:
            raise SettingError(f"{label('units')} = {self.units}: must be at least 1")
        filled = self._filled(learning, quorum)
        if filled.uneven.link_delay and self.mode != "federated":
            raise SettingError(
                f"{label('link_delay')} delays the messages of a federated run: it needs --mode federated"
            )
        self.validate_device_link(learning)
        own_part = learning.ppo().own_part
        if own_part != "none" and self.mode != "federated":
            raise SettingError(
                f"own_part {own_part!r} is a unit's own part beside the fleet's shared policy: it needs "
                "--mode federated"
            )
        hosts = host_setting_problem(filled.per_host, learning, self.mode)
        if hosts is not None:
            raise SettingError(f"{label('units_per_host')} = {self.units_per_host}: {hosts}")
        can_host = hosts_possible(learning, "federated", filled.uneven.even)
        memory = run_memory_problem(
            self.units, self.mode, self.transport, filled.per_host, hosts_possible=can_host
        )
        if memory is not None:
            raise SettingError(memory)
        if (self.out / "metrics.csv").exists():
            raise SettingError(f"{label('out')} = {str(self.out)!r} already holds a run; choose another")
        check_writable_dir("out", self.out)
        return filled

    def learning_resolved(self) -> RunSettings:
        """What :meth:`result_settings` needs, without building an agent: the learning settings, quorum,
        uneven fleet and units per host resolved, nothing else checked."""
        learning = resolve_learning(self.learning, default_scheme=self.default_scheme)
        quorum = learning.federation_scheme().default_quorum if self.quorum is None else self.quorum
        return self._filled(learning, quorum)

    @property
    def default_scheme(self) -> str:
        return ALONE_SCHEME if self.mode == "individual" else DEFAULT_SCHEME

    def _filled(self, learning: LearningSettings, quorum: float) -> RunSettings:
        """This value with resolved ``learning`` and ``quorum``, the uneven fleet resolved and the units per
        host chosen (``auto``: :func:`auto_units_per_host`)."""
        uneven = self.uneven.resolved_uneven(get_env_spec(learning.env).control_period, self.units)
        per_host = self.units_per_host
        if per_host == AUTO:
            possible = hosts_possible(learning, self.mode, uneven.even)
            per_host = auto_units_per_host(self.units, possible=possible, cores=usable_cores())
        return replace(self, learning=learning, quorum=quorum, uneven=uneven, units_per_host=per_host)

    @property
    def per_host(self) -> int:
        assert self.units_per_host != AUTO, "resolved() chooses the units per host"
        return self.units_per_host

    def validate_device_link(self, learning: LearningSettings) -> None:
        """With device bridges: the unit type can be reached and its driver builds unit 0 to the env's spaces;
        without: no driver is named."""
        if self.device_link != "mqtt":
            if self.device_driver is not None:
                raise SettingError(
                    f"{label('device_driver')} names what device bridges serve: it needs "
                    f"{label('device_link')} mqtt"
                )
            return
        from fleetrl.envs.device_side import bridge_driver, check_bridge_driver

        env = get_env_spec(learning.env)
        name = "device_link" if self.device_driver is None or not env.takes_link else "device_driver"
        driver = as_setting_error(name, bridge_driver, env, self.device_driver)
        unit = describe_env(learning.env)
        as_setting_error("device_driver", check_bridge_driver, driver, unit, learning.fleet_seed)

    def bridge_driver(self) -> Any:
        from fleetrl.envs.device_side import bridge_driver

        return bridge_driver(get_env_spec(self.learning.env), self.device_driver)

    @property
    def needs_broker(self) -> bool:
        federated_mqtt = self.mode == "federated" and self.transport == "mqtt"
        return federated_mqtt or self.device_link == "mqtt"

    def to_toml(self) -> str:
        """config.toml: every setting but the password, so that ``fleetrl train --config`` reruns the run."""
        header = (
            "fleetrl train settings of this run (no password is ever written here).\n"
            f"Rerun it: fleetrl train --config {self.out / 'config.toml'} --out NEW_DIR"
        )
        return toml_text(replace(self, broker=self.public_broker), header)

    def result_settings(self) -> dict[str, Any]:
        """Every setting that can change the run's result, as JSON-plain values."""
        values = {k: v for k, v in flat_values(self).items() if k not in NOT_RESULT_SETTINGS}
        plain: dict[str, Any] = json.loads(json.dumps(values, sort_keys=True, default=str))
        return plain

    def to_config(self) -> dict[str, Any]:
        """config.json: everything that defines the resolved run (no password)."""
        import torch

        config = flat_values(self)
        config["out"] = str(self.out)
        config["broker"] = self.public_broker
        config["broker_password_file"] = path_text(self.broker_password_file)
        config["ppo"] = dataclasses.asdict(self.learning.ppo())
        config["result_settings"] = self.result_settings()
        unit = describe_env(self.learning.env)
        config["env_id"] = unit.env_id
        config["completion_threshold"] = self.learning.target_score
        config["episode_cap"] = unit.episode_cap
        config["versions"] = {"python": platform.python_version(), "torch": torch.__version__}
        return config


def path_text(path: Path | None) -> str | None:
    return None if path is None else str(path)
