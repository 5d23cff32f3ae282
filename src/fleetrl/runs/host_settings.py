"""The ``units_per_host`` setting: which runs can group their units into unit hosts, and how."""

from __future__ import annotations

from fleetrl.agent.config import PPOConfig, host_config_problem
from fleetrl.federation.schemes.base import Scheme, StepScheme


def host_setting_problem(
    per_host: int, *, mode: str, transport: str, scheme: Scheme, ppo: PPOConfig, even: bool
) -> str | None:
    """Why a run cannot have ``per_host`` units per host (one line, naming what to change), or None."""
    if per_host < 1:
        return f"must be at least 1, got {per_host}"
    if per_host == 1:
        return None
    if mode != "federated" or transport != "local":
        return "unit hosts run in this process: they need --mode federated --transport local"
    if not (isinstance(scheme, StepScheme) and scheme.shared_start):
        return (
            f"a unit host is one policy for its units: it needs a one-policy per-step scheme (pergrad), "
            f"not {scheme.name}"
        )
    if not even:
        return "a unit host steps its units together: it cannot make them uneven (--pace, --slow, --absent …)"
    return host_config_problem(ppo)


def host_groups(units: int, per_host: int) -> list[list[int]]:
    """The units of each host, in order: hosts of ``per_host`` units (0 … per_host − 1 the first), the last
    one carrying what is left."""
    return [list(range(start, min(start + per_host, units))) for start in range(0, units, per_host)]


def host_id(units: list[int]) -> str:
    """A host's federation id: ``host-`` and its first unit (its units' own ids stay in the metrics)."""
    return f"host-{units[0]}"
