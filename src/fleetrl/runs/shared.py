"""The settings all roles of a federated run must share, as the text map the chief's ``welcome`` and each
worker's ``join`` carry (:mod:`fleetrl.federation.shared_settings` compares them).

They are what makes the workers' messages mean the same thing to the chief and to each other: the env (the
tensor shapes and the task), the fleet seed and profile (which units the fleet is made of), the PPO preset
and its ``--set`` overrides, and the scheme with its parameters. Each value is written the same way on every
machine (JSON with sorted keys), so equal settings give equal text.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

from fleetrl.federation.schemes import get_scheme
from fleetrl.runs.spec import WorkerSpec


def shared_settings(
    *,
    env: str,
    fleet_seed: int,
    fleet_profile: str | None,
    preset: str,
    overrides: Mapping[str, Any],
    scheme: str,
    scheme_params: Mapping[str, Any],
    target_score: float | None,
) -> dict[str, str]:
    """The shared settings of a run as name → value text (validated settings in, so every value is known;
    the scheme's parameters are written as the scheme object gives them, defaults filled in)."""
    return {
        "env": env,
        "fleet_seed": str(int(fleet_seed)),
        "fleet_profile": fleet_profile or "none",
        "preset": preset,
        "overrides": _canonical(dict(overrides)),
        "scheme": scheme,
        "scheme_params": _canonical(get_scheme(scheme, **scheme_params).params()),
        "target_score": _canonical(None if target_score is None else float(target_score)),
    }


def _canonical(value: Any) -> str:
    return json.dumps(value, sort_keys=True, separators=(",", ":"))


def spec_shared_settings(spec: WorkerSpec) -> dict[str, str]:
    """A worker's shared settings, from its spec."""
    return shared_settings(
        env=spec.env,
        fleet_seed=spec.fleet_seed,
        fleet_profile=spec.fleet_profile,
        preset=spec.preset,
        overrides=spec.overrides,
        scheme=spec.scheme,
        scheme_params=spec.scheme_params,
        target_score=spec.target_score,
    )
