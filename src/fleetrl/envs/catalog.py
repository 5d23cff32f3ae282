"""The environments a fleet can train on, by the short names the command line uses."""

from dataclasses import dataclass

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


ENV_SPECS: dict[str, EnvSpec] = {
    "qube": EnvSpec("qube", QUBE_BALANCE_ID, QUBE_EPISODE_CAP, 2450.0),
    "cartpole": EnvSpec("cartpole", CARTPOLE_UNIT_ID, CARTPOLE_EPISODE_CAP, 475.0),
}


def get_env_spec(name: str) -> EnvSpec:
    """Look up an environment by short name, with an error that lists the choices."""
    try:
        return ENV_SPECS[name]
    except KeyError:
        choices = " or ".join(sorted(ENV_SPECS))
        raise ValueError(f"unknown env {name!r} (choose {choices})") from None
