"""Does a seeded run depend on the host CPU? Emulate other CPUs on this one and compare the scores.

    python lab/benchmarks/portable_determinism.py [--cartpole-rounds 40] [--qube-rounds 12]

Runs the same short seeded training in child processes under settings that make torch, MKL, numba, numpy and
glibc's libm take another CPU's code paths (and all at once), in the default and the portable mode
(``FLEETRL_PORTABLE=1``); prints per mode whether every emulated CPU gave the host's scores, and CPU times.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import resource
import subprocess
import sys

VARIANTS: dict[str, dict[str, str]] = {
    "host": {},
    "torch: no SIMD (ATEN default)": {"ATEN_CPU_CAPABILITY": "default"},
    "MKL: SSE4.2 kernels": {"MKL_ENABLE_INSTRUCTIONS": "SSE4_2"},
    "MKL: AVX kernels": {"MKL_ENABLE_INSTRUCTIONS": "AVX"},
    "MKL: compatible path (MKL_CBWR)": {"MKL_CBWR": "COMPATIBLE"},
    "numba: generic x86-64": {"NUMBA_CPU_NAME": "generic"},
    "numpy: x86-64-v3 off": {"NPY_DISABLE_CPU_FEATURES": "X86_V3"},
    "glibc libm: no AVX2/FMA": {"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX2,-FMA"},
}
VARIANTS["an old CPU: all of the above"] = {k: v for extra in VARIANTS.values() for k, v in extra.items()}


def probe(cartpole_rounds: int, qube_rounds: int) -> None:
    """Child: play the seeded rounds and print their scores as JSON (one line)."""
    import fleetrl  # noqa: F401, I001  (first: it applies FLEETRL_PORTABLE before numpy and torch load)
    import gymnasium
    import torch
    from fleetrl.agent.config import get_preset
    from fleetrl.agent.criterion import CompletionCriterion
    from fleetrl.agent.learner import Learner
    from fleetrl.agent.ppo import PPOAgent
    from fleetrl.envs.registration import CARTPOLE_UNIT_ID, QUBE_BALANCE_ID

    torch.set_num_threads(1)
    scores: dict[str, list[float]] = {}
    for env_id, rounds, target in (
        (CARTPOLE_UNIT_ID, cartpole_rounds, 475.0),
        (QUBE_BALANCE_ID, qube_rounds, 2450.0),
    ):
        env = gymnasium.make(env_id, unit=0, fleet_seed=0)
        agent = PPOAgent(4, int(env.action_space.n), get_preset("standard"), seed=0)  # type: ignore[attr-defined]
        learner = Learner(env, agent, CompletionCriterion(target), seed=0)
        scores[env_id] = [learner.play_round().score for _ in range(rounds)]
        # the last bits of the weights show a difference before the scores do
        scores[env_id + " θ"] = [float(x) for x in agent.actor_parameters()[:4]]
    print(json.dumps({"scores": scores, "torch_capability": torch.backends.cpu.get_cpu_capability()}))


def run_child(
    extra_env: dict[str, str], portable: bool, cartpole_rounds: int, qube_rounds: int
) -> tuple[dict, float]:
    """The probe's result in a child process, and the child's CPU seconds."""
    env = {k: v for k, v in os.environ.items() if k != "FLEETRL_PORTABLE"}
    env.update(extra_env)
    if portable:
        env["FLEETRL_PORTABLE"] = "1"
    command = [sys.executable, __file__, "--probe"]
    command += ["--cartpole-rounds", str(cartpole_rounds), "--qube-rounds", str(qube_rounds)]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    return json.loads(out.stdout.strip().splitlines()[-1]), cpu


def digest(result: dict) -> str:
    return hashlib.sha256(json.dumps(result["scores"], sort_keys=True).encode()).hexdigest()[:12]


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--probe", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--cartpole-rounds", type=int, default=40)
    parser.add_argument("--qube-rounds", type=int, default=12)
    args = parser.parse_args()
    if args.probe:
        probe(args.cartpole_rounds, args.qube_rounds)
        return 0
    print(f"# {args.cartpole_rounds} CartPoleUnit rounds + {args.qube_rounds} QUBE rounds, standard, seed 0")
    verdicts = {}
    for portable in (False, True):
        mode = "portable (FLEETRL_PORTABLE=1)" if portable else "default"
        print(f"\n## mode: {mode}")
        print(f"{'emulated CPU':34s} {'torch':8s} {'scores digest':14s} {'same as host':13s} CPU s")
        reference, same_everywhere = None, True
        for name, extra in VARIANTS.items():
            result, seconds = run_child(extra, portable, args.cartpole_rounds, args.qube_rounds)
            d = digest(result)
            reference = reference or d
            same = d == reference
            same_everywhere &= same
            cap = result["torch_capability"]
            print(f"{name:34s} {cap:8s} {d:14s} {'yes' if same else 'NO':13s} {seconds:6.1f}", flush=True)
        verdicts[mode] = same_everywhere
    print()
    for mode, same in verdicts.items():
        verdict = "identical scores under every emulated CPU" if same else "scores depend on the CPU"
        print(f"{mode}: {verdict}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
