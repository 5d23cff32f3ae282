"""An arm of an experiment: a dict of ``fleetrl train`` settings repeated over seeds; its command line and its
key are both derived from it, so the printed command and the key cannot disagree."""

import hashlib
import json
import shlex
from dataclasses import dataclass
from pathlib import Path
from typing import Any

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
