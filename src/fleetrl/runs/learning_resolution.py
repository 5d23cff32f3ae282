"""The learning settings resolved once before anything starts (every default filled in, every value checked),
the fleet's shape the chief needs before any worker exists, and the small checks every command's settings
use."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, get_type_hints

from fleetrl.agent.config import DEFAULT_PRESET, PPOConfig, get_preset
from fleetrl.envs.catalog import describe_env, get_env_spec
from fleetrl.federation.schemes import DEFAULT_SCHEME, get_scheme
from fleetrl.federation.shared_settings import LearningSettings
from fleetrl.runs.setting_values import SettingError, coerce, label


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


def as_setting_error(name: str, check: Any, *args: Any) -> Any:
    """Run a lower layer's own check; its ValueError becomes a SettingError naming the setting."""
    try:
        return check(*args)
    except SettingError:
        raise
    except ValueError as err:
        raise SettingError(f"{label(name)}: {err}") from None


def resolve_learning(learning: LearningSettings, *, default_scheme: str = DEFAULT_SCHEME) -> LearningSettings:
    """``learning`` with every default filled in (``default_scheme`` if none is named) and every value
    checked: a new value, or SettingError naming the first setting that cannot work. No agent is built."""
    resolved, _ = _resolve(learning, default_scheme, probe=False)
    return resolved


def resolve_and_probe(
    learning: LearningSettings, *, default_scheme: str = DEFAULT_SCHEME
) -> tuple[LearningSettings, FleetShape]:
    """:func:`resolve_learning`, and the fleet's shape read from the one agent built for it."""
    resolved, shape = _resolve(learning, default_scheme, probe=True)
    assert shape is not None
    return resolved, shape


def _resolve(
    learning: LearningSettings, default_scheme: str, *, probe: bool
) -> tuple[LearningSettings, FleetShape | None]:
    env = as_setting_error("env", get_env_spec, learning.env)
    profile = as_setting_error("fleet_profile", env.resolve_fleet_profile, learning.fleet_profile)
    as_setting_error("preset", get_preset, learning.preset)
    scheme = default_scheme if learning.scheme is None else learning.scheme
    as_setting_error("scheme", get_scheme, scheme)
    params = as_setting_error("scheme_params", lambda: get_scheme(scheme, **learning.scheme_params).params())
    if learning.max_rounds < 1:
        raise SettingError(f"{label('max_rounds')} = {learning.max_rounds}: must be at least 1")
    if learning.seed < 0 or learning.fleet_seed < 0:
        raise SettingError(f"{label('seed')}, {label('fleet_seed')}: must be non-negative integers")
    overrides = typed_overrides(learning.overrides)
    as_setting_error("overrides", replace(get_preset(learning.preset), **overrides).validate)
    target = learning.target_score
    if target is not None and not math.isfinite(target):
        raise SettingError(f"{label('target_score')} = {target}: must be a finite number")
    unit = as_setting_error("env", describe_env, learning.env)  # builds unit 0: a bad factory fails here
    resolved = replace(
        learning, fleet_profile=profile, scheme=scheme, scheme_params=params, overrides=overrides
    )
    agent = _probe_agent(resolved) if probe else None  # before the target: the agent is the deeper fault
    if target is None:
        target = as_setting_error("target_score", env.default_target, unit)
    resolved = replace(resolved, target_score=target)
    return resolved, None if agent is None else fleet_shape(resolved, agent)


def _probe_agent(learning: LearningSettings) -> Any:
    from fleetrl.runs.factory import probe_agent  # torch: only once the cheap checks passed

    return as_setting_error("env", probe_agent, learning.env, learning.ppo())


def with_large_fleet_update(learning: LearningSettings, units: int) -> LearningSettings:
    """``learning`` for a federated fleet of ``units``: the unit type's large-fleet update, from its size on
    and with the default preset, under the ``--set`` overrides (an explicit one wins)."""
    rule = as_setting_error("env", get_env_spec, learning.env).large_fleet
    if rule is None or units < rule.from_units or learning.preset != DEFAULT_PRESET:
        return learning
    return replace(learning, overrides=dict(rule.settings) | dict(learning.overrides))


def typed_overrides(overrides: dict[str, Any]) -> dict[str, Any]:
    """The ``--set`` overrides, each as its PPOConfig field's type; SettingError naming an unknown one."""
    hints = get_type_hints(PPOConfig)
    unknown = sorted(set(overrides) - set(hints))
    if unknown:
        raise SettingError(
            f"--set {', '.join(unknown)}: unknown PPO setting(s) (known: {', '.join(sorted(hints))})"
        )
    return {k: coerce(f"--set {k}", v, hints[k]) for k, v in overrides.items()}


@dataclass(frozen=True)
class FleetShape:
    """What the chief needs before any worker exists: the names and shapes of what the scheme shares, and its
    exchanges per round."""

    layout: list[tuple[str, tuple[int, ...]]]
    exchanges_per_round: int


def fleet_shape(learning: LearningSettings, agent: Any = None) -> FleetShape:
    """The shape of a fleet of resolved ``learning`` settings, read from ``agent`` or else from one agent
    built for it; SettingError if the agent or the scheme cannot run."""
    agent = _probe_agent(learning) if agent is None else agent
    scheme = learning.federation_scheme()
    steps = as_setting_error("scheme", scheme.exchanges_per_round, agent)
    return FleetShape(list(scheme.layout(agent)), steps)
