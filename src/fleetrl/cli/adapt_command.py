"""``fleetrl adapt``: the fleet's policy fitted to one unit in a few episodes (its own part; the shared part
held), written as that unit's model file. Registered on the main parser by ``register(subparsers)``."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from fleetrl.cli.control_command import DEFAULT_ENV, add_model_env_argument, run_env
from fleetrl.cli.settings_args import add_fleet_profile_argument


def register(subparsers: Any) -> None:
    """Add the ``adapt`` subcommand to ``subparsers``."""
    adapt: argparse.ArgumentParser = subparsers.add_parser(
        "adapt", help="fit the fleet's policy to one unit in a few episodes: that unit's own model file"
    )
    adapt.add_argument("model", type=Path, help="the fleet's policy: a models/worker-K.safetensors file")
    adapt.add_argument("--out", type=Path, required=True, help="the unit's model file to write")
    add_model_env_argument(adapt)
    adapt.add_argument("--unit", type=int, default=0, help="the simulated unit to fit (default 0)")
    adapt.add_argument("--fleet-seed", type=int, default=0)
    add_fleet_profile_argument(adapt)
    adapt.add_argument("--episodes", type=int, default=5, help="episodes on the unit (default 5)")
    adapt.add_argument(
        "--check",
        type=int,
        default=10,
        help="greedy episodes before and after, to compare; a fit that scores less is not kept (default 10)",
    )
    adapt.add_argument(
        "--own-part",
        default=None,
        help="input, heads or biases (default: the model's own part, else biases; docs/algorithm.md)",
    )
    adapt.add_argument("--seed", type=int, default=0, help="the unit's action draws and check episodes")
    adapt.set_defaults(handler=cmd_adapt)


def cmd_adapt(args: argparse.Namespace) -> int:
    """Fit, write the unit's model file, print one JSON line: episodes, time on the rig, check scores."""
    from fleetrl.runs.adapt import adapt_model

    if args.out.exists():
        raise ValueError(f"--out {args.out} exists: choose another file (nothing is overwritten)")
    if not args.out.parent.is_dir():
        raise ValueError(f"--out {args.out}: no directory {args.out.parent} to write it in")
    env = args.env or run_env(args.model) or DEFAULT_ENV
    done = adapt_model(
        args.model,
        env,
        args.unit,
        fleet_seed=args.fleet_seed,
        fleet_profile=args.fleet_profile,
        episodes=args.episodes,
        check=args.check,
        seed=args.seed,
        own_part=args.own_part,
        out=args.out,
    )
    if not done.kept_fit:
        print(
            f"the fit scored less on the check episodes than the fleet's policy; {args.out} holds "
            "the fleet's policy (its own part zero)",
            file=sys.stderr,
        )
    held = {
        k: sum(s >= (done.cap or float("inf")) for s in v)
        for k, v in (("before", done.before), ("after", done.after))
    }
    print(
        json.dumps(
            {
                "model": str(args.out),
                "unit": args.unit,
                "episodes": len(done.scores),
                "scores": done.scores,
                "rig_seconds": None if done.rig_seconds is None else round(done.rig_seconds, 1),
                "check_before": done.before,
                "check_after": done.after,
                "held_before": held["before"],
                "held_after": held["after"],
                "kept": "fit" if done.kept_fit else "fleet policy",
            }
        )
    )
    return 0
