"""The ``units_per_host`` setting: which runs can group their units into unit hosts, and how."""

from __future__ import annotations

import math
import os
from typing import Literal

from fleetrl.federation.shared_settings import LearningSettings


def host_setting_problem(per_host: int, learning: LearningSettings, mode: str = "federated") -> str | None:
    """Why a run of resolved ``learning`` cannot have ``per_host`` units per host (naming what to change), or
    None."""
    if per_host < 1:
        return f"must be at least 1, got {per_host}"
    if per_host == 1:
        return None
    own_part = learning.ppo().own_part
    if own_part != "none":
        return f"own_part {own_part!r} gives each unit a part of its own: it needs a worker per unit (1)"
    if mode != "federated":
        return "a unit host is one member of a federation: it needs --mode federated"
    scheme = learning.federation_scheme()
    if not scheme.one_policy_per_step:
        return (
            f"a unit host is one policy for its units: it needs a one-policy per-step scheme (pergrad), "
            f"not {scheme.name}"
        )
    return None


AUTO: Literal["auto"] = "auto"
"""``--units-per-host auto``: :func:`auto_units_per_host`"""
AUTO_HOSTS_ABOVE_UNITS = 16
"""``auto`` keeps one worker per unit up to this many units"""


def usable_cores() -> int:
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def units_per_core(units: int, cores: int) -> int:
    return max(1, math.ceil(units / max(cores, 1)))


def hosts_possible(learning: LearningSettings, mode: str, even: bool) -> bool:
    """Whether ``auto`` groups a run of these settings into unit hosts: an even fleet that can have them."""
    return even and host_setting_problem(2, learning, mode) is None


def auto_units_per_host(units: int, *, possible: bool, cores: int) -> int:
    """What ``auto`` chooses: about one host per core for a fleet of more than :data:`AUTO_HOSTS_ABOVE_UNITS`
    units that can have hosts, else 1."""
    return units_per_core(units, cores) if possible and units > AUTO_HOSTS_ABOVE_UNITS else 1


def host_groups(units: int, per_host: int) -> list[list[int]]:
    """The units of each host, in order (the last one carrying what is left)."""
    return [list(range(start, min(start + per_host, units))) for start in range(0, units, per_host)]


def host_id(units: list[int]) -> str:
    """A host's federation id: ``host-`` and its first unit."""
    return f"host-{units[0]}"


def member_ids(units: int, per_host: int) -> list[str]:
    """The federation's members: the worker ids 0 … N-1, or each host's :func:`host_id`."""
    if per_host == 1:
        return [str(k) for k in range(units)]
    return [host_id(group) for group in host_groups(units, per_host)]
