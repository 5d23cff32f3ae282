"""The environments a fleet can train on, by the short names the command line uses."""

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from fleetrl.envs.registration import (
    CARTPOLE_EPISODE_CAP,
    CARTPOLE_UNIT_ID,
    QUBE_BALANCE_ID,
    QUBE_EPISODE_CAP,
)


@dataclass(frozen=True)
class EnvSpec:
    """What a run needs to know about one environment type."""

    name: str
    """short name used on the command line (``qube``, ``cartpole``)"""
    gym_id: str
    """registered Gymnasium id"""
    episode_cap: int
    """steps after which an episode is truncated"""
    completion_threshold: float
    """weighted moving average of the last 10 scores at which a worker's learning is complete"""
    fleet_profile: Callable[[str | None], str] | None = None
    """the name of the fleet profile chosen by a name (None: the default), with a ValueError for an unknown
    one; None if the unit type has a single fleet"""

    def resolve_fleet_profile(self, name: str | None) -> str | None:
        """The fleet profile a run of this env draws its units with (``name``, or the type's default); a
        ValueError if ``name`` is unknown or this unit type has no profiles."""
        if self.fleet_profile is not None:
            return self.fleet_profile(name)
        if name is not None:
            raise ValueError(f"{self.name} units have one fleet, no fleet profiles (got {name!r})")
        return None

    def make_kwargs(self, fleet_profile: str | None) -> dict[str, Any]:
        """The keyword arguments of ``gymnasium.make`` that pick the fleet profile (none for one fleet)."""
        resolved = self.resolve_fleet_profile(fleet_profile)
        return {} if resolved is None else {"fleet_profile": resolved}


def _qube_fleet_profile(name: str | None) -> str:
    from fleetrl.devices.qube.fleet_profiles import fleet_profile  # compiles the physics: only when asked

    return fleet_profile(name).name


ENV_SPECS: dict[str, EnvSpec] = {
    "qube": EnvSpec("qube", QUBE_BALANCE_ID, QUBE_EPISODE_CAP, 2450.0, _qube_fleet_profile),
    "cartpole": EnvSpec("cartpole", CARTPOLE_UNIT_ID, CARTPOLE_EPISODE_CAP, 475.0),
}


def get_env_spec(name: str) -> EnvSpec:
    """Look up an environment by short name, with an error that lists the choices."""
    try:
        return ENV_SPECS[name]
    except KeyError:
        choices = " or ".join(sorted(ENV_SPECS))
        raise ValueError(f"unknown env {name!r} (choose {choices})") from None
