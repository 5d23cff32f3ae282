"""An arm of an experiment: a dict of ``fleetrl train`` settings repeated over seeds; its command line and its
key are both derived from it, so the printed command and the key cannot disagree; an experiment's
:class:`Budget`."""

import hashlib
import json
import shlex
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fleetrl.federation.schemes import StepScheme, resolve_scheme
from fleetrl_lab.records import record_path
from fleetrl_lab.sweep import Run, train_args

KEY_SETTINGS = ("env", "units", "mode", "preset", "max_rounds", "scheme", "fleet_seed", "transport")
"""settings the key spells out; any other makes the key end in a digest of them"""


def arm_key(settings: dict[str, Any]) -> str:
    """A directory name for ``settings``: ``qube-3-federated-standard-m1000-fedavg`` (a factory's
    ``package.module:factory`` as ``package.module-factory``; ``-fleet<n>`` off fleet
    seed 0, ``-mqtt`` over MQTT, ``-<digest>`` if anything else is set)."""
    env, units, mode, preset = (settings[k] for k in ("env", "units", "mode", "preset"))
    env = str(env).replace(":", "-")  # a unit factory's package.module:factory
    key = f"{env}-{units}-{mode}-{preset}-m{settings['max_rounds']}"
    if settings.get("scheme") not in (None, "paper"):  # the keys made before arms named a scheme
        key += f"-{settings['scheme']}"
    if settings.get("fleet_seed", 0):
        key += f"-fleet{settings['fleet_seed']}"
    if settings.get("transport") == "mqtt" and settings["mode"] == "federated":
        key += "-mqtt"
    rest = {k: v for k, v in settings.items() if k not in KEY_SETTINGS}
    if rest.get("quorum") == 1.0:  # the keys made before arms named their quorum
        del rest["quorum"]
    if rest:
        key += "-" + hashlib.sha256(json.dumps(rest, sort_keys=True).encode()).hexdigest()[:8]
    return key


@dataclass(frozen=True)
class Places:
    """Where a sweep's runs and records go."""

    runs: Path
    """run directories (models, TensorBoard; not committed)"""
    records: Path
    """run records (committed beside the report)"""
    unseen_units: int = 0
    """units of the generalisation row per run"""


@dataclass(frozen=True, eq=False)
class Arm:
    """One configuration of ``fleetrl train``, run once per seed."""

    label: str
    """how the report names it"""
    settings: dict[str, Any]
    """``fleetrl train`` settings other than ``seed`` and ``out``"""

    @property
    def key(self) -> str:
        """Directory name of its runs and records."""
        return arm_key(self.settings)

    @property
    def criterion(self) -> str:
        """What a unit's completion proves in this arm's runs (``sampled``, the paper's, or ``argmax``)."""
        return str((self.settings.get("overrides") or {}).get("criterion", "sampled"))

    @property
    def units(self) -> int:
        """Units (one worker each)."""
        return int(self.settings["units"])

    def with_settings(self, **changes: Any) -> "Arm":
        """The same arm with some settings changed (its key follows)."""
        return Arm(self.label, {**self.settings, **changes})

    def run(self, places: Places, seed: int) -> Run:
        """The run of this arm for ``seed``."""
        return Run(
            places.runs / self.key / f"seed-{seed}",
            {**self.settings, "seed": seed},
            record_path(places.records, self.key, seed),
            {"arm": self.key, "seed": seed},
            places.unseen_units,
        )

    def runs(self, places: Places, seeds: list[int]) -> list[Run]:
        """One run per seed."""
        return [self.run(places, seed) for seed in seeds]

    def command(self, root: Path) -> str:
        """The command that regenerates the arm's runs (one per seed)."""
        out = shlex.quote(str(root / self.key))
        args = shlex.join(train_args(self.settings))
        return f"for s in SEEDS; do fleetrl train {args} --seed $s --out {out}/seed-$s; done"


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
