"""The settings of a run, for every command that starts one: typed, defaulted, validated once before anything
starts.

``RunSettings`` is ``fleetrl train``'s; :mod:`fleetrl.runs.role_settings` has the chief's and the worker's.
They are built from parts every command shares (:class:`LearningSettings`, :class:`RoundRules`,
:class:`BrokerLogin`), so a new setting is one field (a type, a default, a docstring) in the part it belongs
to, plus its check in that part's ``validate_*`` method and its flag. A field's name is its config-file key
and its flag's ``dest``; :func:`fleetrl.runs.setting_values.build` reads a file and the flags into them.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import platform
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, get_type_hints

from fleetrl.agent.config import PPOConfig, get_preset
from fleetrl.envs.catalog import describe_env, get_env_spec
from fleetrl.federation.aggregation import get_aggregator
from fleetrl.federation.schemes import DEFAULT_SCHEME, Granularity, Scheme, get_scheme
from fleetrl.runs.setting_values import (
    SettingError,
    check_readable_file,
    check_writable_dir,
    coerce,
    dump_toml,
    label,
    toml_values,
)
from fleetrl.transport.login import broker_password, password_in_url, without_password
from fleetrl.transport.mqtt import BrokerAddress

log = logging.getLogger(__name__)

MODES = ("individual", "federated")
TRANSPORTS = ("mqtt", "local")
DEVICE_LINKS = ("inprocess", "mqtt")
NOT_RESULT_SETTINGS = ("out", "live", "broker", "broker_password_file")
"""settings that cannot change what a run learns (where it writes, the live view, the broker's address)"""


def choose(name: str, value: str, choices: tuple[str, ...]) -> None:
    """SettingError unless ``value`` is one of ``choices``."""
    if value not in choices:
        what = name.replace("_", " ")
        raise SettingError(f"{label(name)}: unknown {what} {value!r} (choose {' or '.join(choices)})")


def positive(name: str, value: float | None, *, allow_zero: bool = False) -> None:
    """SettingError unless ``value`` (if set) is > 0 (or ≥ 0)."""
    if value is not None and not (value >= 0 if allow_zero else value > 0):
        bound = "≥ 0" if allow_zero else "> 0"
        raise SettingError(f"{label(name)} = {value!r}: must be {bound}")


def check_scheme_quorum(scheme: str, quorum: float) -> None:
    """SettingError if a scheme that averages every optimisation step is given a quorum below 1."""
    if quorum < 1.0 and get_scheme(scheme).granularity is Granularity.STEP:
        raise SettingError(
            f"{label('quorum')} = {quorum}: scheme {scheme} averages every optimisation step over every "
            "worker; it needs quorum 1"
        )


def as_setting_error(name: str, check: Any, *args: Any) -> Any:
    """Run a lower layer's own check; its ValueError becomes a SettingError naming the setting."""
    try:
        return check(*args)
    except SettingError:
        raise
    except ValueError as err:
        raise SettingError(f"{label(name)}: {err}") from None


@dataclass(kw_only=True)
class LearningSettings:
    """What every worker learns with (the chief needs it for the shape of what is shared)."""

    env: str = "qube"
    """the unit type: ``qube`` (QUBE-Servo 2 balance), ``cartpole``, or your own as
    ``package.module:factory`` with ``factory(unit, fleet_seed) -> gymnasium.Env``"""
    fleet_profile: str | None = None
    """the simulated fleet's profile (QUBE: ``table2``, the default, or ``v1``, the fleet before the
    calibration; CartPole and unit factories have one fleet); validation fills in the default's name"""
    target_score: float | None = None
    """learning is complete when the weighted moving average of the last 10 scores reaches it (default: the
    built-in's own target, QUBE 2450, CartPole 475; a factory's env spec ``reward_threshold``); validation
    fills it in"""
    preset: str = "standard"
    """PPO preset: ``standard`` (the default: the settings that learn on every unit type measured),
    ``paper`` (Table 1 as written, to reproduce the paper) or ``paper-code`` (what the authors' code ran)"""
    max_rounds: int = 1000
    """the paper's M: the most rounds per worker (a round is one episode, or with the paper-code preset
    the episodes that fill the memory)"""
    scheme: str | None = None
    """federated: ``pergrad`` (the default), ``paper`` (Algorithms 1 and 2), ``fedavg``, ``fedavgm`` or
    ``fedadam`` (:mod:`fleetrl.federation.schemes`); None: the default, which validation fills in
    (:meth:`default_scheme`)"""
    scheme_params: dict[str, Any] = field(default_factory=dict)
    """the scheme's parameters (``--scheme-param KEY=VALUE``; the ``[scheme_params]`` table); validation
    fills in the scheme's defaults, so equal schemes have equal tables"""
    overrides: dict[str, Any] = field(default_factory=dict)
    """PPO config fields that replace the preset's (``--set KEY=VALUE``; the ``[overrides]`` table)"""

    def validate_learning(self) -> None:
        """Env, preset, scheme and its parameters, M and every PPO override (name, type, range), then unit 0
        of the env built once (its spaces checked) and the target score."""
        env = as_setting_error("env", get_env_spec, self.env)
        self.fleet_profile = as_setting_error("fleet_profile", env.resolve_fleet_profile, self.fleet_profile)
        as_setting_error("preset", get_preset, self.preset)
        if self.scheme is None:
            self.scheme = self.default_scheme()
        as_setting_error("scheme", get_scheme, self.scheme)
        self.scheme_params = as_setting_error("scheme_params", self.federation_scheme).params()
        if self.max_rounds < 1:
            raise SettingError(f"{label('max_rounds')} = {self.max_rounds}: must be at least 1")
        self.overrides = self._typed_overrides()
        if self.target_score is not None and not math.isfinite(self.target_score):
            raise SettingError(f"{label('target_score')} = {self.target_score}: must be a finite number")
        from fleetrl.runs.factory import probe_agent  # torch: only once the cheap checks passed

        unit = as_setting_error("env", describe_env, self.env)  # builds unit 0: a bad factory fails here
        agent = as_setting_error("env", probe_agent, self.env, self.ppo())
        if self.target_score is None:
            self.target_score = as_setting_error("target_score", env.default_target, unit)
        as_setting_error("scheme", self.federation_scheme().exchanges_per_round, agent)

    def result_target_score(self) -> dict[str, float]:
        """``target_score`` as a result setting: none for a built-in at its own target, so that the records of
        built-in runs made before the setting existed keep their keys (like an empty ``scheme_params``)."""
        spec = get_env_spec(self.env)
        if spec.builtin and self.target_score == spec.declared_target:
            return {}
        assert self.target_score is not None, "validate_learning fills in the target score"
        return {"target_score": self.target_score}

    def shared_settings(self, fleet_seed: int) -> dict[str, str]:
        """What every role of a run of these settings on fleet ``fleet_seed`` must share, as the chief's
        ``welcome`` and a worker's ``join`` carry it (:mod:`fleetrl.runs.shared`)."""
        from fleetrl.runs.shared import shared_settings

        return shared_settings(
            env=self.env, fleet_seed=fleet_seed, fleet_profile=self.fleet_profile, preset=self.preset,
            overrides=self.overrides, scheme=self.scheme_name, scheme_params=self.scheme_params,
            target_score=self.target_score,
        )  # fmt: skip

    def default_scheme(self) -> str:
        """The scheme a run takes when none is named: :data:`~fleetrl.federation.schemes.DEFAULT_SCHEME`."""
        return DEFAULT_SCHEME

    @property
    def scheme_name(self) -> str:
        """The run's scheme: the one named, else :meth:`default_scheme`."""
        return self.scheme or self.default_scheme()

    def federation_scheme(self) -> Scheme:
        """A new scheme object of the run (its name and parameters); ValueError naming a bad one."""
        return get_scheme(self.scheme_name, **self.scheme_params)

    def _typed_overrides(self) -> dict[str, Any]:
        hints = get_type_hints(PPOConfig)
        unknown = sorted(set(self.overrides) - set(hints))
        if unknown:
            raise SettingError(
                f"--set {', '.join(unknown)}: unknown PPO setting(s) (known: {', '.join(sorted(hints))})"
            )
        return {k: coerce(f"--set {k}", v, hints[k]) for k, v in self.overrides.items()}

    def ppo(self) -> PPOConfig:
        """The preset with the overrides applied, type- and range-checked."""
        config = dataclasses.replace(get_preset(self.preset), **self._typed_overrides())
        as_setting_error("overrides", config.validate)
        return config

    def ppo_config(self) -> dict[str, Any]:
        """:meth:`ppo` as a plain dict."""
        return asdict(self.ppo())


@dataclass(kw_only=True)
class RoundRules:
    """How the chief closes a round."""

    aggregation: str = "mean"
    """how the chief aggregates (mean, median, trimmed_mean[:β], clipped_mean[:C])"""
    quorum: float = 1.0
    """fraction of W whose answers close a round at the deadline (1.0: fully synchronous; < 1 needs
    ``round_timeout``)"""
    round_timeout: float | None = None
    """seconds after which a round closes with the quorum (unset: wait for every worker)"""

    def validate_rounds(self) -> None:
        """Aggregation rule, quorum and round timeout, and that they fit together."""
        as_setting_error("aggregation", get_aggregator, self.aggregation)
        if not 0.0 < self.quorum <= 1.0:
            raise SettingError(f"{label('quorum')} = {self.quorum}: must be in (0, 1]")
        positive("round_timeout", self.round_timeout)
        if self.quorum < 1.0 and self.round_timeout is None:
            raise SettingError(
                f"{label('quorum')} = {self.quorum} needs {label('round_timeout')}: "
                "the quorum applies at the round deadline"
            )


@dataclass(kw_only=True)
class BrokerLogin:
    """Where the broker is and how to log in; the password never travels in a URL a run writes or passes
    on."""

    broker: str | None = None
    """``mqtt://[user@]host:port`` or ``mqtts://…`` (train: none starts an embedded broker)"""
    broker_password_file: Path | None = None
    """a file holding the broker password (else the ``FLEETRL_BROKER_PASSWORD`` environment variable)"""

    def validate_broker(self) -> None:
        """The URL parses; the password file is readable; a password inside the URL is warned about."""
        if self.broker is None:
            return
        as_setting_error("broker", BrokerAddress.parse, self.broker)
        check_readable_file("broker_password_file", self.broker_password_file)
        if password_in_url(self.broker):
            log.warning(
                "the broker URL carries a password: every local user sees it in `ps` and it stays in shell "
                "history; use --broker-password-file FILE or FLEETRL_BROKER_PASSWORD instead"
            )

    @property
    def broker_password(self) -> str | None:
        """The password: from the file, else from the URL, else from the environment (None: no login)."""
        return broker_password(self.broker_password_file, self.broker)

    @property
    def public_broker(self) -> str | None:
        """The broker URL without its password (safe to log, to write and to pass on a command line)."""
        return None if self.broker is None else without_password(self.broker)


@dataclass(kw_only=True)
class RunSettings(LearningSettings, RoundRules, BrokerLogin):
    """One training run of a simulated fleet (``fleetrl train``)."""

    out: Path
    """the run directory (created; must not hold a run)"""
    mode: str = "federated"
    """``individual`` (each unit alone, the paper's Fig. 5a) or ``federated`` (Algorithms 1 and 2)"""
    units: int = 3
    """how many units (one worker each)"""
    seed: int = 0
    """fixes the learning: network initialisation, action sampling, window starts"""
    fleet_seed: int = 0
    """fixes the fleet: with the unit index it draws each unit's dynamics"""
    transport: str = "mqtt"
    """federated: ``mqtt`` (a real broker, workers in processes) or ``local`` (in-process bus, threads)"""
    device_link: str = "inprocess"
    """how workers reach their devices: ``inprocess`` or ``mqtt`` (one device bridge per unit)"""
    device_driver: str | None = None
    """with ``device_link = "mqtt"``: the device side the bridges serve, ``package.module:function`` with
    ``driver(unit, fleet_seed, *, realtime) -> DeviceDriver`` (needed for a unit factory; a built-in's
    bridges serve its simulated units)"""
    live: bool = True
    """show the live terminal view"""

    def default_scheme(self) -> str:
        """Federated: :data:`~fleetrl.federation.schemes.DEFAULT_SCHEME`; each unit alone: ``paper``, whose
        learners stop at completion (the scheme is otherwise unused, and the result settings stay those of
        the individual runs made before the default changed)."""
        return "paper" if self.mode == "individual" else DEFAULT_SCHEME

    def validate(self) -> None:
        """Raise SettingError naming the first setting that cannot work; nothing is created."""
        self.validate_learning()
        choose("mode", self.mode, MODES)
        choose("transport", self.transport, TRANSPORTS)
        choose("device_link", self.device_link, DEVICE_LINKS)
        if self.mode == "individual" and (self.scheme != "paper" or self.scheme_params):
            raise SettingError(f"--scheme {self.scheme} is a federation scheme: it needs --mode federated")
        self.validate_rounds()
        check_scheme_quorum(self.scheme_name, self.quorum)
        self.validate_broker()
        if self.units < 1:
            raise SettingError(f"{label('units')} = {self.units}: must be at least 1")
        if self.seed < 0 or self.fleet_seed < 0:
            raise SettingError(f"{label('seed')}, {label('fleet_seed')}: must be non-negative integers")
        self.validate_device_link()
        if (self.out / "metrics.csv").exists():
            raise SettingError(f"{label('out')} = {str(self.out)!r} already holds a run; choose another")
        check_writable_dir("out", self.out)

    def validate_device_link(self) -> None:
        """With device bridges: the unit type can be reached through a link, and its driver function (a
        user's, named by ``device_driver``) loads, builds unit 0 and fits the env's spaces. Without: no
        driver is named."""
        if self.device_link != "mqtt":
            if self.device_driver is not None:
                raise SettingError(
                    f"{label('device_driver')} names what device bridges serve: it needs "
                    f"{label('device_link')} mqtt"
                )
            return
        from fleetrl.envs.device_side import bridge_driver, check_bridge_driver

        env = get_env_spec(self.env)
        name = "device_link" if self.device_driver is None or not env.takes_link else "device_driver"
        driver = as_setting_error(name, bridge_driver, env, self.device_driver)
        unit = describe_env(self.env)
        as_setting_error("device_driver", check_bridge_driver, driver, unit, self.fleet_seed)

    def bridge_driver(self) -> Any:
        """What the run's device bridges serve (:func:`fleetrl.envs.device_side.bridge_driver`)."""
        from fleetrl.envs.device_side import bridge_driver

        return bridge_driver(get_env_spec(self.env), self.device_driver)

    @property
    def needs_broker(self) -> bool:
        """Whether any part of the run talks MQTT."""
        federated_mqtt = self.mode == "federated" and self.transport == "mqtt"
        return federated_mqtt or self.device_link == "mqtt"

    def to_toml(self) -> str:
        """config.toml of the run directory: every setting (no password), so that
        ``fleetrl train --config runs/x/config.toml --out runs/y`` reruns the run."""
        table = toml_values(self)
        if self.broker is not None:
            table["broker"] = self.public_broker
        header = (
            "fleetrl train settings of this run (no password is ever written here).\n"
            f"Rerun it: fleetrl train --config {self.out / 'config.toml'} --out NEW_DIR"
        )
        return dump_toml(table, header)

    def result_settings(self) -> dict[str, Any]:
        """Every setting that can change the run's result, as JSON-plain values (the fleet profile's default
        name, the typed overrides and the scheme's parameters filled in): two runs with equal result settings
        learn the same. A scheme without parameters (``paper``, ``fedavg``) has no ``scheme_params`` key, and
        a built-in at its own target no ``target_score`` key, as in the records made before either existed."""
        self.validate_learning()
        values = {k: v for k, v in asdict(self).items() if k not in NOT_RESULT_SETTINGS}
        if not values["scheme_params"]:
            del values["scheme_params"]
        if values["device_driver"] is None:  # as in the records made before the setting existed
            del values["device_driver"]
        del values["target_score"]
        values |= self.result_target_score()
        plain: dict[str, Any] = json.loads(json.dumps(values, sort_keys=True, default=str))
        return plain

    def to_config(self) -> dict[str, Any]:
        """Everything that defines the run, for config.json (the resolved PPO config too; no password)."""
        import torch

        config = asdict(self)
        config["out"] = str(self.out)
        config["broker"] = self.public_broker
        config["broker_password_file"] = path_text(self.broker_password_file)
        config["ppo"] = self.ppo_config()
        config["result_settings"] = self.result_settings()
        unit = describe_env(self.env)
        config["env_id"] = unit.env_id
        config["completion_threshold"] = self.target_score
        config["episode_cap"] = unit.episode_cap
        config["versions"] = {"python": platform.python_version(), "torch": torch.__version__}
        return config


def path_text(path: Path | None) -> str | None:
    return None if path is None else str(path)
