"""The budget of an experiment's runs (:class:`Budget`) and an arm's training settings (:func:`arm`)."""

from dataclasses import dataclass
from typing import Any

from fleetrl.federation.schemes import StepScheme, resolve_scheme
from fleetrl_lab.arms import Arm


@dataclass(frozen=True)
class Budget:
    """How big an experiment's runs are (the paper's M, the unseen units) and which fleet they train on."""

    qube_rounds: int
    cartpole_rounds: int
    unseen_units: int
    """units of the generalisation row (each final policy, one greedy episode on each)"""
    fleet_seed: int = 0
    """the fleet every arm trains on"""
    unit_type: str | None = None
    """a user's unit type (``--env``) trained instead of the built-ins, for ``cartpole_rounds`` rounds"""
    target_score: float | None = None
    """every arm's ``--target-score`` (None: the env's own)"""


FULL = Budget(qube_rounds=1000, cartpole_rounds=400, unseen_units=10)
QUICK = Budget(qube_rounds=4, cartpole_rounds=6, unseen_units=2)

TUNING_SEEDS = range(0, 10)
"""the learning seeds tuning may use; a report's figures are on seeds outside them"""
TUNING_FLEET_SEED = 0


def arm(
    env: str,
    units: int,
    mode: str,
    preset: str,
    rounds: int,
    label: str,
    scheme: str | None = None,
    fleet_seed: int = 0,
    target_score: float | None = None,
    scheme_params: dict[str, float] | None = None,
    overrides: dict[str, object] | None = None,
    run: dict[str, Any] | None = None,
) -> Arm:
    """A training arm. Federated arms use the in-process bus and name their ``scheme``, and a per-step scheme
    its ``quorum`` (1), so a new default changes no arm. ``run``: other run settings."""
    settings: dict[str, object] = {
        "env": env,
        "units": units,
        "mode": mode,
        "preset": preset,
        "max_rounds": rounds,
    }
    if mode == "federated":
        if scheme is None:
            raise ValueError(f"arm {label!r}: a federated arm names its scheme")
        settings["transport"] = "local"
        settings["scheme"] = scheme
        if isinstance(resolve_scheme(scheme), StepScheme):  # the rule its records were made with
            settings["quorum"] = 1.0
    if fleet_seed:
        settings["fleet_seed"] = fleet_seed
    if target_score is not None:
        settings["target_score"] = target_score
    if scheme_params:
        settings["scheme_params"] = scheme_params
    if overrides:
        settings["overrides"] = overrides
    return Arm(label, {**settings, **(run or {})})
