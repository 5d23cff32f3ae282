"""A digest of short seeded runs, to show that a refactoring of the learning code changed no number.

    python lab/benchmarks/run_fingerprint.py [--rounds 30] [--fleet-rounds 10] [--part alone|fleet|hosts|all]

Prints SHA-256 digests of the scores and final parameters of runs alone (each preset and env), federated
through ``fleetrl train`` (each preset, scheme and env) and in unit hosts. Equal digests before and after a
change on one machine mean bit-identical runs.
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import subprocess
import sys
import tempfile
from pathlib import Path

# isort: off
import fleetrl  # noqa: F401  (first: it applies FLEETRL_PORTABLE before numpy and torch load)
import gymnasium
import numpy as np
import torch

# isort: on
from fleetrl import portable
from fleetrl.agent.config import get_preset
from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.agent.learner import Learner
from fleetrl.agent.ppo import PPOAgent
from fleetrl.envs.registration import CARTPOLE_UNIT_ID, QUBE_BALANCE_ID

SEED = 3


def fingerprint(preset: str, env_id: str, rounds: int) -> tuple[str, str]:
    env = gymnasium.make(env_id, unit=0, fleet_seed=0)
    obs_dim = int(env.observation_space.shape[0])  # type: ignore[index]
    agent = PPOAgent(obs_dim, int(env.action_space.n), get_preset(preset), seed=SEED)  # type: ignore[attr-defined]
    learner = Learner(env, agent, CompletionCriterion(1e9), seed=SEED)
    scores = np.array([learner.play_round().score for _ in range(rounds)], dtype=np.float64)
    params = agent.model_parameters()
    return digest(scores.tobytes()), digest(params.tobytes())


def digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:16]


PRESETS = ("paper", "paper-code", "standard")
SCHEMES = ("paper", "fedavg", "pergrad", "fedavgm", "fedavgm:momentum=0.5", "fedadam", "fedprox")
"""each scheme with its defaults (fedavgm's momentum 0 is fedavg), and fedavgm with momentum"""
HOST_SCHEMES = ("pergrad",)  # run again in unit hosts (6 units, 3 a host, preset standard): per-step only


def fleet_fingerprint(
    preset: str, scheme: str, env: str, rounds: int, units: int = 3, per_host: int = 1
) -> tuple[str, str]:
    """Digests of a federated ``fleetrl train`` of ``units`` units (``per_host`` a host), in-process."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        command = [sys.executable, "-m", "fleetrl.cli.main", "train", "--env", env, "--units", str(units)]
        command += ["--units-per-host", str(per_host)]
        name, _, param = scheme.partition(":")
        command += ["--mode", "federated", "--transport", "local", "--scheme", name, "--preset", preset]
        command += ["--scheme-param", param] if param else []
        command += ["--seed", str(SEED), "--max-rounds", str(rounds), "--no-live", "--out", str(out)]
        done = subprocess.run(command, capture_output=True, text=True)
        if done.returncode != 0:
            return f"failed({done.returncode})", done.stderr.strip().splitlines()[-1][:60]
        with (out / "metrics.csv").open() as f:
            rows = sorted((int(r["round"]), r["worker"], r["score"]) for r in csv.DictReader(f))
        scores = digest(repr(rows).encode())
        params = hashlib.sha256()
        for model in sorted((out / "models").glob("*.safetensors")):
            from safetensors.numpy import load_file

            tensors = load_file(str(model))
            for name in sorted(tensors):
                params.update(name.encode() + tensors[name].tobytes())
        return scores, params.hexdigest()[:16]


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--rounds", type=int, default=30, help="rounds of each run alone")
    parser.add_argument("--fleet-rounds", type=int, default=10, help="rounds of each federated run")
    parser.add_argument("--part", choices=("alone", "fleet", "hosts", "all"), default="all")
    args = parser.parse_args()
    torch.set_num_threads(1)
    print(f"# seed {SEED}; {portable.describe_host()}")
    if args.part in ("alone", "all"):
        print(f"# alone, {args.rounds} rounds")
        for env_id in (CARTPOLE_UNIT_ID, QUBE_BALANCE_ID):
            for preset in PRESETS:
                scores, params = fingerprint(preset, env_id, args.rounds)
                print(f"{env_id:26s} {preset:10s} scores {scores} parameters {params}", flush=True)
    if args.part in ("fleet", "all"):
        print(f"# 3 units federated on the in-process bus, {args.fleet_rounds} rounds")
        for env in ("cartpole", "qube"):
            for preset in PRESETS:
                for scheme in SCHEMES:
                    scores, params = fleet_fingerprint(preset, scheme, env, args.fleet_rounds)
                    line = f"{env:8s} {preset:10s} {scheme:8s} scores {scores} parameters {params}"
                    print(line, flush=True)
    if args.part in ("hosts", "all"):
        print(f"# 6 units federated in unit hosts of 3 on the in-process bus, {args.fleet_rounds} rounds")
        for env in ("cartpole", "qube"):
            for scheme in HOST_SCHEMES:
                scores, params = fleet_fingerprint("standard", scheme, env, args.fleet_rounds, 6, 3)
                print(f"{env:8s} hosts      {scheme:8s} scores {scores} parameters {params}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
