"""The peer: Stable-Baselines3 PPO with its defaults, trained per unit on the same registered env, stopped by
the same completion criterion (WMA of the last 10 episode scores ≥ the env's threshold).

``python -m fleetrl_lab.peers --env cartpole --unit 0 --seed 0 --max-steps 200000 --out R.json``
trains one unit and writes the episodes it needed (null if it did not complete within the step budget).
"""

import argparse
import json
import shlex
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fleetrl.agent.criterion import CompletionCriterion
from fleetrl.envs.catalog import describe_env, get_env_spec


def train_sb3_unit(env: str, unit: int, fleet_seed: int, seed: int, max_steps: int) -> dict[str, Any]:
    """Train SB3 PPO (defaults) on one unit until the completion criterion holds or ``max_steps`` pass."""
    try:
        import torch
        from stable_baselines3 import PPO
        from stable_baselines3.common.callbacks import BaseCallback
        from stable_baselines3.common.env_util import make_vec_env
    except ImportError as err:  # pragma: no cover - depends on the install
        raise RuntimeError(
            "the peers experiment needs Stable-Baselines3: pip install 'fleetrl[bench]'"
        ) from err

    from fleetrl.portable import describe_host

    torch.set_num_threads(1)
    spec = get_env_spec(env)
    criterion = CompletionCriterion(spec.default_target(describe_env(env)))
    scores: list[float] = []

    class StopAtCriterion(BaseCallback):
        """Feeds every finished episode's score to the criterion; stops training when it holds."""

        def _on_step(self) -> bool:
            for info in self.locals["infos"]:
                if "episode" in info:
                    scores.append(float(info["episode"]["r"]))
                    criterion.add(scores[-1])
            return not criterion.done

    vec_env = make_vec_env(lambda: spec.make(unit, fleet_seed).env, n_envs=1, seed=seed)
    model = PPO("MlpPolicy", vec_env, seed=seed, device="cpu", verbose=0)
    started = time.monotonic()
    model.learn(total_timesteps=max_steps, callback=StopAtCriterion())
    return {
        "env": env,
        "unit": unit,
        "fleet_seed": fleet_seed,
        "seed": seed,
        "max_steps": max_steps,
        "episodes_to_completion": len(scores) if criterion.done else None,
        "episodes": len(scores),
        "steps": int(model.num_timesteps),
        "final_wma": criterion.wma,
        "wall_seconds": round(time.monotonic() - started, 2),
        "host": describe_host(),
    }


@dataclass
class PeerRun:
    """One SB3 training of one unit, as a process (so two run at once)."""

    out: Path
    """its result (a small JSON record, committed)"""
    log: Path
    """its process's output (not committed)"""
    env: str
    unit: int
    seed: int
    max_steps: int
    fleet_seed: int = 0

    def args(self) -> list[str]:
        """Arguments of this module's command line."""
        numbers = {"--unit": self.unit, "--seed": self.seed, "--fleet-seed": self.fleet_seed}
        numbers["--max-steps"] = self.max_steps
        return [
            "--env",
            self.env,
            *(x for k, v in numbers.items() for x in (k, str(v))),
            "--out",
            str(self.out),
        ]

    def argv(self) -> list[str]:
        """The full command line."""
        return [sys.executable, "-m", "fleetrl_lab.peers", *self.args()]

    def command(self) -> str:
        """The command a person types to rerun it."""
        return shlex.join(["python", "-m", "fleetrl_lab.peers", *self.args()])

    @property
    def name(self) -> str:
        """How progress lines name it."""
        return f"SB3 {self.env} unit {self.unit} seed {self.seed}"

    @property
    def done(self) -> bool:
        """Whether the result file exists and was made with these settings."""
        try:
            result = self.result()
        except (OSError, ValueError):
            return False
        made = (result.get(k) for k in ("env", "unit", "fleet_seed", "seed", "max_steps"))
        return tuple(made) == (self.env, self.unit, self.fleet_seed, self.seed, self.max_steps)

    def reusable(self) -> bool:
        """A result on disk is either done or redone."""
        return False

    def finish(self) -> None:
        """Nothing: the process wrote its result itself."""

    def result(self) -> dict[str, Any]:
        """The result written by the run."""
        data: dict[str, Any] = json.loads(self.out.read_text())
        return data


def main(argv: list[str] | None = None) -> int:
    """Command line of one peer run."""
    parser = argparse.ArgumentParser(prog="python -m fleetrl_lab.peers", description=__doc__)
    parser.add_argument("--env", default="cartpole")
    parser.add_argument("--unit", type=int, default=0)
    parser.add_argument("--fleet-seed", type=int, default=0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--max-steps", type=int, default=200_000)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    result = train_sb3_unit(args.env, args.unit, args.fleet_seed, args.seed, args.max_steps)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.out.with_suffix(".tmp")
    tmp.write_text(json.dumps(result, indent=2) + "\n")
    tmp.replace(args.out)
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
