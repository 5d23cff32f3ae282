"""The settings of a training run, as the command line gives them."""

import platform
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from fleetrl.envs.catalog import get_env_spec
from fleetrl.federation.schemes import get_scheme

MODES = ("individual", "federated")
TRANSPORTS = ("mqtt", "local")
DEVICE_LINKS = ("inprocess", "mqtt")


@dataclass
class RunSettings:
    """One training run of a simulated fleet."""

    mode: str
    """``individual`` (each unit alone, the paper's Fig. 5a) or ``federated`` (Algorithms 1 and 2)"""
    env: str
    """``qube`` or ``cartpole``"""
    units: int
    """how many units (one worker each)"""
    preset: str
    """PPO preset: ``paper`` (Table 1) or ``standard``"""
    seed: int
    """fixes the learning: network initialisation, action sampling, window starts"""
    max_rounds: int
    """the paper's M: the most rounds (episodes) per worker"""
    out: Path
    """the run directory"""
    fleet_seed: int = 0
    """fixes the fleet: with the unit index it draws each unit's dynamics"""
    transport: str = "mqtt"
    """federated: ``mqtt`` (a real broker, workers in processes) or ``local`` (in-process bus, threads)"""
    broker: str | None = None
    """federated mode: ``mqtt://[user:pass@]host:port`` of an existing broker; none starts an embedded one"""
    scheme: str = "paper"
    """federated: ``paper`` (Algorithms 1 and 2) or ``fedavg`` (model averaging; see
    :mod:`fleetrl.federation.schemes`)"""
    aggregation: str = "mean"
    """federated: how the chief aggregates gradients (mean, median, trimmed_mean[:β], clipped_mean[:C])"""
    quorum: float = 1.0
    """federated: fraction of W whose gradients close a round at the deadline (1.0: fully synchronous)"""
    round_timeout: float | None = None
    """federated: seconds after which a round closes with the quorum (None: wait for every worker)"""
    device_link: str = "inprocess"
    """how workers reach their devices: ``inprocess`` or ``mqtt`` (one device bridge per unit)"""
    overrides: dict[str, Any] = field(default_factory=dict)
    """PPO config fields that replace the preset's"""
    live: bool = True
    """show the live terminal view"""

    def validate(self) -> None:
        """Raise ValueError with a clear message for any setting that cannot work."""
        get_env_spec(self.env)
        if self.mode not in MODES:
            raise ValueError(f"unknown mode {self.mode!r} (choose {' or '.join(MODES)})")
        if self.transport not in TRANSPORTS:
            raise ValueError(f"unknown transport {self.transport!r} (choose {' or '.join(TRANSPORTS)})")
        get_scheme(self.scheme)
        if self.mode == "individual" and self.scheme != "paper":
            raise ValueError(f"--scheme {self.scheme} is a federation scheme: it needs --mode federated")
        if self.device_link not in DEVICE_LINKS:
            raise ValueError(f"unknown device link {self.device_link!r} (choose {' or '.join(DEVICE_LINKS)})")
        if not 0.0 < self.quorum <= 1.0:
            raise ValueError(f"--quorum must be in (0, 1], got {self.quorum}")
        if self.round_timeout is not None and self.round_timeout <= 0:
            raise ValueError(f"--round-timeout must be positive, got {self.round_timeout}")
        if self.units < 1:
            raise ValueError(f"--units must be at least 1, got {self.units}")
        if self.max_rounds < 1:
            raise ValueError(f"--max-rounds must be at least 1, got {self.max_rounds}")
        if self.seed < 0 or self.fleet_seed < 0:
            raise ValueError("seeds must be non-negative integers")
        self.ppo_config()

    def ppo_config(self) -> dict[str, Any]:
        """The preset's PPO settings with the overrides applied (unknown names are refused)."""
        from fleetrl.agent.config import get_preset

        ppo = asdict(get_preset(self.preset))
        unknown = set(self.overrides) - set(ppo)
        if unknown:
            raise ValueError(f"unknown PPO setting(s) {sorted(unknown)} (known: {', '.join(sorted(ppo))})")
        ppo.update(self.overrides)
        return ppo

    @property
    def needs_broker(self) -> bool:
        """Whether any part of the run talks MQTT."""
        federated_mqtt = self.mode == "federated" and self.transport == "mqtt"
        return federated_mqtt or self.device_link == "mqtt"

    def to_config(self) -> dict[str, Any]:
        """Everything that defines the run, for config.json (including the resolved PPO config)."""
        import torch

        config = asdict(self)
        config["out"] = str(self.out)
        config["ppo"] = self.ppo_config()
        spec = get_env_spec(self.env)
        config["env_id"] = spec.gym_id
        config["completion_threshold"] = spec.completion_threshold
        config["episode_cap"] = spec.episode_cap
        config["versions"] = {"python": platform.python_version(), "torch": torch.__version__}
        return config
