"""A run's learning settings as one frozen value (:class:`LearningSettings`: its fields' defaults are the
only defaults, its flags and help are generated from them), and the part every role must share: the chief's
``welcome`` and a worker's ``join`` carry :func:`shared_text`; a worker whose map differs is refused at join.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from fleetrl.agent.config import DEFAULT_PRESET, PPOConfig, get_preset
from fleetrl.federation.schemes import Scheme, get_scheme

SharedSettings = Mapping[str, str]  # setting name → its value as text, the same on every machine

MISSING = "<not set>"  # how a setting one side lacks is shown
NOT_SHARED = {"shared": False}  # field metadata of a setting each role may have its own of


@dataclass(frozen=True, kw_only=True)
class LearningSettings:
    """What every worker learns with; the fields not marked ``NOT_SHARED`` must be equal on every role."""

    env: str = "qube"
    """the unit type: ``qube`` (QUBE-Servo 2 balance), ``cartpole``, or your own as ``package.module:factory``
    with ``factory(unit, fleet_seed) -> gymnasium.Env`` (imported from the current directory or the installed
    packages)"""
    fleet_seed: int = 0
    """seed of the fleet's per-unit dynamics: with the unit index it draws each unit"""
    fleet_profile: str | None = None
    """the simulated fleet's profile (QUBE: ``table2``, fitted to the paper's Table 2, ``v1``, the fleet
    before the calibration, or ``wide``, mixed revisions and wear; CartPole: ``standard`` or ``wide``, masses,
    pole length and force ±40 per cent; a user's unit type has one fleet); unset: the unit type's own"""
    preset: str = DEFAULT_PRESET
    """PPO preset: ``standard`` (learns on every unit type measured), ``paper`` (Table 1 as written, to
    reproduce the paper) or ``paper-code`` (what the authors' code ran)"""
    overrides: dict[str, Any] = field(default_factory=dict)
    """PPO settings that replace the preset's, e.g. ``--set clip_eps=0.2`` (the ``[overrides]`` table)"""
    scheme: str | None = None
    """federated: ``pergrad`` (gradients averaged at every optimisation step), ``paper`` (the paper's
    gradient sharing + model transfer), ``fedavg`` (model averaging), ``fedavgm`` or ``fedadam`` (fedavg
    with a server optimiser)"""
    scheme_params: dict[str, Any] = field(default_factory=dict)
    """the scheme's parameters, e.g. ``--scheme-param momentum=0.9`` (the ``[scheme_params]`` table);
    resolution fills in the scheme's defaults, so equal schemes have equal tables"""
    target_score: float | None = None
    """learning is complete when the weighted moving average of the last 10 scores reaches it; unset: the
    unit type's own (a factory's env spec ``reward_threshold``)"""
    seed: int = field(default=0, metadata=NOT_SHARED)
    """the learning seed: a worker's action sampling, window starts and network initialisation (each worker
    its own); under a scheme whose fleet is one policy the chief's seed draws the network every worker
    starts from"""
    max_rounds: int = field(default=1000, metadata=NOT_SHARED)
    """the paper's M: the most rounds per worker (a round is one episode, or with the paper-code preset the
    episodes that fill the memory)"""

    @property
    def scheme_name(self) -> str:
        """The resolved value's scheme (resolution names one)."""
        assert self.scheme is not None, "resolve_learning names the scheme"
        return self.scheme

    def federation_scheme(self) -> Scheme:
        """A new scheme object of these settings (its name and parameters); ValueError naming a bad one."""
        return get_scheme(self.scheme_name, **self.scheme_params)

    def ppo(self) -> PPOConfig:
        """The preset with the overrides applied (resolution has type- and range-checked them)."""
        return dataclasses.replace(get_preset(self.preset), **self.overrides)

    def to_json(self) -> dict[str, Any]:
        """The fields as JSON-plain values (tuples as lists), which the constructor reads back."""
        plain: dict[str, Any] = json.loads(json.dumps(dataclasses.asdict(self)))
        return plain


def shared_text(settings: LearningSettings) -> dict[str, str]:
    """Every shared field of the resolved ``settings`` as text, written the same way on every machine."""
    text = {}
    for f in dataclasses.fields(settings):
        if f.metadata.get("shared", True):
            value = getattr(settings, f.name)
            text[f.name] = value if isinstance(value, str) else _canonical(value)
    text["fleet_profile"] = settings.fleet_profile or "none"
    text["fleet_seed"] = str(int(settings.fleet_seed))
    target = settings.target_score
    text["target_score"] = _canonical(None if target is None else float(target))
    return text


def _canonical(value: Any) -> str:
    return json.dumps(value, sort_keys=True, separators=(",", ":"))


class SettingsRefused(ValueError):
    """The chief refused this worker at join: a shared setting differs (a setting error: exit code 2)."""


def settings_difference(chief: SharedSettings, worker: SharedSettings) -> str | None:
    """Why ``worker``'s settings cannot join ``chief``'s run (the first differing key); None if equal."""
    for key in sorted(set(chief) | set(worker)):
        ours, theirs = chief.get(key, MISSING), worker.get(key, MISSING)
        if ours != theirs:
            return f"setting {key!r} differs (chief {ours!r}, worker {theirs!r})"
    return None
