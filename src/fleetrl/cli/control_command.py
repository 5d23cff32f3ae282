"""The commands on a model file: ``fleetrl export`` (its greedy policy as ONNX, checked), ``fleetrl control``
(a saved policy run on one unit through its driver, with the bridge's safety; no torch, no broker) and
``fleetrl adapt`` (the fleet's policy fitted to one unit in a few episodes: docs/on-device.md)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from fleetrl.cli.device_command import DRIVERS, add_driver_arguments, make_driver, realtime_mode
from fleetrl.cli.settings_args import add_fleet_profile_argument
from fleetrl.envs.catalog import get_env_spec

DEFAULT_ENV = "qube"


def register(subparsers: Any) -> None:
    """Add the ``export``, ``control`` and ``adapt`` subcommands to ``subparsers``."""
    export: argparse.ArgumentParser = subparsers.add_parser(
        "export", help="write a saved policy as ONNX (observation -> greedy action) and check it"
    )
    export.add_argument("model", type=Path, help="a models/worker-K.safetensors file")
    export.add_argument("--out", type=Path, required=True, help="the .onnx file to write")
    add_model_env_argument(export)
    export.add_argument(
        "--check", type=int, default=1000, help="observations the export is checked on (default 1000)"
    )
    export.add_argument("--unit", type=int, default=0, help="the simulated unit the check's states come from")
    export.add_argument("--fleet-seed", type=int, default=0)
    add_fleet_profile_argument(export)
    export.add_argument("--seed", type=int, default=0, help="seed of the check's observations")
    export.set_defaults(handler=cmd_export)

    control: argparse.ArgumentParser = subparsers.add_parser(
        "control", help="run a saved policy (model file or ONNX) on one unit through its driver; no broker"
    )
    control.add_argument("model", type=Path, help="a models/worker-K.safetensors file or an exported .onnx")
    add_model_env_argument(control)
    control.add_argument("--unit", type=int, default=0, help="index of the unit in the fleet (default 0)")
    control.add_argument("--episodes", type=int, default=10, help="episodes to play (default 10)")
    control.add_argument("--seed", type=int, default=0, help="episode k resets with seed SEED + k")
    add_driver_arguments(control)
    control.set_defaults(handler=cmd_control)

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


def add_model_env_argument(p: argparse.ArgumentParser) -> None:
    """``--env``: the task the policy was trained on (its observations, actions and reward)."""
    p.add_argument(
        "--env",
        default=None,
        metavar="ENV",
        help="the env the policy was trained on: qube, qube-continuous, cartpole or package.module:factory "
        "(default: the one an exported file records, else the run's config.json beside models/, else qube)",
    )


def run_env(model: Path) -> str | None:
    """The env in ``RUN/config.json`` for a model file ``RUN/models/worker-K.safetensors``, else None."""
    config = model.parent.parent / "config.json"
    if model.parent.name != "models" or not config.is_file():
        return None
    try:
        env = json.loads(config.read_text()).get("env")
    except (OSError, ValueError, AttributeError):
        return None
    return env if isinstance(env, str) else None


def cmd_export(args: argparse.Namespace) -> int:
    """Write the ONNX file, print the check's result; exit 1 if it failed (no file is left then)."""
    from fleetrl.control.export import export_policy

    env = args.env or run_env(args.model) or DEFAULT_ENV
    try:
        check = export_policy(
            args.model,
            args.out,
            env,
            observations=args.check,
            seed=args.seed,
            unit=args.unit,
            fleet_seed=args.fleet_seed,
            fleet_profile=args.fleet_profile,
        )
    except ImportError as err:
        hint = "pip install 'fleetrl[export]'"
        raise ValueError(f"the export needs onnx and onnxruntime ({err}): {hint}") from None
    print(check.describe())
    if not check.passed:
        print(f"fleetrl export: {args.out} not written: the exported graph disagrees with fleetrl's policy")
        return 1
    print(f"wrote {args.out} (env {env}; input 'observation', output 'action': docs/on-device.md)")
    return 0


def cmd_control(args: argparse.Namespace) -> int:
    """Run the episodes, printing each score and their mean; the motor is off when this returns."""
    from fleetrl.control.controller import run_on_unit
    from fleetrl.control.policies import load_policy

    if args.episodes < 1:
        raise ValueError(f"--episodes must be at least 1, got {args.episodes}")
    if not args.watchdog_ms > 0:
        raise ValueError(f"--watchdog-ms must be positive, got {args.watchdog_ms}")
    policy = load_policy(args.model)
    env = args.env or policy.env or run_env(args.model) or DEFAULT_ENV
    spec = get_env_spec(env)
    if args.driver in DRIVERS and spec.device is None:
        raise ValueError(f"{spec.title} is your own unit type: give its driver as --driver PKG.MOD:FUNCTION")
    realtime = realtime_mode(args)
    device = spec.device if args.driver in DRIVERS else None  # which built-in unit --driver sim simulates
    driver = make_driver(argparse.Namespace(**{**vars(args), "env": device}), realtime)
    mode = "real time" if realtime else "lockstep"
    what = f"{args.model} on {env} ({args.driver}, {mode})"
    print(f"unit {args.unit}: {what}, {args.episodes} episodes", flush=True)

    def report(episode: int, score: float) -> None:
        print(f"episode {episode + 1}: score {score:g}", flush=True)

    scores = run_on_unit(
        policy,
        env,
        driver,
        args.episodes,
        seed=args.seed,
        unit=args.unit,
        fleet_seed=args.fleet_seed,
        realtime=realtime,
        watchdog=args.watchdog_ms / 1e3,
        report=report,
    )
    print(f"mean score {sum(scores) / len(scores):g} over {len(scores)} episodes", flush=True)
    return 0


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
    cap = done.cap or float("inf")
    result = {
        "model": str(args.out),
        "unit": args.unit,
        "episodes": len(done.scores),
        "scores": done.scores,
        "rig_seconds": None if done.rig_seconds is None else round(done.rig_seconds, 1),
        "check_before": done.before,
        "check_after": done.after,
        "held_before": sum(s >= cap for s in done.before),
        "held_after": sum(s >= cap for s in done.after),
        "kept": "fit" if done.kept_fit else "fleet policy",
    }
    print(json.dumps(result))
    return 0
